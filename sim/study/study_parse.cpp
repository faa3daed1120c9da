// Reading a study file: its inputs, axes, cases and settings, each value
// checked on its own (a constraint between keys is checked per point).
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
#include "sim/study/study.h"
#include "sim/study/study_values.h"
#include "util/child_process.h"
#include "util/errors.h"
#include "util/toml_guard.h"
#include "util/version.h"

namespace ropsim {

using namespace study_detail;

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

bool is_run_param(const std::string& k) {
  for (const auto& p : kRunParams)
    if (k == p.key) return true;
  return false;
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
    if (!f || !parse_fidelity(*f)) fail(s, at, to_string(v) + " is not functional, cycle, sampled or approximate");
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
      if (exit_status_of(e) != kUserErrorStatus) throw;  // a broken invariant stays one
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
    if (exit_status_of(e) != kUserErrorStatus) throw;  // a broken invariant stays one
    fail(s, at, e.what());
  }
}

}  // namespace

Study load_study(const std::string& path, const std::string& mesh_dir) {
  std::string text;
  if (!read_text_file(path, text)) throw UserError(path + ": cannot read the study file");
  return parse_study(text, path, mesh_dir);
}

Study parse_study(const std::string& text, const std::string& path, const std::string& mesh_dir) {
  Study s;
  s.path = path;
  if (!mesh_dir.empty()) s.mesh_dir = std::filesystem::absolute(mesh_dir).lexically_normal().string();
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
  // The inputs, each named by its scene's own name unless its entry names it.
  std::map<std::string, std::string> named_by;  // label -> the entry that gave it
  if (const toml::table* in = t["inputs"].as_table()) {
    for (const auto& [k, node] : *in) {
      const std::string key = "inputs." + std::string(k.str());
      if (key != "inputs.scenes" && key != "inputs.traces" && key != "inputs.meshes" && key != "inputs.apps")
        fail(s, key, "unknown key (scenes, traces, meshes, apps)");
      const bool scene = key == "inputs.scenes", trace = key == "inputs.traces", app = key == "inputs.apps";
      const std::string what = scene ? "scene" : "path";
      const std::string expected =
          fmt::format("expected a non-empty list of {} or of tables {{{} = \"...\", name = \"...\"}}",
                      scene ? "built-in scene names" : "file names", what);
      const toml::array* a = node.as_array();
      if (!a || a->empty()) fail(s, key, expected);
      for (size_t i = 0; i < a->size(); ++i) {
        const toml::node& e = *a->get(i);
        StudyInput si;
        si.at = fmt::format("{}[{}]", key, i);
        si.line = int(e.source().begin.line);
        std::string v, name;
        if (auto str = e.value_exact<std::string>()) {
          v = *str;
        } else if (const toml::table* et = e.as_table()) {
          for (const auto& [ek, en] : *et) {
            const std::string ekey(ek.str());
            if (ekey != what && ekey != "name") fail(s, si.at + "." + ekey, "unknown key (" + what + ", name)");
            auto sv = en.value_exact<std::string>();
            if (!sv || sv->empty()) fail(s, si.at + "." + ekey, "expected a non-empty string");
            (ekey == "name" ? name : v) = *sv;
          }
          if (v.empty()) fail(s, si.at, "missing " + what + " = \"...\"");
        } else {
          fail(s, si.at, expected);
        }
        if (scene) {
          bool known = false;
          for (const auto& sc : scene_catalog()) known = known || sc.name == v;
          if (!known) fail(s, si.at, v + " is not a built-in scene (ropsim scene --list)");
          si.scene = si.label = v;
        } else {
          std::filesystem::path p(v);
          if (p.is_relative()) p = dir / p;
          if (!std::filesystem::is_regular_file(p))
            fail(s, si.at,
                 v + (trace ? ": no such trace file"
                      : app ? ": no such application entry file"
                            : ": no such scene file"));
          (trace ? si.trace : app ? si.app : si.mesh) = p.lexically_normal().string();
          si.label = p.stem().string();
          if (app) {
            try {
              si.label = load_app_entry(si.app).name;  // checked now: a bad entry runs nothing
            } catch (const std::exception& ex) {
              if (exit_status_of(ex) != kUserErrorStatus) throw;  // a broken invariant stays one
              fail(s, si.at, ex.what());
            }
          } else if (!trace) {
            try {
              si.label = load_scene_file(si.mesh, scene_overrides(s)).name;  // checked now: a bad file runs nothing
            } catch (const std::exception& ex) {
              if (exit_status_of(ex) != kUserErrorStatus) throw;  // a broken invariant stays one
              fail(s, si.at, ex.what());
            }
          }
        }
        if (!name.empty()) si.label = name;
        if (auto [it, fresh] = named_by.emplace(si.label, si.at); !fresh)
          fail(s, si.at,
               fmt::format("two inputs are named {} ({} too): give one a name of its own, {{{} = \"{}\", name = "
                           "\"...\"}}",
                           si.label, it->second, what, v));
        s.inputs.push_back(si);
      }
    }
  }
  if (s.inputs.empty()) fail(s, "inputs", "a study needs at least one input (inputs.scenes or inputs.traces)");
  bool has_trace = false, has_mesh = false, has_scene = false, has_app = false;
  for (const auto& in : s.inputs) {
    has_trace = has_trace || !in.trace.empty();
    has_mesh = has_mesh || !in.mesh.empty();
    has_app = has_app || !in.app.empty();
    has_scene = has_scene || !in.scene.empty();
  }
  if ((has_mesh || has_app) && s.reference_spp) fail(s, "study.reference_spp", "applies to built-in scenes only");
  if (has_trace && s.reference_spp) fail(s, "study.reference_spp", "applies to scenes only (a trace's spp is fixed)");

  bool any_cycle = false, any_hw = false;
  // A key an axis or a case sets, at `at`: is it a parameter, and does it
  // apply to the study's inputs?
  auto check_key = [&](const std::string& key, const std::string& at) {
    const bool hw = is_hw_key(key);
    if (!is_run_param(key) && !hw)
      fail(s, at,
           "unknown parameter (a run parameter: method, spp, seed, fidelity, hash_bits, alpha_bits, "
           "surface_id_bits, width, height, scene_seed, repeat, order, slab_layers, slab_bits, enderton_selection; or "
           "a hardware key: ropsim config --markdown; or the named cases: cases)");
    if (has_trace && (key == "spp" || key == "width" || key == "height" || key == "scene_seed"))
      fail(s, at, "applies to scenes, meshes and apps only: the study has trace inputs");
    if (key == "scene_seed" && has_app)
      fail(s, at, "applies to scenes and meshes only: the study has application inputs (inputs.apps)");
    if (key == "order" && (has_trace || has_scene || has_app))
      fail(s, at, "applies to mesh inputs only (inputs.meshes): the study has other inputs");
    if (key.rfind("numerics.", 0) == 0)
      fail(s, at,
           "sweep the numerics with the axes hash_bits, alpha_bits and surface_id_bits (they apply to "
           "both fidelities)");
    any_hw = any_hw || hw || key == "design";
  };
  auto check_value = [&](const std::string& key, const std::string& at, const StudyValue& v) {
    if (is_run_param(key)) check_run_value(s, key, at, v);
    if (is_hw_key(key)) check_hw_value(s, key, at, v);
    if (key == "fidelity" && is_timed(to_string(v))) any_cycle = true;
  };
  std::map<std::string, std::string> case_keys;  // a key the cases set -> the first case that sets it
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
      StudyAxis axis{key, {}, {}};
      if (axis.is_cases()) {
        const toml::array* a = node.as_array();
        if (!a || a->empty() || !a->is_array_of_tables())
          fail(s, at, "expected a list of tables, e.g. [{name = \"lk16\", method = \"lk\", spp = 16}]");
        std::map<std::string, std::string> case_named, case_same;  // name / parameters -> the case
        for (size_t i = 0; i < a->size(); ++i) {
          const std::string ca = fmt::format("{}[{}]", at, i);
          std::string name;
          StudyCase c;
          for (const auto& [ck, cn] : *a->get(i)->as_table()) {
            const std::string ckey(ck.str()), cat = ca + "." + ckey;
            if (ckey == "name") {
              auto v = cn.value_exact<std::string>();
              if (!v || v->empty()) fail(s, cat, "expected a non-empty string");
              name = *v;
              continue;
            }
            if (ckey == "cases") fail(s, cat, "a case cannot hold cases");
            if (cn.is_table()) fail(s, cat, "expected a value (a hardware key is quoted: {\"section.key\" = ...})");
            if (cn.is_array())
              fail(s, cat, "a case is one combination: one value per key (sweep a key as an axis of its own)");
            check_key(ckey, cat);
            const StudyValue v = value_of(s, cat, cn);
            check_value(ckey, cat, v);
            c[ckey] = v;
            case_keys.emplace(ckey, ca);
          }
          if (name.empty()) fail(s, ca, "missing name = \"...\" (the case's name in the results)");
          if (auto [it, fresh] = case_named.emplace(name, ca); !fresh)
            fail(s, ca + ".name", "two cases are named " + name + " (" + it->second + " too)");
          if (auto [it, fresh] = case_same.emplace(to_json_params(c).dump(), ca); !fresh)
            fail(s, ca, "sets the parameters of " + it->second + ": two cases would be one combination");
          axis.values.emplace_back(name);
          axis.cases.push_back(std::move(c));
        }
      } else {
        check_key(key, at);
        if (const toml::array* a = node.as_array()) {
          if (a->empty()) fail(s, at, "an axis needs at least one value");
          for (const auto& e : *a) axis.values.push_back(value_of(s, at, e));
        } else {
          axis.values.push_back(value_of(s, at, node));
        }
        std::set<std::string> seen;
        for (const auto& v : axis.values) {
          // Under zip a value may stand at several positions.
          if (s.combine == Study::Combine::kProduct && !seen.insert(to_string(v)).second)
            fail(s, at, "the value " + to_string(v) + " appears twice");
          check_value(key, at, v);
        }
      }
      s.axes.push_back(std::move(axis));
    }
  }
  for (const auto& a : s.axes)
    if (auto c = case_keys.find(a.key); c != case_keys.end())
      fail(s, "axes." + a.key, "is set by " + c->second + " too: a key is an axis or a key of the cases, not both");
  if (any_hw && !any_cycle) fail(s, "axes", "hardware keys need a timed fidelity (cycle or sampled) among the points");
  const size_t zip_n = zip_length(s);
  if (s.combine == Study::Combine::kZip) {
    const StudyAxis* longest = nullptr;
    for (const auto& a : s.axes)
      if (a.values.size() > 1 && !longest) longest = &a;
    for (const auto& a : s.axes)
      if (a.values.size() != 1 && a.values.size() != zip_n)
        fail(s, "axes." + a.key,
             fmt::format("combine = \"zip\" needs lists of one length, or single values, which every position "
                         "takes ({} here, {} for {})",
                         a.values.size(), zip_n, longest->key));
    // Two positions of one combination would be one point.
    std::map<std::string, size_t> position_of;
    for (size_t i = 0; i < zip_n && zip_n <= kMaxStudyPoints; ++i) {
      const StudyCase c = zip_position(s, i);
      if (auto [it, fresh] = position_of.emplace(to_json_params(c).dump(), i); !fresh)
        fail(s, "axes",
             fmt::format("combine = \"zip\": positions {} and {} of the lists (from 1) are the same combination ({}): "
                         "give each position its own values",
                         it->second + 1, i + 1, to_json_params(c).dump()));
    }
  }
  // Bounded before anything is expanded: a product of long lists is refused,
  // not allocated.
  uint64_t points = std::max<size_t>(1, s.inputs.size());
  if (s.combine == Study::Combine::kZip) {
    points = zip_n > kMaxStudyPoints ? kMaxStudyPoints + 1 : points * zip_n;
  } else {
    for (const auto& a : s.axes) {
      const uint64_t n = a.values.size();
      if (n > 0 && points > kMaxStudyPoints / n) {
        points = kMaxStudyPoints + 1;
        break;
      }
      points *= n;
    }
  }
  if (points > kMaxStudyPoints)
    fail(s, "axes", fmt::format("the inputs and axes give more than {} points", kMaxStudyPoints));
  s.points_at_most = points;
  return s;
}

}  // namespace ropsim
