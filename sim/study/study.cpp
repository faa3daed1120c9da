// A study's points: the expansion of its axes and cases, the check of its
// inputs, and what a point resolves to (its input, method, design, sampling
// and the keys of the capture, reference and live-point library it shares).
#include "sim/study/study.h"

#include <fmt/format.h>
#include <toml++/toml.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "rtl_models/algo/random_hash.h"
#include "rtl_models/algo/slab.h"
#include "sim/fidelity/fidelity.h"
#include "sim/fidelity/sampled/livepoint_file.h"
#include "sim/study/study_values.h"
#include "util/child_process.h"
#include "util/errors.h"
#include "util/toml_guard.h"
#include "util/version.h"

namespace ropsim {

using namespace study_detail;

std::string to_string(const StudyValue& v) {
  if (auto* i = std::get_if<int64_t>(&v)) return std::to_string(*i);
  if (auto* d = std::get_if<double>(&v)) return fmt::format("{}", *d);  // shortest round-trip
  if (auto* b = std::get_if<bool>(&v)) return *b ? "true" : "false";
  return std::get<std::string>(v);
}

nlohmann::ordered_json to_json(const StudyValue& v) {
  if (auto* i = std::get_if<int64_t>(&v)) return *i;
  if (auto* d = std::get_if<double>(&v)) return *d;
  if (auto* b = std::get_if<bool>(&v)) return *b;
  return std::get<std::string>(v);
}

namespace {

/// The files a mesh file names besides itself: an OBJ's material libraries
/// (`mtllib`, the rest of the line, relative to the OBJ's folder, as Assimp
/// reads them) and a glTF's external buffers and images (their relative
/// `uri`s). A file that cannot be read names none (the capture says why).
std::vector<std::string> files_named_by_mesh(const std::string& mesh) {
  namespace fs = std::filesystem;
  std::string ext = fs::path(mesh).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  const fs::path folder = fs::path(mesh).parent_path();
  std::vector<std::string> out;
  if (ext == ".obj") {
    std::ifstream f(mesh);
    std::string line;
    while (std::getline(f, line)) {
      const size_t b = line.find_first_not_of(" \t");
      if (b == std::string::npos || line.compare(b, 6, "mtllib") != 0 || b + 6 >= line.size() ||
          !std::isspace(static_cast<unsigned char>(line[b + 6])))
        continue;
      const size_t n = line.find_first_not_of(" \t", b + 6), e = line.find_last_not_of(" \t\r");
      if (n != std::string::npos && e >= n)
        out.push_back((folder / line.substr(n, e - n + 1)).lexically_normal().string());
    }
  } else if (ext == ".gltf") {
    const nlohmann::json j = nlohmann::json::parse(read_text(mesh), nullptr, /*allow_exceptions=*/false);
    if (!j.is_object()) return out;
    for (const char* section : {"buffers", "images"}) {
      auto it = j.find(section);
      if (it == j.end() || !it->is_array()) continue;
      for (const auto& e : *it) {
        if (!e.is_object()) continue;
        auto u = e.find("uri");
        if (u == e.end() || !u->is_string()) continue;
        const std::string uri = u->get<std::string>();
        if (uri.rfind("data:", 0) == 0 || uri.find("://") != std::string::npos) continue;
        std::string path;  // percent-decoded (RFC 3986, as glTF's uris are)
        for (size_t i = 0; i < uri.size(); ++i)
          if (uri[i] == '%' && i + 2 < uri.size() && std::isxdigit(static_cast<unsigned char>(uri[i + 1])) &&
              std::isxdigit(static_cast<unsigned char>(uri[i + 2]))) {
            path += char(std::stoi(uri.substr(i + 1, 2), nullptr, 16));
            i += 2;
          } else {
            path += uri[i];
          }
        out.push_back((folder / path).lexically_normal().string());
      }
    }
  }
  return out;
}

const StudyInput& input_of(const Study& s, const std::string& label) {
  for (const auto& in : s.inputs)
    if (in.label == label) return in;
  throw InternalError("a study point names an input the study has");
}

}  // namespace

nlohmann::ordered_json StudyPoint::params_json() const {
  nlohmann::ordered_json j;
  j["input"] = input;
  for (const auto& [k, v] : params) j[k] = to_json(v);
  return j;
}

std::vector<StudyPoint> expand_study(const Study& s) {
  std::vector<StudyCase> combos;
  if (s.combine == Study::Combine::kZip) {
    for (size_t i = 0, n = zip_length(s); i < n; ++i) combos.push_back(zip_position(s, i));
  } else {
    combos.emplace_back();
    for (const auto& a : s.axes) {
      std::vector<StudyCase> next;
      for (const auto& c : combos)
        for (size_t i = 0; i < a.values.size(); ++i) {
          auto m = c;
          put_value(m, a, i);
          next.push_back(std::move(m));
        }
      combos = std::move(next);
    }
  }
  std::vector<StudyPoint> points;
  std::set<std::string> seen;
  for (const auto& in : s.inputs)
    for (const auto& c : combos) {
      StudyPoint p;
      p.index = points.size();
      p.input = in.label;
      p.params = c;
      // A functional run has no hardware: its hardware values are dropped,
      // and the points that then repeat another are one point.
      auto f = p.params.find("fidelity");
      if (f == p.params.end() || !is_timed(std::get<std::string>(f->second)))
        for (auto it = p.params.begin(); it != p.params.end();)
          it = is_hardware(it->first) ? p.params.erase(it) : std::next(it);
      // Likewise the sampling of a point that is not sampled.
      if (f == p.params.end() || parse_fidelity(std::get<std::string>(f->second)) != Fidelity::kSampled)
        for (auto it = p.params.begin(); it != p.params.end();)
          it = is_sampling_key(it->first) ? p.params.erase(it) : std::next(it);
      // The identity: what the input is, every parameter, what the metrics
      // compare against, and the tool that computes them.
      nlohmann::ordered_json id;
      id["input"] = !in.trace.empty()  ? "trace:" + in.trace
                    : !in.mesh.empty() ? "mesh:" + in.mesh
                    : !in.app.empty()  ? "app:" + in.app
                                       : "scene:" + in.scene;
      if (!in.app.empty()) id["app"] = read_text(in.app);  // the entry's content: an edited entry is a new point
      id["params"] = p.params_json();
      if (auto d = p.params.find("design"); d != p.params.end())  // the design's content, not only its name
        id["design"] = read_text(design_path(s, std::get<std::string>(d->second)));
      id["reference"] = s.reference;
      id["reference_spp"] = s.reference_spp;
      id["ropsim"] = std::string(ropsim_version()) + " " + ropsim_commit();
      p.hash = hex64(hash_text(id.dump()));
      if (!seen.insert(p.hash).second) continue;
      points.push_back(std::move(p));
    }
  return points;
}

void check_study_inputs(const Study& s) {
  for (const auto& in : s.inputs) {
    auto missing = [&](const std::string& why) {
      throw UserError(fmt::format("{}: {} (line {}): {}", s.path, in.at, in.line, why));
    };
    if (!in.trace.empty() && !is_regular_file(in.trace)) missing(in.trace + ": no such trace file");
    if (!in.app.empty()) {
      AppEntry e;
      try {
        e = load_app_entry(in.app);
      } catch (const std::exception& ex) {
        if (exit_status_of(ex) != kUserErrorStatus) throw;  // a broken invariant stays one
        missing(ex.what());
      }
      if (find_executable(e.command[0]).empty())
        missing(
            fmt::format("{}: {} is not installed: install the Debian package {} (scripts/deps.sh --apps "
                        "installs it)",
                        in.app, e.command[0], e.package));
      continue;
    }
    if (in.mesh.empty()) continue;
    SceneSpec spec;
    try {
      spec = load_scene_file(in.mesh, scene_overrides(s));
    } catch (const std::exception& e) {
      if (exit_status_of(e) != kUserErrorStatus) throw;  // a broken invariant stays one
      missing(e.what());
    }
    const std::string where = s.mesh_dir.empty() ? "give --mesh-dir DIR or set ROPSIM_MESH_DIR to the "
                                                   "folder of the meshes"
                                                 : "not in --mesh-dir " + s.mesh_dir + " either";
    for (const auto& ob : spec.objects) {
      // ob.name is the object's `name`, else "object[i]".
      const std::string of = in.mesh + ": " + (ob.name.rfind("object[", 0) == 0 ? ob.name : "object " + ob.name) + ": ";
      if (!is_regular_file(ob.mesh)) missing(of + ob.mesh + ": no such mesh file (" + where + ")");
      if (!ob.texture.empty() && !is_regular_file(ob.texture)) missing(of + ob.texture + ": no such texture file");
      for (const auto& f : files_named_by_mesh(ob.mesh))
        if (!is_regular_file(f)) missing(of + ob.mesh + " names " + f + ": no such file");
    }
  }
}

ResolvedPoint resolve_point(const Study& s, const StudyPoint& p, const std::string& dir) {
  ResolvedPoint r;
  const StudyInput& in = input_of(s, p.input);
  auto get = [&](const char* key) -> const StudyValue* {
    auto it = p.params.find(key);
    return it == p.params.end() ? nullptr : &it->second;
  };
  auto get_int = [&](const char* key, int64_t def) {
    const StudyValue* v = get(key);
    return v ? std::get<int64_t>(*v) : def;
  };
  if (!in.app.empty()) {
    r.capture_app = in.app;
    AppOverrides& o = r.capture_app_overrides;
    if (get("spp")) o.spp = int(get_int("spp", 1));
    if (get("width")) o.width = unsigned(get_int("width", 0));
    if (get("height")) o.height = unsigned(get_int("height", 0));
    const AppEntry e = load_app_entry(in.app, o);
    nlohmann::ordered_json id;
    id["app"] = in.app;
    id["entry"] = read_text(in.app);
    id["spp"] = e.spp;
    id["width"] = e.width;
    id["height"] = e.height;
    r.capture_key = hex64(hash_text(id.dump()));
    r.input.trace_path = (std::filesystem::path(dir) / "traces" / (r.capture_key + ".rtr")).string();
  } else if (!in.mesh.empty()) {
    r.capture_scene = in.mesh;
    SceneOverrides& o = r.capture_overrides;
    o = scene_overrides(s);
    if (get("spp")) o.spp = int(get_int("spp", 16));
    if (get("width")) o.width = uint32_t(get_int("width", 0));
    if (get("height")) o.height = uint32_t(get_int("height", 0));
    if (get("scene_seed")) o.seed = uint64_t(get_int("scene_seed", 1));
    if (const StudyValue* v = get("order")) {
      DrawOrder d;
      parse_draw_order(std::get<std::string>(*v), d);
      o.order = d;
    }
    nlohmann::ordered_json id;
    id["mesh"] = in.mesh;
    id["spp"] = o.spp ? *o.spp : 0;
    id["width"] = o.width ? *o.width : 0;
    id["height"] = o.height ? *o.height : 0;
    id["seed"] = o.seed ? *o.seed : 0;
    id["order"] = o.order ? to_string(*o.order) : "";
    r.capture_key = hex64(hash_text(id.dump()));
    r.input.trace_path = (std::filesystem::path(dir) / "traces" / (r.capture_key + ".rtr")).string();
  } else if (in.trace.empty()) {
    r.input.scene.name = in.scene;
    r.input.scene.spp = int(get_int("spp", 16));
    r.input.scene.width = uint32_t(get_int("width", 0));
    r.input.scene.height = uint32_t(get_int("height", 0));
    r.input.scene.seed = uint64_t(get_int("scene_seed", 1));
  } else {
    r.input.trace_path = in.trace;
  }
  r.input.repeat = uint32_t(get_int("repeat", 1));
  if (const StudyValue* m = get("method")) parse_method(std::get<std::string>(*m), r.method.method);
  r.method.seed = uint64_t(get_int("seed", 1));
  if (const StudyValue* e = get("enderton_selection"))
    parse_enderton_selection(std::get<std::string>(*e), r.method.enderton_selection);
  r.method.numerics.hash_bits = int(get_int("hash_bits", 32));
  r.method.numerics.alpha_bits = int(get_int("alpha_bits", 32));
  r.method.numerics.surface_id_bits = int(get_int("surface_id_bits", 32));
  r.method.slab_layers = int(get_int("slab_layers", MethodConfig{}.slab_layers));
  r.method.slab_bits = int(get_int("slab_bits", MethodConfig{}.slab_bits));
  const StudyValue* f = get("fidelity");
  if (f) {
    const auto fid = parse_fidelity(std::get<std::string>(*f));
    if (!fid) fail(s, "fidelity", std::get<std::string>(*f) + " is not functional, cycle, sampled or approximate");
    r.fidelity = *fid;
  }
  std::vector<std::string> overrides;
  for (const auto& [k, v] : p.params)
    if (is_hw_key(k)) overrides.push_back(k + "=" + to_string(v));
  if (r.timed()) {
    const StudyValue* design = get("design");
    r.hw = resolve_hw_config(design ? design_path(s, std::get<std::string>(*design)) : "", overrides);
    r.hw.name = "study " + s.name + (design ? ", design " + std::get<std::string>(*design) : "");
    r.method.formats = r.hw.blend.formats;  // the blend targets' formats are functional too
  }
  if (r.fidelity == Fidelity::kSampled) {
    SamplingParams& sp0 = r.sampling;
    sp0.units = uint64_t(get_int("sample_units", int64_t(sp0.units)));
    sp0.unit_fragments = uint64_t(get_int("sample_size", int64_t(sp0.unit_fragments)));
    sp0.warmup_fragments = uint64_t(get_int("sample_warmup", int64_t(sp0.warmup_fragments)));
    sp0.cooldown_fragments = uint64_t(get_int("sample_cooldown", int64_t(sp0.cooldown_fragments)));
    sp0.warming_fragments = uint64_t(get_int("sample_warming", int64_t(sp0.warming_fragments)));
    if (const StudyValue* v = get("sample_warming_reach"))
      sp0.warming_reach = std::holds_alternative<double>(*v) ? std::get<double>(*v) : double(std::get<int64_t>(*v));
    // One library per input, method and sampling, shared by every design.
    nlohmann::ordered_json id;
    id["input"] = r.input.describe();
    id["scene"] = {r.input.scene.name, r.input.scene.spp, r.input.scene.width, r.input.scene.height,
                   r.input.scene.seed};
    id["method"] = {to_string(r.method.method),
                    r.method.seed,
                    r.method.numerics.hash_bits,
                    r.method.numerics.alpha_bits,
                    r.method.numerics.surface_id_bits,
                    r.method.slab_layers,
                    r.method.slab_bits,
                    int(r.method.enderton_selection)};
    const SamplingParams& sp = r.sampling;
    id["sampling"] = {sp.unit_fragments, sp.warmup_fragments,  sp.cooldown_fragments,
                      sp.units,          sp.warming_fragments, sp.warming_reach};
    id["version"] = kLivePointFileVersion;
    r.livepoints_key = hex64(hash_text(id.dump()));
  }
  if (s.reference) {
    r.reference_input = r.input;
    if (s.reference_spp) r.reference_input.scene.spp = s.reference_spp;
    nlohmann::ordered_json id;
    id["input"] = !in.trace.empty()                     ? "trace:" + in.trace
                  : !in.mesh.empty() || !in.app.empty() ? "capture:" + r.capture_key
                                                        : "scene:" + in.scene;
    id["spp"] = r.reference_input.scene.spp;
    id["width"] = r.reference_input.scene.width;
    id["height"] = r.reference_input.scene.height;
    id["scene_seed"] = r.reference_input.scene.seed;
    id["repeat"] = r.reference_input.repeat;
    r.reference_key = hex64(hash_text(id.dump()));
  }
  return r;
}

}  // namespace ropsim
