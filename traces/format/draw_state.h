// A draw's fixed-function state as the ROP sees it (trace format v2, section
// 1.5 of docs/trace-format.md): blending, depth test and write, colour-write
// mask, and the encoding of the framebuffer it draws into. The methods read it
// to tell opaque draws from transparent and order-independent ones. No
// SystemC here.
#pragma once
#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace ropsim {

/// GL's blend factors (glBlendFuncSeparate), in this order on the wire.
enum class BlendFactor : uint8_t {
  kZero,
  kOne,
  kSrcColor,
  kOneMinusSrcColor,
  kDstColor,
  kOneMinusDstColor,
  kSrcAlpha,
  kOneMinusSrcAlpha,
  kDstAlpha,
  kOneMinusDstAlpha,
  kConstantColor,
  kOneMinusConstantColor,
  kConstantAlpha,
  kOneMinusConstantAlpha,
  kSrcAlphaSaturate,
};
inline constexpr BlendFactor kLastBlendFactor = BlendFactor::kSrcAlphaSaturate;
/// GL's blend equations (glBlendEquationSeparate).
enum class BlendEquation : uint8_t { kAdd, kSubtract, kReverseSubtract, kMin, kMax };
inline constexpr BlendEquation kLastBlendEquation = BlendEquation::kMax;
/// GL's depth functions (glDepthFunc).
enum class DepthFunc : uint8_t { kNever, kLess, kEqual, kLequal, kGreater, kNotequal, kGequal, kAlways };
inline constexpr DepthFunc kLastDepthFunc = DepthFunc::kAlways;
/// How the target framebuffer stores colour: 8-bit unsigned normalised,
/// 8-bit sRGB-encoded (blending in linear), or floating point.
enum class TargetEncoding : uint8_t { kUnorm8 = 0, kSrgb8 = 1, kFloat = 2 };
inline constexpr TargetEncoding kLastTargetEncoding = TargetEncoding::kFloat;

/// What a draw is to the transparency methods (docs/methods.md):
/// - kOpaque: blending off; its fragments are opaque (alpha 1);
/// - kSrcOver: SRC_ALPHA, ONE_MINUS_SRC_ALPHA on colour: the order-dependent
///   transparency the stochastic methods replace;
/// - kPremultipliedOver: ONE, ONE_MINUS_SRC_ALPHA (colour premultiplied);
/// - kAdditive: ONE or SRC_ALPHA, ONE (order-independent);
/// - kOther: any other blend (multiply, min/max...): order-independent or not,
///   every method applies it as the `blend` method does.
enum class DrawKind : uint8_t { kOpaque, kSrcOver, kPremultipliedOver, kAdditive, kOther };
inline constexpr int kDrawKinds = 5;
/// A count per draw kind, in DrawKind order.
using DrawKindCounts = std::array<uint64_t, kDrawKinds>;

/// Which path of a transparency method a draw's fragments take
/// (docs/methods.md "Methods on a frame of draw states"):
/// - kMethod: the method's own transparency (src-over and premultiplied
///   src-over draws, and every draw of a trace without draw states);
/// - kOpaque: a z-buffer write with the draw's own depth state (blending off);
/// - kBlend: the draw's blend applied to the stored colour, with its own depth
///   state, as `blend` applies it (additive and other blends).
enum class DrawRoute : uint8_t { kMethod, kOpaque, kBlend };
constexpr DrawRoute route_of(DrawKind k) {
  return k == DrawKind::kOpaque                                         ? DrawRoute::kOpaque
         : k == DrawKind::kSrcOver || k == DrawKind::kPremultipliedOver ? DrawRoute::kMethod
                                                                        : DrawRoute::kBlend;
}
const char* to_string(DrawKind k);
const char* to_string(BlendFactor f);
const char* to_string(BlendEquation e);
const char* to_string(DepthFunc f);
const char* to_string(TargetEncoding e);

struct DrawState {
  uint32_t draw_id = 0;  ///< the fragments' draw_id this state applies to
  bool blend = true;     ///< GL_BLEND on the target's first colour attachment
  BlendEquation eq_rgb = BlendEquation::kAdd, eq_alpha = BlendEquation::kAdd;
  BlendFactor src_rgb = BlendFactor::kSrcAlpha, dst_rgb = BlendFactor::kOneMinusSrcAlpha;
  BlendFactor src_alpha = BlendFactor::kOne, dst_alpha = BlendFactor::kOneMinusSrcAlpha;
  std::array<float, 4> blend_color{0.0f, 0.0f, 0.0f, 0.0f};  ///< glBlendColor (RGBA)
  bool depth_test = true;                                    ///< GL_DEPTH_TEST
  DepthFunc depth_func = DepthFunc::kLess;
  bool depth_write = false;                          ///< glDepthMask
  uint8_t color_mask = 0xF;                          ///< glColorMask: bit 0 red .. bit 3 alpha
  TargetEncoding encoding = TargetEncoding::kFloat;  ///< the target's colour storage
  std::string name;  ///< the GL debug label, else "program N", else ""; UTF-8, at most 255 bytes
};

/// The state every draw of a trace without draw records has (version 1, or a
/// version 2 trace whose table is empty): src-over with the fragment's alpha,
/// depth test LESS without depth writes, float target; the meaning of every
/// trace before draw states existed.
DrawState default_draw_state(uint32_t draw_id);

/// The kind of a draw's state (DrawKind).
DrawKind draw_kind(const DrawState& s);

/// The draw states of a trace, looked up by draw_id. Empty: every draw has
/// default_draw_state(). Otherwise every fragment's draw_id has a state.
class DrawTable {
 public:
  DrawTable() = default;
  /// States in any order; draw ids must be distinct (validate() says).
  explicit DrawTable(std::vector<DrawState> states);
  bool empty() const { return states_.empty(); }
  size_t size() const { return states_.size(); }
  const std::vector<DrawState>& states() const { return states_; }  ///< sorted by draw_id
  /// The state of draw_id, or nullptr when the table is non-empty and lacks it.
  const DrawState* find(uint32_t draw_id) const;
  /// The state of draw_id: find()'s, or for an empty table the one default
  /// state (default_draw_state(0): its draw_id is 0 whatever the id asked;
  /// thread-safe). An id the non-empty table lacks is an InternalError (the
  /// trace reader refuses a fragment whose draw has no state).
  const DrawState& at(uint32_t draw_id) const;
  /// "" when the table is valid (distinct ids, enumerations in range, mask in
  /// 0..15, a UTF-8 name of at most 255 bytes, finite blend colour), else the
  /// reason, naming the state ("draw state i (draw d): ...").
  std::string validate() const;
  bool operator==(const DrawTable& o) const;

 private:
  std::vector<DrawState> states_;
};

}  // namespace ropsim
