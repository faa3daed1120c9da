#include "study.h"

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

#include "errors.h"
#include "livepoint_file.h"
#include "random_hash.h"
#include "slab.h"
#include "toml_guard.h"
#include "version.h"

namespace ropsim {

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

/// The run parameters an axis may sweep, besides the hardware keys.
struct RunParam {
  const char* key;
  const char* meaning;
};
constexpr RunParam kRunParams[] = {
    {"method", "the transparency method"},
    {"spp", "samples per pixel (scenes)"},
    {"seed", "seed of the methods' hash-based random numbers"},
    {"fidelity", "functional, cycle, sampled or approximate"},
    {"hash_bits", "alpha-reference hash width, bits"},
    {"alpha_bits", "opacity fixed-point precision, bits"},
    {"surface_id_bits", "surface id register width, bits"},
    {"width", "scene width, pixels (scenes)"},
    {"height", "scene height, pixels (scenes)"},
    {"scene_seed", "seed of the scene generator (scenes)"},
    {"repeat", "draw the input this many times into one frame"},
    {"order", "draw order of a mesh input's capture: authored, shuffled, far-to-near, near-to-far"},
    {"design", "a hardware design file (cycle points; hardware keys override it)"},
    {"slab_layers", "slab: k, layers per pixel (1..16)"},
    {"slab_bits", "slab: b, bits of each layer's coverage mask (1..64)"},
    {"enderton_selection", "enderton and its variants: depth-first (default) or original (docs/methods.md)"},
    {"sample_units", "sampled points: units K"},
    {"sample_size", "sampled points: fragments U per measured window"},
    {"sample_warmup", "sampled points: fragments W simulated in detail before each window"},
    {"sample_cooldown", "sampled points: fragments C simulated after each window"},
    {"sample_warming", "sampled points: fragments T before each warm-up that may warm the caches tag-only"},
    {"sample_warming_reach", "sampled points: the warming reach R, times the design's cache lines"},
};

bool is_sampling_key(const std::string& k) { return k.rfind("sample_", 0) == 0; }

bool is_fidelity(const std::string& f) {
  return f == "functional" || f == "cycle" || f == "sampled" || f == "approximate";
}
/// Does the fidelity give time (and so take a design)?
bool is_timed(const std::string& f) { return f != "functional"; }

bool is_run_param(const std::string& k) {
  for (const auto& p : kRunParams)
    if (k == p.key) return true;
  return false;
}

bool is_hw_key(const std::string& k) {
  for (const auto& p : hw_params())
    if (p.key == k) return true;
  return false;
}

bool is_hardware(const std::string& k) { return k == "design" || is_hw_key(k); }

[[noreturn]] void fail(const Study& s, const std::string& key, const std::string& why) {
  throw UserError(s.path + ": " + key + ": " + why);
}

/// A design file's path, relative to the study file's folder.
std::string design_path(const Study& s, const std::string& f) {
  std::filesystem::path p(f);
  if (p.is_relative()) p = std::filesystem::absolute(s.path).parent_path() / p;
  return p.lexically_normal().string();
}

std::string read_text(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

StudyValue value_of(const Study& s, const std::string& key, const toml::node& n) {
  if (auto v = n.value_exact<int64_t>()) return *v;
  if (auto v = n.value_exact<double>()) return *v;
  if (auto v = n.value_exact<bool>()) return *v;
  if (auto v = n.value_exact<std::string>()) return *v;
  fail(s, key, "values must be integers, reals, booleans or strings");
}

int64_t int_of(const Study& s, const std::string& key, const StudyValue& v, int64_t lo, int64_t hi) {
  const int64_t* i = std::get_if<int64_t>(&v);
  if (!i) fail(s, key, "expected an integer, got " + to_string(v));
  if (*i < lo || *i > hi) fail(s, key, fmt::format("{} is not in [{}, {}]", *i, lo, hi));
  return *i;
}

/// Checks one value of a run-parameter axis.
void check_run_value(const Study& s, const std::string& key, const std::string& at, const StudyValue& v) {
  if (key == "method") {
    Method m;
    if (!std::holds_alternative<std::string>(v) || !parse_method(std::get<std::string>(v), m))
      fail(s, at, to_string(v) + " is not a method (ropsim run --help lists them)");
  } else if (key == "enderton_selection") {
    EndertonSelection e;
    if (!std::holds_alternative<std::string>(v) || !parse_enderton_selection(std::get<std::string>(v), e))
      fail(s, at, to_string(v) + " is not depth-first or original");
  } else if (key == "fidelity") {
    const std::string* f = std::get_if<std::string>(&v);
    if (!f || !is_fidelity(*f)) fail(s, at, to_string(v) + " is not functional, cycle, sampled or approximate");
  } else if (key == "sample_units" || key == "sample_size") {
    int_of(s, at, v, 1, int64_t{1} << 40);
  } else if (key == "sample_warmup" || key == "sample_cooldown" || key == "sample_warming") {
    int_of(s, at, v, 0, int64_t{1} << 40);
  } else if (key == "sample_warming_reach") {
    const double* d = std::get_if<double>(&v);
    const int64_t* i = std::get_if<int64_t>(&v);
    const double r = d ? *d : i ? double(*i) : -1.0;
    if (!(r >= 0 && r <= 1e6)) fail(s, at, to_string(v) + " is not a number in [0, 1e6]");
  } else if (key == "spp") {
    const int64_t n = int_of(s, at, v, 1, kMaxSpp);
    if (!is_valid_spp(int(n))) fail(s, at, fmt::format("{} is not a power of two in [1, 64]", n));
  } else if (key == "seed" || key == "scene_seed") {
    int_of(s, at, v, 0, INT64_MAX);
  } else if (key == "hash_bits") {
    int_of(s, at, v, 8, 32);
  } else if (key == "alpha_bits" || key == "surface_id_bits") {
    int_of(s, at, v, 1, 32);
  } else if (key == "width" || key == "height") {
    int_of(s, at, v, 1, kMaxScreenSide);
  } else if (key == "repeat") {
    int_of(s, at, v, 1, 1000);
  } else if (key == "slab_layers") {
    int_of(s, at, v, 1, kMaxSlabLayers);
  } else if (key == "slab_bits") {
    int_of(s, at, v, 1, kMaxSlabBits);
  } else if (key == "design") {
    const std::string* f = std::get_if<std::string>(&v);
    if (!f) fail(s, at, "expected the path of a design file");
    try {
      load_hw_config(design_path(s, *f));
    } catch (const std::exception& e) {
      fail(s, at, e.what());
    }
  } else if (key == "order") {
    DrawOrder o;
    if (!std::holds_alternative<std::string>(v) || !parse_draw_order(std::get<std::string>(v), o))
      fail(s, at, to_string(v) + " is not a draw order (authored, shuffled, far-to-near, near-to-far)");
  }
}

/// Checks one value of a hardware axis on its own (range and type); a
/// constraint between keys is checked per point.
void check_hw_value(const Study& s, const std::string& key, const std::string& at, const StudyValue& v) {
  HwConfig c;
  try {
    apply_hw_override(c, key + "=" + to_string(v));
  } catch (const std::exception& e) {
    fail(s, at, e.what());
  }
}

std::string hex16(uint64_t h) { return fmt::format("{:016x}", h); }

uint64_t hash_text(const std::string& s) {
  uint64_t h = 0x9e3779b97f4a7c15ull;
  for (unsigned char c : s) h = mix64(h ^ c);
  return mix64(h ^ s.size());
}

const StudyInput& input_of(const Study& s, const std::string& label) {
  for (const auto& in : s.inputs)
    if (in.label == label) return in;
  throw InternalError("a study point names an input the study has");
}

}  // namespace

Study load_study(const std::string& path) {
  std::string text;
  if (!read_text_file(path, text)) throw UserError(path + ": cannot read the study file");
  return parse_study(text, path);
}

Study parse_study(const std::string& text, const std::string& path) {
  Study s;
  s.path = path;
  const TomlInput in = toml_input(text, path);
  if (!in.error.empty()) throw UserError(in.error);
  toml::table t;
  try {
    t = toml::parse(in.ascii, path);
  } catch (const toml::parse_error& e) {
    throw UserError(fmt::format("{}: line {}: {}", path, e.source().begin.line, e.description()));
  }
  const std::filesystem::path dir = std::filesystem::absolute(path).parent_path();
  for (const auto& [k, node] : t) {
    const std::string key(k.str());
    if (key != "study" && key != "inputs" && key != "axes" && key != "slurm")
      fail(s, key, "unknown section (study, inputs, axes, slurm)");
    if (!node.is_table()) fail(s, key, "expected a table [" + key + "]");
  }
  s.name = std::filesystem::path(path).stem().string();
  if (const toml::table* st = t["study"].as_table()) {
    for (const auto& [k, node] : *st) {
      const std::string key = "study." + std::string(k.str());
      if (key == "study.name") {
        auto v = node.value_exact<std::string>();
        if (!v || v->empty()) fail(s, key, "expected a non-empty string");
        s.name = *v;
      } else if (key == "study.combine") {
        auto v = node.value_exact<std::string>();
        if (!v || (*v != "product" && *v != "zip")) fail(s, key, "expected \"product\" or \"zip\"");
        s.combine = *v == "zip" ? Study::Combine::kZip : Study::Combine::kProduct;
      } else if (key == "study.reference") {
        auto v = node.value_exact<bool>();
        if (!v) fail(s, key, "expected true or false");
        s.reference = *v;
      } else if (key == "study.reference_spp") {
        auto v = node.value_exact<int64_t>();
        if (!v || !is_valid_spp(int(*v)) || *v > kMaxSpp) fail(s, key, "expected a power of two in [1, 64]");
        s.reference_spp = int(*v);
      } else if (key == "study.save_images") {
        auto v = node.value_exact<bool>();
        if (!v) fail(s, key, "expected true or false");
        s.save_images = *v;
      } else {
        fail(s, key, "unknown key (name, combine, reference, reference_spp, save_images)");
      }
    }
  }
  if (const toml::table* sl = t["slurm"].as_table()) {
    // Checked here so that a bad value is refused before anything is submitted.
    auto word = [](const std::string& v, const char* extra) {
      if (v.empty()) return false;
      for (char c : v)
        if (!std::isalnum(static_cast<unsigned char>(c)) && !std::strchr(extra, c)) return false;
      return true;
    };
    for (const auto& [k, node] : *sl) {
      const std::string key = "slurm." + std::string(k.str());
      auto v = node.value_exact<std::string>();
      if (key == "slurm.partition") {
        if (!v || !word(*v, "_-.,")) fail(s, key, "expected a partition name (letters, digits, _-.,)");
        s.slurm.partition = *v;
      } else if (key == "slurm.time") {
        if (!v || !word(*v, ":-") || !std::isdigit(static_cast<unsigned char>((*v)[0])))
          fail(s, key, "expected a SLURM time limit such as \"30\", \"01:00:00\" or \"1-00:00:00\"");
        s.slurm.time = *v;
      } else if (key == "slurm.mem") {
        if (!v || !word(*v, "") || !std::isdigit(static_cast<unsigned char>((*v)[0])) ||
            v->find_first_not_of("0123456789") < v->size() - 1 || !std::strchr("0123456789KMGT", v->back()))
          fail(s, key, "expected a memory size such as \"512M\" or \"2G\"");
        s.slurm.mem = *v;
      } else if (key == "slurm.throttle") {
        auto n = node.value_exact<int64_t>();
        if (!n || *n < 1 || *n > 100000) fail(s, key, "expected an integer in [1, 100000]");
        s.slurm.throttle = unsigned(*n);
      } else if (key == "slurm.args") {
        const toml::array* a = node.as_array();
        if (!a) fail(s, key, "expected a list of sbatch options, e.g. [\"--qos=short\"]");
        for (const auto& e : *a) {
          auto arg = e.value_exact<std::string>();
          if (!arg || arg->rfind("-", 0) != 0) fail(s, key, "expected a list of sbatch options, each starting with -");
          s.slurm.args.push_back(*arg);
        }
      } else {
        fail(s, key, "unknown key (partition, time, mem, throttle, args)");
      }
    }
  }
  std::set<std::string> labels;
  if (const toml::table* in = t["inputs"].as_table()) {
    std::set<std::string> scene_labels;  // the built-in scenes' names (checked below)
    if (const toml::array* sc = (*in)["scenes"].as_array())
      for (const auto& e : *sc)
        if (auto v = e.value_exact<std::string>()) scene_labels.insert(*v);
    for (const auto& [k, node] : *in) {
      const std::string key = "inputs." + std::string(k.str());
      if (key != "inputs.scenes" && key != "inputs.traces" && key != "inputs.meshes")
        fail(s, key, "unknown key (scenes, traces, meshes)");
      const toml::array* a = node.as_array();
      if (!a || a->empty()) fail(s, key, "expected a non-empty list of strings");
      for (const auto& e : *a) {
        auto v = e.value_exact<std::string>();
        if (!v) fail(s, key, "expected a list of strings");
        StudyInput si;
        if (key == "inputs.scenes") {
          bool known = false;
          for (const auto& sc : scene_catalog()) known = known || sc.name == *v;
          if (!known) fail(s, key, *v + " is not a built-in scene (ropsim scene --list)");
          si.scene = si.label = *v;
        } else {
          std::filesystem::path p(*v);
          if (p.is_relative()) p = dir / p;
          const bool trace = key == "inputs.traces";
          if (!std::filesystem::is_regular_file(p))
            fail(s, key, *v + (trace ? ": no such trace file" : ": no such scene file"));
          (trace ? si.trace : si.mesh) = p.lexically_normal().string();
          si.label = p.stem().string();
          if (!trace) {
            try {
              load_scene_file(si.mesh);  // checked now: a bad scene file runs nothing
            } catch (const std::exception& e) {
              fail(s, key, e.what());
            }
          }
        }
        // A mesh or trace named like a built-in scene of the study is
        // "<stem>-mesh" / "<stem>-trace" (the scenes keep their names).
        if (si.scene.empty() && scene_labels.count(si.label)) si.label += si.trace.empty() ? "-mesh" : "-trace";
        if (!labels.insert(si.label).second) fail(s, key, "two inputs are named " + si.label);
        s.inputs.push_back(si);
      }
    }
  }
  if (s.inputs.empty()) fail(s, "inputs", "a study needs at least one input (inputs.scenes or inputs.traces)");
  bool has_trace = false, has_mesh = false, has_scene = false;
  for (const auto& in : s.inputs) {
    has_trace = has_trace || !in.trace.empty();
    has_mesh = has_mesh || !in.mesh.empty();
    has_scene = has_scene || !in.scene.empty();
  }
  if (has_mesh && s.reference_spp) fail(s, "study.reference_spp", "applies to built-in scenes only");
  if (has_trace && s.reference_spp) fail(s, "study.reference_spp", "applies to scenes only (a trace's spp is fixed)");

  bool any_cycle = false, any_hw = false;
  if (const toml::table* ax = t["axes"].as_table()) {
    // In the order of the file (a toml::table iterates its keys sorted).
    std::vector<std::pair<std::string, const toml::node*>> in_order;
    for (const auto& [k, node] : *ax) in_order.emplace_back(std::string(k.str()), &node);
    std::stable_sort(in_order.begin(), in_order.end(), [](const auto& a, const auto& b) {
      return a.second->source().begin.line < b.second->source().begin.line;
    });
    for (const auto& [key, node_ptr] : in_order) {
      const toml::node& node = *node_ptr;
      const std::string at = "axes." + key;
      const bool run = is_run_param(key), hw = is_hw_key(key);
      if (!run && !hw)
        fail(
            s, at,
            "unknown parameter (a run parameter: method, spp, seed, fidelity, hash_bits, alpha_bits, "
            "surface_id_bits, width, height, scene_seed, repeat, order, slab_layers, slab_bits, enderton_selection; or "
            "a hardware key: ropsim config --markdown)");
      StudyAxis axis{key, {}};
      if (const toml::array* a = node.as_array()) {
        if (a->empty()) fail(s, at, "an axis needs at least one value");
        for (const auto& e : *a) axis.values.push_back(value_of(s, at, e));
      } else {
        axis.values.push_back(value_of(s, at, node));
      }
      std::set<std::string> seen;
      for (const auto& v : axis.values) {
        if (!seen.insert(to_string(v)).second) fail(s, at, "the value " + to_string(v) + " appears twice");
        if (run) check_run_value(s, key, at, v);
        if (hw) check_hw_value(s, key, at, v);
        if (key == "fidelity" && is_timed(to_string(v))) any_cycle = true;
      }
      if (has_trace && (key == "spp" || key == "width" || key == "height" || key == "scene_seed"))
        fail(s, at, "applies to scenes and meshes only: the study has trace inputs");
      if (key == "order" && (has_trace || has_scene))
        fail(s, at, "applies to mesh inputs only (inputs.meshes): the study has other inputs");
      if (key.rfind("numerics.", 0) == 0)
        fail(s, at,
             "sweep the numerics with the axes hash_bits, alpha_bits and surface_id_bits (they apply to "
             "both fidelities)");
      any_hw = any_hw || hw || key == "design";
      s.axes.push_back(std::move(axis));
    }
  }
  if (any_hw && !any_cycle) fail(s, "axes", "hardware keys need a timed fidelity (cycle or sampled) among the points");
  if (s.combine == Study::Combine::kZip)
    for (const auto& a : s.axes)
      if (a.values.size() != s.axes.front().values.size())
        fail(s, "axes." + a.key,
             fmt::format("combine = \"zip\" needs lists of one length ({} here, {} for {})", a.values.size(),
                         s.axes.front().values.size(), s.axes.front().key));
  // Bounded before anything is expanded: a product of long lists is refused,
  // not allocated.
  uint64_t points = std::max<size_t>(1, s.inputs.size());
  for (const auto& a : s.axes) {
    const uint64_t n = s.combine == Study::Combine::kZip ? 1 : a.values.size();
    if (n > 0 && points > kMaxStudyPoints / n) {
      points = kMaxStudyPoints + 1;
      break;
    }
    points *= n;
  }
  if (s.combine == Study::Combine::kZip && !s.axes.empty())
    points = std::max<size_t>(1, s.inputs.size()) * uint64_t(s.axes.front().values.size());
  if (points > kMaxStudyPoints)
    fail(s, "axes", fmt::format("the inputs and axes give more than {} points", kMaxStudyPoints));
  s.points_at_most = points;
  return s;
}

nlohmann::ordered_json StudyPoint::params_json() const {
  nlohmann::ordered_json j;
  j["input"] = input;
  for (const auto& [k, v] : params) j[k] = to_json(v);
  return j;
}

std::vector<StudyPoint> expand_study(const Study& s) {
  std::vector<std::map<std::string, StudyValue>> combos;
  if (s.axes.empty()) {
    combos.emplace_back();
  } else if (s.combine == Study::Combine::kZip) {
    for (size_t i = 0; i < s.axes.front().values.size(); ++i) {
      std::map<std::string, StudyValue> m;
      for (const auto& a : s.axes) m[a.key] = a.values[i];
      combos.push_back(std::move(m));
    }
  } else {
    combos.emplace_back();
    for (const auto& a : s.axes) {
      std::vector<std::map<std::string, StudyValue>> next;
      for (const auto& c : combos)
        for (const auto& v : a.values) {
          auto m = c;
          m[a.key] = v;
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
      if (f == p.params.end() || std::get<std::string>(f->second) != "sampled")
        for (auto it = p.params.begin(); it != p.params.end();)
          it = is_sampling_key(it->first) ? p.params.erase(it) : std::next(it);
      // The identity: what the input is, every parameter, what the metrics
      // compare against, and the tool that computes them.
      nlohmann::ordered_json id;
      id["input"] = !in.trace.empty()  ? "trace:" + in.trace
                    : !in.mesh.empty() ? "mesh:" + in.mesh
                                       : "scene:" + in.scene;
      id["params"] = p.params_json();
      if (auto d = p.params.find("design"); d != p.params.end())  // the design's content, not only its name
        id["design"] = read_text(design_path(s, std::get<std::string>(d->second)));
      id["reference"] = s.reference;
      id["reference_spp"] = s.reference_spp;
      id["ropsim"] = std::string(ropsim_version()) + " " + ropsim_commit();
      p.hash = hex16(hash_text(id.dump()));
      if (!seen.insert(p.hash).second) continue;
      points.push_back(std::move(p));
    }
  return points;
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
  if (!in.mesh.empty()) {
    r.capture_scene = in.mesh;
    SceneOverrides& o = r.capture_overrides;
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
    r.capture_key = hex16(hash_text(id.dump()));
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
  if (f) r.fidelity = std::get<std::string>(*f);
  std::vector<std::string> overrides;
  for (const auto& [k, v] : p.params)
    if (is_hw_key(k)) overrides.push_back(k + "=" + to_string(v));
  if (r.timed()) {
    const StudyValue* design = get("design");
    r.hw = resolve_hw_config(design ? design_path(s, std::get<std::string>(*design)) : "", overrides);
    r.hw.name = "study " + s.name + (design ? ", design " + std::get<std::string>(*design) : "");
    r.method.formats = r.hw.blend.formats;  // the blend targets' formats are functional too
  }
  if (r.fidelity == "sampled") {
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
    r.livepoints_key = hex16(hash_text(id.dump()));
  }
  if (s.reference) {
    r.reference_input = r.input;
    if (s.reference_spp) r.reference_input.scene.spp = s.reference_spp;
    nlohmann::ordered_json id;
    id["input"] = !in.trace.empty()  ? "trace:" + in.trace
                  : !in.mesh.empty() ? "capture:" + r.capture_key
                                     : "scene:" + in.scene;
    id["spp"] = r.reference_input.scene.spp;
    id["width"] = r.reference_input.scene.width;
    id["height"] = r.reference_input.scene.height;
    id["scene_seed"] = r.reference_input.scene.seed;
    id["repeat"] = r.reference_input.repeat;
    r.reference_key = hex16(hash_text(id.dump()));
  }
  return r;
}

}  // namespace ropsim
