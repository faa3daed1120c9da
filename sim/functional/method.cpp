#include "method.h"

#include <stdexcept>

namespace ropsim {

const std::vector<MethodTraits>& method_table() {
  //                         pipeline select tracker sorter reference seeded
  static const std::vector<MethodTraits> t = {
      {Method::kLk, "lk", "Laine & Karras 2011: stratified stochastic transparency", true, false, true, true, true,
       false},
      {Method::kEnderton, "enderton", "Enderton et al. 2010: R = floor(alpha m + xi) survivors chosen at random",
       true, false, false, false, true, true},
      {Method::kNaive, "naive", "naive stochastic transparency: one random reference per sample", true, false, false,
       false, true, true},
      {Method::kA2c, "a2c", "alpha-to-coverage: a dithered fixed sample mask", true, true, false, false, false, false},
      {Method::kOpaque, "opaque", "a plain z-buffer: every covered sample that passes is written", true, false, false,
       false, false, false},
      {Method::kReference, "reference", "A-buffer ground truth: every fragment of every sample, sorted", false, false,
       false, false, false, false},
  };
  return t;
}

const MethodTraits& traits(Method m) {
  for (const auto& t : method_table())
    if (t.method == m) return t;
  throw std::logic_error("method without traits");
}

const char* to_string(Method m) { return traits(m).name; }

bool parse_method(const std::string& s, Method& out) {
  for (const auto& t : method_table())
    if (s == t.name) {
      out = t.method;
      return true;
    }
  return false;
}

const std::vector<std::string>& method_names() {
  static const std::vector<std::string> v = [] {
    std::vector<std::string> r;
    for (const auto& t : method_table()) r.push_back(t.name);
    return r;
  }();
  return v;
}

}  // namespace ropsim
