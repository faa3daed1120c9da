#include "rtl_models/functional/method.h"

namespace ropsim {

namespace {
constexpr bool every_method_has_its_row() {
  int i = 0;
  for (const auto& t : kMethodTable)
    if (int(t.method) != i++) return false;
  return i == int(kLastMethod) + 1;
}
static_assert(every_method_has_its_row(), "kMethodTable: one row per Method, in enumerator order");
}  // namespace

const char* to_string(Method m) { return traits(m).name; }

const char* to_string(EndertonSelection s) { return s == EndertonSelection::kOriginal ? "original" : "depth-first"; }

bool parse_enderton_selection(const std::string& s, EndertonSelection& out) {
  for (EndertonSelection e : {EndertonSelection::kDepthFirst, EndertonSelection::kOriginal})
    if (s == to_string(e)) {
      out = e;
      return true;
    }
  return false;
}

const char* to_string(PassKind p) {
  switch (p) {
    case PassKind::kTotalAlpha:
      return "total_alpha";
    case PassKind::kStochastic:
      return "stochastic";
    case PassKind::kAccumulate:
      return "accumulate";
    case PassKind::kWboit:
      return "wboit";
    case PassKind::kFramebuffer:
      return "framebuffer";
    case PassKind::kPrepass:
      return "prepass";
  }
  return "?";
}

bool parse_method(const std::string& s, Method& out) {
  for (const auto& t : kMethodTable)
    if (s == t.name) {
      out = t.method;
      return true;
    }
  return false;
}

const std::vector<std::string>& method_names() {
  static const std::vector<std::string> v = [] {
    std::vector<std::string> r;
    for (const auto& t : kMethodTable) r.push_back(t.name);
    return r;
  }();
  return v;
}

}  // namespace ropsim
