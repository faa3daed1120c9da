#include "sim/study/study_values.h"

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
#include "util/child_process.h"
#include "util/errors.h"
#include "util/toml_guard.h"
#include "util/version.h"

namespace ropsim::study_detail {

bool is_sampling_key(const std::string& k) { return k.rfind("sample_", 0) == 0; }

bool is_timed(const std::string& f) {
  const auto fid = parse_fidelity(f);
  return fid && is_timed(*fid);
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

SceneOverrides scene_overrides(const Study& s) {
  SceneOverrides o;
  if (!s.mesh_dir.empty()) o.mesh_dir = s.mesh_dir;
  return o;
}

void put_value(StudyCase& m, const StudyAxis& a, size_t i) {
  if (a.is_cases()) {
    m[kCaseParam] = a.values[i];
    for (const auto& [k, v] : a.cases[i]) m[k] = v;
  } else {
    m[a.key] = a.values[i];
  }
}

size_t zip_length(const Study& s) {
  size_t n = 1;
  for (const auto& a : s.axes) n = std::max(n, a.values.size());
  return n;
}

StudyCase zip_position(const Study& s, size_t i) {
  StudyCase m;
  for (const auto& a : s.axes) put_value(m, a, a.values.size() == 1 ? 0 : i);
  return m;
}

nlohmann::ordered_json to_json_params(const StudyCase& c) {
  nlohmann::ordered_json j = nlohmann::ordered_json::object();
  for (const auto& [k, v] : c) j[k] = to_json(v);
  return j;
}

bool is_regular_file(const std::string& p) {
  std::error_code ec;
  return std::filesystem::is_regular_file(p, ec);
}

uint64_t hash_text(const std::string& s) {
  uint64_t h = 0x9e3779b97f4a7c15ull;
  for (unsigned char c : s) h = mix64(h ^ c);
  return mix64(h ^ s.size());
}

}  // namespace ropsim::study_detail
