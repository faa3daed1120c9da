// Reading one TOML table of an input file (a mesh scene file, an application
// entry) key by key: typed getters that remember which keys were read, so
// that finish() names the first unknown key. Every error is Error("FILE:LINE:
// PREFIXKEY: what"), one line.
#pragma once
#include <toml++/toml.h>

#include <array>
#include <cmath>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace ropsim::detail {

/// Reads the keys of one TOML table, remembering which were used, so that
/// finish() can name the first unknown key. Every error names file:line: key.
template <class Error>
class TomlKeys {
 public:
  TomlKeys(const toml::table& t, std::string file, std::string prefix)
      : t_(t), file_(std::move(file)), prefix_(std::move(prefix)) {}

  [[noreturn]] void fail(const toml::node* n, const std::string& key, const std::string& what) const {
    std::string where = file_;
    const toml::node* at = n ? n : &t_;
    if (at->source().begin.line) where += ":" + std::to_string(at->source().begin.line);
    throw Error(where + ": " + prefix_ + key + ": " + what);
  }
  const toml::node* node(const std::string& key) {
    used_.insert(key);
    return t_.get(key);
  }
  std::optional<double> number(const std::string& key) {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    if (!n->is_number()) fail(n, key, "must be a number");
    double v = *n->value<double>();
    if (!std::isfinite(v)) fail(n, key, "must be finite");
    return v;
  }
  double number_in(const std::string& key, double def, double lo, double hi, const char* range) {
    auto v = number(key);
    if (!v) return def;
    if (!(*v >= lo && *v <= hi)) fail(node(key), key, std::string("must be in ") + range);
    return *v;
  }
  std::optional<int64_t> integer(const std::string& key) {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    if (!n->is_integer()) fail(n, key, "must be an integer");
    return *n->value<int64_t>();
  }
  std::optional<bool> boolean(const std::string& key) {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    if (!n->is_boolean()) fail(n, key, "must be true or false");
    return *n->value<bool>();
  }
  std::optional<std::string> string(const std::string& key) {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    if (!n->is_string()) fail(n, key, "must be a string");
    return *n->value<std::string>();
  }
  std::string choice(const std::string& key, const std::string& def, const std::vector<std::string>& allowed) {
    auto v = string(key);
    if (!v) return def;
    for (const auto& a : allowed)
      if (*v == a) return a;
    std::string list;
    for (const auto& a : allowed) list += (list.empty() ? "\"" : ", \"") + a + "\"";
    fail(node(key), key, "\"" + *v + "\" is not one of " + list);
  }
  std::optional<std::array<double, 3>> vec3(const std::string& key) {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    const toml::array* a = n->as_array();
    if (!a || a->size() != 3) fail(n, key, "must be an array of 3 numbers");
    std::array<double, 3> v{};
    for (size_t i = 0; i < 3; ++i) {
      const toml::node& e = *a->get(i);
      if (!e.is_number() || !std::isfinite(*e.value<double>())) fail(n, key, "must be an array of 3 finite numbers");
      v[i] = *e.value<double>();
    }
    return v;
  }
  std::optional<std::array<float, 3>> rgb(const std::string& key) {
    auto v = vec3(key);
    if (!v) return std::nullopt;
    for (double c : *v)
      if (c < 0) fail(node(key), key, "colour components must be >= 0 (linear RGB)");
    return std::array<float, 3>{float((*v)[0]), float((*v)[1]), float((*v)[2])};
  }
  /// An array of strings (nullopt when absent); an empty array when
  /// non_empty is false.
  std::optional<std::vector<std::string>> strings(const std::string& key, bool non_empty = true) {
    const toml::node* n = node(key);
    if (!n) return std::nullopt;
    const toml::array* a = n->as_array();
    if (!a) fail(n, key, "must be an array of strings");
    std::vector<std::string> out;
    for (const toml::node& e : *a) {
      if (!e.is_string()) fail(n, key, "must be an array of strings");
      out.push_back(*e.value<std::string>());
    }
    if (non_empty && out.empty()) fail(n, key, "must not be empty");
    return out;
  }
  const toml::table* table(const std::string& key) {
    const toml::node* n = node(key);
    if (!n) return nullptr;
    if (!n->is_table()) fail(n, key, "must be a table");
    return n->as_table();
  }
  void finish() const {
    for (auto&& [k, v] : t_)
      if (!used_.count(std::string(k.str()))) fail(&v, std::string(k.str()), "unknown key");
  }
  const std::string& file() const { return file_; }

 private:
  const toml::table& t_;
  std::string file_, prefix_;
  std::set<std::string> used_;
};

}  // namespace ropsim::detail
