#include "traces/format/draw_state.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "traces/format/utf8.h"
#include "util/errors.h"

namespace ropsim {

const char* to_string(DrawKind k) {
  switch (k) {
    case DrawKind::kOpaque:
      return "opaque";
    case DrawKind::kSrcOver:
      return "src-over";
    case DrawKind::kPremultipliedOver:
      return "premultiplied-over";
    case DrawKind::kAdditive:
      return "additive";
    case DrawKind::kOther:
      return "other";
  }
  return "?";
}

const char* to_string(BlendFactor f) {
  static const char* const names[] = {"ZERO",
                                      "ONE",
                                      "SRC_COLOR",
                                      "ONE_MINUS_SRC_COLOR",
                                      "DST_COLOR",
                                      "ONE_MINUS_DST_COLOR",
                                      "SRC_ALPHA",
                                      "ONE_MINUS_SRC_ALPHA",
                                      "DST_ALPHA",
                                      "ONE_MINUS_DST_ALPHA",
                                      "CONSTANT_COLOR",
                                      "ONE_MINUS_CONSTANT_COLOR",
                                      "CONSTANT_ALPHA",
                                      "ONE_MINUS_CONSTANT_ALPHA",
                                      "SRC_ALPHA_SATURATE"};
  const auto i = static_cast<size_t>(f);
  return i < sizeof(names) / sizeof(names[0]) ? names[i] : "?";
}

const char* to_string(BlendEquation e) {
  static const char* const names[] = {"FUNC_ADD", "FUNC_SUBTRACT", "FUNC_REVERSE_SUBTRACT", "MIN", "MAX"};
  const auto i = static_cast<size_t>(e);
  return i < sizeof(names) / sizeof(names[0]) ? names[i] : "?";
}

const char* to_string(DepthFunc f) {
  static const char* const names[] = {"NEVER", "LESS", "EQUAL", "LEQUAL", "GREATER", "NOTEQUAL", "GEQUAL", "ALWAYS"};
  const auto i = static_cast<size_t>(f);
  return i < sizeof(names) / sizeof(names[0]) ? names[i] : "?";
}

const char* to_string(TargetEncoding e) {
  switch (e) {
    case TargetEncoding::kUnorm8:
      return "unorm8";
    case TargetEncoding::kSrgb8:
      return "srgb8";
    case TargetEncoding::kFloat:
      return "float";
  }
  return "?";
}

DrawState default_draw_state(uint32_t draw_id) {
  DrawState s;
  s.draw_id = draw_id;
  return s;
}

DrawKind draw_kind(const DrawState& s) {
  using F = BlendFactor;
  if (!s.blend) return DrawKind::kOpaque;
  if (s.eq_rgb != BlendEquation::kAdd) return DrawKind::kOther;
  if (s.src_rgb == F::kOne && s.dst_rgb == F::kZero) return DrawKind::kOpaque;  // blending that replaces
  if (s.src_rgb == F::kSrcAlpha && s.dst_rgb == F::kOneMinusSrcAlpha) return DrawKind::kSrcOver;
  if (s.src_rgb == F::kOne && s.dst_rgb == F::kOneMinusSrcAlpha) return DrawKind::kPremultipliedOver;
  if ((s.src_rgb == F::kOne || s.src_rgb == F::kSrcAlpha) && s.dst_rgb == F::kOne) return DrawKind::kAdditive;
  return DrawKind::kOther;
}

DrawTable::DrawTable(std::vector<DrawState> states) : states_(std::move(states)) {
  std::stable_sort(states_.begin(), states_.end(),
                   [](const DrawState& a, const DrawState& b) { return a.draw_id < b.draw_id; });
}

const DrawState* DrawTable::find(uint32_t draw_id) const {
  const auto it = std::lower_bound(states_.begin(), states_.end(), draw_id,
                                   [](const DrawState& s, uint32_t id) { return s.draw_id < id; });
  return it != states_.end() && it->draw_id == draw_id ? &*it : nullptr;
}

const DrawState& DrawTable::at(uint32_t draw_id) const {
  if (states_.empty()) {
    // One immutable state shared by every id (and every thread): the default
    // state's rules do not depend on the draw.
    static const DrawState kDefault = default_draw_state(0);
    return kDefault;
  }
  if (const DrawState* s = find(draw_id)) return *s;
  throw InternalError("every fragment's draw has a draw state (draw " + std::to_string(draw_id) + " has none)");
}

std::string DrawTable::validate() const {
  for (size_t i = 0; i < states_.size(); ++i) {
    const DrawState& s = states_[i];
    const std::string at = "draw state " + std::to_string(i) + " (draw " + std::to_string(s.draw_id) + "): ";
    if (i > 0 && states_[i - 1].draw_id == s.draw_id) return at + "a second state for the same draw";
    if (s.eq_rgb > kLastBlendEquation || s.eq_alpha > kLastBlendEquation) return at + "blend equation out of range";
    for (BlendFactor f : {s.src_rgb, s.dst_rgb, s.src_alpha, s.dst_alpha})
      if (f > kLastBlendFactor) return at + "blend factor out of range";
    if (s.depth_func > kLastDepthFunc) return at + "depth function out of range";
    if (s.encoding > kLastTargetEncoding) return at + "target encoding out of range";
    if (s.color_mask > 0xF) return at + "colour mask above 15";
    if (s.name.size() > 255) return at + "name longer than 255 bytes";
    if (!is_valid_utf8(s.name)) return at + "name is not valid UTF-8";
    for (float c : s.blend_color)
      if (!std::isfinite(c)) return at + "blend colour not finite";
  }
  return "";
}

bool DrawTable::operator==(const DrawTable& o) const {
  if (states_.size() != o.states_.size()) return false;
  for (size_t i = 0; i < states_.size(); ++i) {
    const DrawState &a = states_[i], &b = o.states_[i];
    if (a.draw_id != b.draw_id || a.blend != b.blend || a.eq_rgb != b.eq_rgb || a.eq_alpha != b.eq_alpha ||
        a.src_rgb != b.src_rgb || a.dst_rgb != b.dst_rgb || a.src_alpha != b.src_alpha || a.dst_alpha != b.dst_alpha ||
        a.blend_color != b.blend_color || a.depth_test != b.depth_test || a.depth_func != b.depth_func ||
        a.depth_write != b.depth_write || a.color_mask != b.color_mask || a.encoding != b.encoding || a.name != b.name)
      return false;
  }
  return true;
}

}  // namespace ropsim
