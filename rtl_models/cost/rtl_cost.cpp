#include "rtl_models/cost/rtl_cost.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <mutex>
#include <sstream>
#include <stdexcept>

#include "rtl_models/algo/bits.h"
#include "rtl_models/algo/hilbert.h"
#include "rtl_synth_sweep_csv.h"  // docs/data/rtl_synth_sweep.csv, embedded by cmake/embed_csv.cmake
#include "util/errors.h"

namespace ropsim {

namespace {

int64_t at(const RtlParams& p, const char* k) { return p.at(k); }
double log2d(int64_t v) { return std::log2(double(v)); }
int bit_length(int64_t v) {
  int n = 0;
  while (v > 0) {
    ++n;
    v >>= 1;
  }
  return n;
}

/// A parameter a module takes and the range its model covers.
struct Key {
  const char* name;
  int64_t lo, hi;
};

/// One module's structural model (docs/rtl.md "Cost of a design"):
/// flip-flops counted from the RTL's registers where that count is exact
/// (checked against every sweep row by the tests), the rest of the area (the
/// logic: NAND2 equivalents minus 4 per flip-flop) and the levels linear in
/// a few structural terms, fitted to the sweep by least squares on the
/// relative error.
struct ModuleModel {
  const char* module;
  std::vector<Key> keys;          ///< the parameters that change the netlist
  std::vector<const char*> free;  ///< parameters that do not (any value; the sweep's row stands for it)
  std::function<std::optional<int64_t>(const RtlParams&)> flipflops;  ///< exact count, or none
  std::function<std::vector<double>(const RtlParams&)> gates;         ///< terms of the logic (or of all the area)
  std::function<std::vector<double>(const RtlParams&)> levels;        ///< terms of the levels
  const char* level_group = nullptr;  ///< levels are fitted among rows with this parameter equal
  RtlModelBounds bounds;
};

const std::vector<ModuleModel>& models() {
  static const std::vector<ModuleModel> m = {
      {"rop_hilbert_index",
       {{"ORDER", 1, 16}, {"STAGES", 1, 64}},
       {},
       [](const RtlParams& p) { return at(p, "STAGES") * (2 * at(p, "ORDER") + 1); },
       [](const RtlParams& p) {
         return std::vector<double>{double(at(p, "ORDER")), 1.0};
       },
       [](const RtlParams& p) {
         return std::vector<double>{double(at(p, "ORDER")), 1.0};
       },
       nullptr,
       {0.05, 0.02}},
      {"rop_depth_compare",
       {{"LANES", 1, 64}, {"STAGES", 1, 64}},
       {},
       [](const RtlParams& p) { return at(p, "STAGES") * (at(p, "LANES") + 1); },
       [](const RtlParams& p) {
         return std::vector<double>{double(at(p, "LANES")), 1.0};
       },
       [](const RtlParams&) { return std::vector<double>{1.0}; },
       nullptr,
       {0.09, 0.06}},
      {"rop_tracker_update",
       {{"SPP", 1, 64}, {"SID_BITS", 1, 32}, {"STAGES", 1, 64}},
       {},
       [](const RtlParams& p) {
         const int64_t spp = at(p, "SPP");
         return at(p, "STAGES") * (spp + at(p, "SID_BITS") + bit_length(spp) + 2);
       },
       [](const RtlParams& p) {
         const double s = double(at(p, "SPP"));
         return std::vector<double>{s, s * std::log2(s), double(at(p, "SID_BITS")), 1.0};
       },
       [](const RtlParams& p) {
         return std::vector<double>{log2d(at(p, "SPP")), double(at(p, "SID_BITS")), 1.0};
       },
       nullptr,
       {0.07, 0.25}},
      {"rop_bitonic_sorter",
       {{"N", 4, 64}},  // every spp has its sweep row; the model (checked on N = 4..64) is for other N
       {},
       [](const RtlParams&) { return std::optional<int64_t>{}; },  // Yosys trims the key registers: no exact count
       [](const RtlParams& p) {
         const double n = double(at(p, "N")), k = log2d(at(p, "N"));
         return std::vector<double>{n * k * (k + 1) / 4, n, 1.0};
       },
       [](const RtlParams& p) {
         return std::vector<double>{log2d(at(p, "N")), 1.0};
       },
       nullptr,
       {0.07, 0.15}},
      {"rop_alpha_ref",
       {{"LANES", 1, 64}, {"STAGES", 1, 64}, {"HASH_BITS", 8, 32}, {"SID_BITS", 1, 32}},
       {"SPP", "PIXEL_BITS"},
       [](const RtlParams& p) { return at(p, "STAGES") * (at(p, "LANES") * at(p, "HASH_BITS") + 1); },
       [](const RtlParams& p) {
         const double l = double(at(p, "LANES")), h = double(at(p, "HASH_BITS"));
         const double sid = double(std::min(at(p, "SID_BITS"), at(p, "HASH_BITS")));
         return std::vector<double>{l * h * h, l * h, l, l * sid, h, 1.0};
       },
       [](const RtlParams& p) {
         return std::vector<double>{double(at(p, "HASH_BITS")), log2d(at(p, "LANES")), 1.0};
       },
       "STAGES",
       {0.08, 0.55}},
      {"rop_opacity_test",
       {{"LANES", 1, 64}, {"ALPHA_BITS", 1, 32}, {"HASH_BITS", 8, 32}, {"STAGES", 1, 64}},
       {},
       [](const RtlParams& p) { return at(p, "STAGES") * (at(p, "LANES") + 1); },
       [](const RtlParams& p) {
         const double l = double(at(p, "LANES"));
         const int64_t a1 = at(p, "ALPHA_BITS") + 1, h = at(p, "HASH_BITS");
         // one comparator of min(A + 1, h) bits a lane (the shifted operand's low zeros cost nothing)
         return std::vector<double>{l * double(std::min(a1, h)), l, 1.0};
       },
       [](const RtlParams& p) {
         return std::vector<double>{double(std::min(at(p, "ALPHA_BITS") + 1, at(p, "HASH_BITS"))), 1.0};
       },
       nullptr,
       {0.25, 0.35}},
  };
  return m;
}

const ModuleModel* find_model(const std::string& module) {
  for (const auto& m : models())
    if (module == m.module) return &m;
  return nullptr;
}

/// Least squares on the terms given, min sum ((x_i . c - y_i) / w_i)^2, through
/// the normal equations (Gaussian elimination with partial pivoting);
/// nothing when the rows do not determine c.
std::optional<std::vector<double>> solve(const std::vector<std::vector<double>>& x, const std::vector<double>& y,
                                         const std::vector<double>& w) {
  if (x.empty()) return std::nullopt;
  const size_t n = x[0].size();
  if (n == 0 || n > 16 || x.size() < n) return std::nullopt;  // a model has a handful of terms
  std::vector<std::vector<double>> a(n, std::vector<double>(n + 1, 0.0));
  for (size_t i = 0; i < x.size(); ++i) {
    const double wi = 1.0 / (w[i] * w[i]);
    for (size_t r = 0; r < n; ++r) {
      for (size_t c = 0; c < n; ++c) a[r][c] += wi * x[i][r] * x[i][c];
      a[r][n] += wi * x[i][r] * y[i];
    }
  }
  for (size_t col = 0; col < n; ++col) {
    size_t piv = col;
    for (size_t r = col + 1; r < n; ++r)
      if (std::fabs(a[r][col]) > std::fabs(a[piv][col])) piv = r;
    double scale = 0;
    for (size_t c = 0; c < n; ++c) scale = std::max(scale, std::fabs(a[col][c]));
    if (std::fabs(a[piv][col]) <= 1e-12 * std::max(1.0, scale)) return std::nullopt;  // collinear terms
    std::swap(a[col], a[piv]);
    for (size_t r = 0; r < n; ++r) {
      if (r == col) continue;
      const double f = a[r][col] / a[col][col];
      for (size_t c = col; c <= n; ++c) a[r][c] -= f * a[col][c];
    }
  }
  std::vector<double> c(n);
  for (size_t r = 0; r < n; ++r) c[r] = a[r][n] / a[r][r];
  return c;
}

/// The same, but a term that is zero on every row (log2 LANES where
/// only one lane was synthesised) gets coefficient 0. Returns nothing when
/// the rows do not determine the other terms.
std::optional<std::vector<double>> fit(const std::vector<std::vector<double>>& x_all, const std::vector<double>& y,
                                       const std::vector<double>& w) {
  if (x_all.empty()) return std::nullopt;
  std::vector<size_t> used;
  for (size_t c = 0; c < x_all[0].size(); ++c)
    for (const auto& row : x_all)
      if (row[c] != 0) {
        used.push_back(c);
        break;
      }
  std::vector<std::vector<double>> x;
  for (const auto& row : x_all) {
    std::vector<double> r;
    for (size_t c : used) r.push_back(row[c]);
    x.push_back(std::move(r));
  }
  const auto c = solve(x, y, w);
  if (!c) return std::nullopt;
  std::vector<double> full(x_all[0].size(), 0.0);
  for (size_t i = 0; i < used.size(); ++i) full[used[i]] = (*c)[i];
  return full;
}

double dot(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += a[i] * b[i];
  return s;
}

/// The row's parameters restricted to the model's keys (the free ones
/// dropped); nullopt when the row lacks a key.
std::optional<RtlParams> key_params(const ModuleModel& m, const RtlParams& p) {
  RtlParams k;
  for (const Key& key : m.keys) {
    const auto it = p.find(key.name);
    if (it == p.end()) return std::nullopt;
    k[key.name] = it->second;
  }
  return k;
}

std::string params_text(const RtlParams& p) {
  std::string s;
  for (const auto& [k, v] : p) s += (s.empty() ? "" : " ") + k + "=" + std::to_string(v);
  return s;
}

/// Checks the parameters against the model's keys and ranges: "" or why not.
std::string check_params(const ModuleModel& m, const RtlParams& p) {
  for (const Key& key : m.keys) {
    const auto it = p.find(key.name);
    if (it == p.end()) return std::string(m.module) + ": parameter " + key.name + " not given";
    if (it->second < key.lo || it->second > key.hi)
      return std::string(m.module) + ": " + key.name + "=" + std::to_string(it->second) + " outside the modelled " +
             std::to_string(key.lo) + ".." + std::to_string(key.hi);
  }
  for (const auto& [k, v] : p) {
    bool known = std::find(m.free.begin(), m.free.end(), k) != m.free.end();
    for (const Key& key : m.keys) known = known || k == key.name;
    if (!known) return std::string(m.module) + ": unknown parameter " + k;
  }
  if (std::string(m.module) == "rop_bitonic_sorter" && !is_pow2(unsigned(p.at("N"))))
    return "rop_bitonic_sorter: N=" + std::to_string(p.at("N")) + " is not a power of two";
  return "";
}

}  // namespace

std::vector<RtlSynthRow> parse_rtl_synth_csv(const std::string& text, const std::string& name) {
  std::vector<RtlSynthRow> rows;
  std::istringstream in(text);
  std::string line;
  int no = 0;
  auto fail = [&](const std::string& why) { throw UserError(name + ": line " + std::to_string(no) + ": " + why); };
  while (std::getline(in, line)) {
    ++no;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    if (no == 1) {
      if (line.rfind("module,params,cells,flipflops,transistors,nand2_eq,levels", 0) != 0)
        fail("expected the header of scripts/synth.sh");
      continue;
    }
    // module,"NAME=V ...",cells,flipflops,transistors,nand2_eq,levels,seconds
    std::vector<std::string> f;
    std::string cur;
    bool quoted = false;
    for (char c : line) {
      if (c == '"') {
        quoted = !quoted;
      } else if (c == ',' && !quoted) {
        f.push_back(cur);
        cur.clear();
      } else {
        cur += c;
      }
    }
    f.push_back(cur);
    if (f.size() < 7) fail("expected 8 columns");
    RtlSynthRow r;
    r.module = f[0];
    r.params_text = f[1];
    std::istringstream ps(f[1]);
    std::string kv;
    while (ps >> kv) {
      const auto eq = kv.find('=');
      if (eq == std::string::npos || eq == 0) fail("parameter " + kv + " is not NAME=VALUE");
      try {
        r.params[kv.substr(0, eq)] = std::stoll(kv.substr(eq + 1));
      } catch (const std::exception&) {
        fail("parameter " + kv + ": not an integer");
      }
    }
    int64_t* cols[] = {&r.cells, &r.flipflops, &r.transistors, &r.nand2_eq, &r.levels};
    for (int i = 0; i < 5; ++i) {
      size_t used = 0;
      try {
        *cols[i] = std::stoll(f[size_t(2 + i)], &used);
      } catch (const std::exception&) {  // std::stoll's: not a number, or out of range
        used = 0;
      }
      if (used == 0 || used != f[size_t(2 + i)].size()) fail("column " + std::to_string(3 + i) + " is not an integer");
    }
    rows.push_back(std::move(r));
  }
  if (rows.empty()) throw UserError(name + ": no synthesis run");
  return rows;
}

const std::vector<RtlSynthRow>& rtl_synth_table() {
  static const std::vector<RtlSynthRow> t = parse_rtl_synth_csv(kRtlSynthSweepCsv, "docs/data/rtl_synth_sweep.csv");
  return t;
}

const std::vector<std::string>& rtl_cost_modules() {
  static const std::vector<std::string> m = [] {
    std::vector<std::string> v;
    for (const auto& x : models()) v.push_back(x.module);
    return v;
  }();
  return m;
}

const char* to_string(CostSource s) {
  switch (s) {
    case CostSource::kSweep:
      return "sweep";
    case CostSource::kModel:
      return "model";
    case CostSource::kNone:
      return "none";
  }
  return "?";
}

RtlModelBounds rtl_model_bounds(const std::string& module) {
  const ModuleModel* m = find_model(module);
  return m ? m->bounds : RtlModelBounds{};
}

RtlCost rtl_cost_model(const std::string& module, const RtlParams& params, const std::vector<RtlSynthRow>& table) {
  RtlCost r;
  const ModuleModel* m = find_model(module);
  if (!m) {
    r.reason = module + ": no reference RTL";
    return r;
  }
  if (std::string why = check_params(*m, params); !why.empty()) {
    r.reason = why;
    return r;
  }
  // The logic (or the whole area where flip-flops have no exact count).
  std::vector<std::vector<double>> xg, xl;
  std::vector<double> yg, wg, yl, wl;
  const auto ff = m->flipflops(params);
  for (const RtlSynthRow& row : table) {
    if (row.module != module || !key_params(*m, row.params) || !check_params(*m, row.params).empty()) continue;
    const auto rff = m->flipflops(row.params);
    xg.push_back(m->gates(row.params));
    yg.push_back(double(row.nand2_eq) - (rff ? 4.0 * double(*rff) : 0.0));
    wg.push_back(double(row.nand2_eq));
    if (!m->level_group || row.params.at(m->level_group) == params.at(m->level_group)) {
      xl.push_back(m->levels(row.params));
      yl.push_back(double(row.levels));
      wl.push_back(double(row.levels));
    }
  }
  const auto cg = fit(xg, yg, wg);
  if (!cg) {
    r.reason = module + ": too few sweep rows to fit the model (" + std::to_string(xg.size()) + ")";
    return r;
  }
  r.source = CostSource::kModel;
  // Whole gates and levels: the model's figures are estimates within the bounds, not to the last gate.
  r.nand2_eq = std::round(dot(*cg, m->gates(params)) + (ff ? 4.0 * double(*ff) : 0.0));
  r.nand2_error_bound = m->bounds.nand2;
  r.flipflops = ff;
  if (!ff) r.reason = module + ": flip-flops are counted only by synthesis (not in the sweep for these parameters)";
  const auto cl = fit(xl, yl, wl);
  if (cl) {
    r.levels = std::round(dot(*cl, m->levels(params)));
    r.levels_error_bound = m->bounds.levels;
  } else {
    r.reason +=
        std::string(r.reason.empty() ? "" : "; ") + module + ": levels: too few sweep rows" +
        (m->level_group ? std::string(" with ") + m->level_group + "=" + std::to_string(params.at(m->level_group))
                        : std::string()) +
        " to fit";
  }
  return r;
}

RtlCost rtl_cost(const std::string& module, const RtlParams& params, const std::vector<RtlSynthRow>& table) {
  const ModuleModel* m = find_model(module);
  const std::optional<RtlParams> key = m ? key_params(*m, params) : std::nullopt;
  if (key) {
    const RtlParams& want = *key;
    for (const RtlSynthRow& row : table) {
      if (row.module != module || key_params(*m, row.params) != want) continue;
      RtlCost r;
      r.source = CostSource::kSweep;
      r.nand2_eq = double(row.nand2_eq);
      r.flipflops = row.flipflops;
      r.levels = double(row.levels);
      if (row.params != params) r.reason = "the sweep row " + row.params_text + " (same netlist)";
      return r;
    }
  }
  return rtl_cost_model(module, params, table);
}

std::vector<HeldOutError> rtl_model_check(const std::vector<RtlSynthRow>& table) {
  std::vector<HeldOutError> out;
  for (size_t i = 0; i < table.size(); ++i) {
    std::vector<RtlSynthRow> rest = table;
    rest.erase(rest.begin() + long(i));
    const RtlSynthRow& r = table[i];
    const RtlCost m = rtl_cost_model(r.module, r.params, rest);
    HeldOutError e{r.module, r.params_text, std::nullopt, std::nullopt, m.reason};
    if (m.nand2_eq) e.nand2_error = (*m.nand2_eq - double(r.nand2_eq)) / double(r.nand2_eq);
    if (m.levels) e.levels_error = (*m.levels - double(r.levels)) / double(r.levels);
    out.push_back(std::move(e));
  }
  return out;
}

DesignCost design_cost(const RtlDesign& d) {
  DesignCost out;
  if (!d.lk_selection) {
    out.reason = "method " + d.method + ": only lk's units have reference RTL (rtl_models/rtl)";
    return out;
  }
  const int order = std::max(1, bit_length(int64_t(hilbert_side(uint32_t(d.width), uint32_t(d.height)))) - 1);
  const int64_t sid = d.numerics.surface_id_bits, h = d.numerics.hash_bits;
  struct Inst {
    const char* unit;
    const char* module;
    RtlParams params;
  };
  std::vector<Inst> inst = {
      {"hilbert_index", "rop_hilbert_index", {{"ORDER", order}, {"STAGES", 1}}},
      {"depth_compare", "rop_depth_compare", {{"LANES", d.depth_lanes}, {"STAGES", d.depth_stages}}},
      {"tracker_update", "rop_tracker_update", {{"SPP", d.spp}, {"SID_BITS", sid}, {"STAGES", d.tracker_stages}}},
      {"sorter", "rop_bitonic_sorter", {{"N", d.spp}}},
      {"alpha_ref",
       "rop_alpha_ref",
       {{"LANES", d.alpha_ref_lanes},
        {"STAGES", d.alpha_ref_stages},
        {"HASH_BITS", h},
        {"SPP", d.spp},
        {"SID_BITS", sid},
        {"PIXEL_BITS", 32}}},
      {"opacity_test",
       "rop_opacity_test",
       {{"LANES", d.opacity_lanes}, {"ALPHA_BITS", d.numerics.alpha_bits}, {"HASH_BITS", h}, {"STAGES", 1}}},
  };
  double gates = 0, levels = 0;
  int64_t ffs = 0;
  bool all = true;
  for (const Inst& i : inst) {
    UnitCost u{i.unit, i.module, params_text(i.params), {}};
    if (std::string(i.unit) == "sorter" && d.sorter_kind != "bitonic")
      u.cost.reason = "sorter.kind " + d.sorter_kind + ": no reference RTL (only the bitonic network has one)";
    else
      u.cost = rtl_cost(i.module, i.params);
    if (u.cost.nand2_eq && u.cost.flipflops && u.cost.levels) {
      gates += *u.cost.nand2_eq;
      ffs += *u.cost.flipflops;
      levels = std::max(levels, *u.cost.levels);
    } else {
      all = false;
      if (out.reason.empty()) out.reason = std::string(i.unit) + ": " + u.cost.reason;
    }
    out.units.push_back(std::move(u));
  }
  if (all && d.blend_pass) {
    all = false;
    out.reason = "method " + d.method + ": its blend unit has no reference RTL";
  }
  if (all) {
    out.rop_nand2_eq = gates;
    out.rop_flipflops = ffs;
    out.rop_levels = levels;
    out.total_nand2_eq = gates * d.rop_units;
    out.total_flipflops = ffs * d.rop_units;
  }
  return out;
}

}  // namespace ropsim
