// Fixed-function emulation: the OpenGL fixed-function state of a draw made
// with program 0, read back from the current context, and a GLSL 4.50
// compatibility program that renders the same fragments with the same colours,
// so a capture can instrument fixed-function draws like any other program.
//
// The program reads the compatibility built-ins (gl_Vertex, gl_Color,
// gl_SecondaryColor, gl_Normal, gl_MultiTexCoord0/1, gl_FogCoord, the matrices,
// gl_LightSource[], gl_FrontMaterial, gl_LightModel, gl_TextureEnvColor[],
// gl_Fog), so immediate mode, client arrays, the matrix stacks and every
// glLight / glMaterial / glFog / glTexEnv value keep working without uniforms
// set by the caller. Only the structure of the state (which features are on,
// which modes) shapes the source; values that GLSL cannot read from a built-in
// (the alpha test's reference) are written into it. The texture samplers carry
// `layout(binding = N)`: unit 0 and unit 1, nothing to set after linking.
//
// The generator makes no GL calls. docs/capture.md "Fixed-function draws"
// lists the subset and how it is checked against Mesa's own pipeline.
#pragma once
#include <array>
#include <cstdint>
#include <string>

namespace ropsim::glcapture {

/// The GL entry points read_fixed_function_state() calls (the types are the GL
/// ones spelt without <GL/gl.h>: GLenum = unsigned, GLint = int, GLfloat =
/// float, GLboolean = unsigned char), so the capture library can pass its real
/// entry points and its wrappers never see these calls. All are required.
struct GlGetters {
  void (*GetIntegerv)(unsigned pname, int* data) = nullptr;
  void (*GetFloatv)(unsigned pname, float* data) = nullptr;
  unsigned char (*IsEnabled)(unsigned cap) = nullptr;
  void (*GetTexEnviv)(unsigned target, unsigned pname, int* params) = nullptr;
  void (*GetTexEnvfv)(unsigned target, unsigned pname, float* params) = nullptr;
  void (*GetLightfv)(unsigned light, unsigned pname, float* params) = nullptr;
  void (*GetTexParameteriv)(unsigned target, unsigned pname, int* params) = nullptr;
  void (*GetTexLevelParameteriv)(unsigned target, int level, unsigned pname, int* params) = nullptr;
  /// Selects the texture unit whose state the glGetTexEnv / glIsEnabled calls
  /// read; read_fixed_function_state() restores GL_ACTIVE_TEXTURE before it returns.
  void (*ActiveTexture)(unsigned texture) = nullptr;
};

/// The texture target a unit uses: the enabled one of highest precedence
/// (cube map > 3D > rectangle > 2D > 1D), as fixed-function texturing picks it.
enum class TexTarget : uint8_t { kNone, k1D, k2D, k3D, kCubeMap, kRectangle };

/// The base internal format of the unit's texture image, which selects the
/// texture environment's equation (GL 4.6 compatibility profile, "Texture
/// Environments and Texture Functions"). RED and RG images count as kRgb
/// (their missing components read 0, alpha 1).
enum class TexBaseFormat : uint8_t { kAlpha, kLuminance, kLuminanceAlpha, kIntensity, kRgb, kRgba, kDepth };

/// GL_TEXTURE_ENV_MODE. kOther: a mode this module does not name.
enum class TexEnvMode : uint8_t { kModulate, kReplace, kDecal, kAdd, kBlend, kCombine, kOther };

/// GL_COMBINE_RGB / GL_COMBINE_ALPHA: the texture function of a GL_COMBINE
/// environment (GL 2.1 compatibility, table 3.21). DOT3_RGB and DOT3_RGBA are
/// valid for the RGB function only. kOther: a function this module does not
/// name (EXT_texture_env_dot3's DOT3_RGB_EXT / DOT3_RGBA_EXT, the ATI
/// MODULATE_ADD / MODULATE_SIGNED_ADD / MODULATE_SUBTRACT functions).
enum class CombineFunc : uint8_t {
  kReplace,
  kModulate,
  kAdd,
  kAddSigned,
  kInterpolate,
  kSubtract,
  kDot3Rgb,
  kDot3Rgba,
  kOther
};

/// GL_SRCn_RGB / GL_SRCn_ALPHA: where an argument of the combiner comes from.
/// kTextureUnit is GL_TEXTUREi of the crossbar (the unit in
/// CombineArg::unit) for a unit other than the environment's own; GL_TEXTUREi
/// of the own unit reads as kTexture. kOther: a source this module does not
/// name (ATI_texture_env_combine3's GL_ZERO and GL_ONE).
enum class CombineSource : uint8_t { kTexture, kTextureUnit, kConstant, kPrimaryColor, kPrevious, kOther };

/// GL_OPERANDn_RGB / GL_OPERANDn_ALPHA: which components of the source, and
/// whether they are complemented (the ALPHA arguments take only kSrcAlpha and
/// kOneMinusSrcAlpha). kOther: any other value.
enum class CombineOperand : uint8_t { kSrcColor, kOneMinusSrcColor, kSrcAlpha, kOneMinusSrcAlpha, kOther };

/// One argument of the combiner function (Arg0, Arg1 or Arg2).
struct CombineArg {
  CombineSource source = CombineSource::kTexture;
  uint8_t unit = 0;  ///< the texture unit of a kTextureUnit source (0 otherwise)
  CombineOperand operand = CombineOperand::kSrcColor;
  bool operator==(const CombineArg& o) const { return source == o.source && unit == o.unit && operand == o.operand; }
  bool operator!=(const CombineArg& o) const { return !(*this == o); }
};

/// The GL_COMBINE texture environment of a unit (ARB_texture_env_combine,
/// ARB_texture_env_dot3, ARB_texture_env_crossbar as in GL 1.4). The defaults
/// are GL's initial values. Canonical: the arguments a function does not read
/// (REPLACE reads Arg0, INTERPOLATE Arg0..2, the others Arg0 and Arg1) and,
/// under DOT3_RGBA, the whole ALPHA function and its arguments keep their
/// initial values.
struct CombineState {
  CombineFunc rgb = CombineFunc::kModulate;    ///< GL_COMBINE_RGB
  CombineFunc alpha = CombineFunc::kModulate;  ///< GL_COMBINE_ALPHA
  std::array<CombineArg, 3> rgb_args{{{CombineSource::kTexture, 0, CombineOperand::kSrcColor},
                                      {CombineSource::kPrevious, 0, CombineOperand::kSrcColor},
                                      {CombineSource::kConstant, 0, CombineOperand::kSrcAlpha}}};
  std::array<CombineArg, 3> alpha_args{{{CombineSource::kTexture, 0, CombineOperand::kSrcAlpha},
                                        {CombineSource::kPrevious, 0, CombineOperand::kSrcAlpha},
                                        {CombineSource::kConstant, 0, CombineOperand::kSrcAlpha}}};
  /// GL_RGB_SCALE and GL_ALPHA_SCALE: 1, 2 or 4 (0: another value, unsupported)
  uint8_t rgb_scale = 1, alpha_scale = 1;
  bool operator==(const CombineState& o) const;
  bool operator!=(const CombineState& o) const { return !(*this == o); }
};

/// One fixed-function texture unit (0 or 1). A unit that is not `active()`
/// contributes nothing, and its other fields are left at their defaults.
struct TextureUnitState {
  TexTarget target = TexTarget::kNone;        ///< the enabled target (kNone: texturing off)
  bool complete = false;                      ///< the target's texture has its images (else FF skips the unit)
  TexBaseFormat base = TexBaseFormat::kRgba;  ///< base format of the texture's base level
  TexEnvMode env = TexEnvMode::kModulate;     ///< GL_TEXTURE_ENV_MODE
  CombineState combine{};                     ///< the GL_COMBINE state (defaults unless env is kCombine)
  bool texgen = false;                        ///< any of GL_TEXTURE_GEN_S/T/R/Q enabled
  bool lod_bias = false;                      ///< GL_TEXTURE_LOD_BIAS of GL_TEXTURE_FILTER_CONTROL is not 0
  bool active() const { return target != TexTarget::kNone && complete; }
  bool operator==(const TextureUnitState& o) const;
  bool operator!=(const TextureUnitState& o) const { return !(*this == o); }
};

/// One light (GL_LIGHTi). A disabled light's other fields are left false.
struct LightState {
  bool enabled = false;      ///< glIsEnabled(GL_LIGHTi)
  bool directional = false;  ///< GL_POSITION w == 0 (a light at infinity: no distance attenuation)
  bool attenuated = false;   ///< a positional light whose (constant, linear, quadratic) is not (1, 0, 0)
  bool spot = false;         ///< GL_SPOT_CUTOFF is not 180 (a spotlight)
  bool operator==(const LightState& o) const;
  bool operator!=(const LightState& o) const { return !(*this == o); }
};

/// GL_COLOR_MATERIAL_PARAMETER: which front material colour follows gl_Color.
enum class ColorMaterialParameter : uint8_t { kAmbient, kDiffuse, kSpecular, kEmission, kAmbientAndDiffuse };

enum class FogMode : uint8_t { kLinear, kExp, kExp2 };
/// GL_FOG_COORD_SRC: the fog coordinate is |z| in eye coordinates, or glFogCoord's value.
enum class FogSource : uint8_t { kFragmentDepth, kFogCoord };

/// GL_ALPHA_TEST_FUNC (the comparison of the fragment's alpha with the reference).
enum class CompareFunc : uint8_t { kNever, kLess, kEqual, kLequal, kGreater, kNotequal, kGequal, kAlways };

/// The fixed-function state that shapes a draw's vertex and fragment processing.
/// read_fixed_function_state() canonicalises it: a field that has no effect
/// under the others (a light's details while lighting is off, the fog mode
/// while fog is off ...) keeps its default, so two states that render alike
/// compare equal and give the same program.
struct FixedFunctionState {
  static constexpr int kLights = 8;  ///< GL_MAX_LIGHTS of every implementation this reads
  static constexpr int kUnits = 2;   ///< texture units the program emulates

  // Vertex colour and shading.
  bool flat_shading = false;  ///< glShadeModel(GL_FLAT): colours from the provoking vertex
  bool color_sum = false;     ///< GL_COLOR_SUM with lighting off: gl_SecondaryColor added after texturing

  // Lighting (GL_LIGHTING). Light and material values come from the built-ins.
  bool lighting = false;                     ///< GL_LIGHTING: the primary colour is lit, not gl_Color
  std::array<LightState, kLights> lights{};  ///< GL_LIGHT0..7
  bool local_viewer = false;                 ///< GL_LIGHT_MODEL_LOCAL_VIEWER: specular towards the eye, not +z
  bool two_sided = false;                    ///< GL_LIGHT_MODEL_TWO_SIDE (unsupported)
  bool separate_specular = false;            ///< GL_SEPARATE_SPECULAR_COLOR: specular added after texturing
  bool color_material = false;               ///< GL_COLOR_MATERIAL on a face that includes the front
  /// GL_COLOR_MATERIAL_PARAMETER (meaningful with color_material)
  ColorMaterialParameter color_material_parameter = ColorMaterialParameter::kAmbientAndDiffuse;
  bool normalize = false;       ///< GL_NORMALIZE: eye normals normalised
  bool rescale_normal = false;  ///< GL_RESCALE_NORMAL (without GL_NORMALIZE): eye normals scaled by gl_NormalScale

  // Texturing.
  std::array<TextureUnitState, kUnits> units{};  ///< units 0 and 1
  int other_unit = -1;  ///< the first unit >= 2 with a texture target enabled, -1 if none (unsupported)

  // Per-fragment operations the program carries out.
  bool alpha_test = false;                        ///< GL_ALPHA_TEST: a failing fragment is discarded
  CompareFunc alpha_func = CompareFunc::kAlways;  ///< GL_ALPHA_TEST_FUNC
  float alpha_ref = 0;                            ///< GL_ALPHA_TEST_REF, clamped to [0, 1] by GL
  /// The precision of the comparison: 0 compares the float alpha with the
  /// float reference; N (1..8) compares both rounded to N-bit unsigned
  /// normalised values (ties to even), as llvmpipe does on a colour buffer
  /// of <= 8 bits per component. Read from GL_RED_BITS of the framebuffer
  /// bound for drawing: read the state while the application's is bound.
  int alpha_test_bits = 0;
  bool fog = false;                                  ///< GL_FOG: colour mixed towards gl_Fog.color
  FogMode fog_mode = FogMode::kLinear;               ///< GL_FOG_MODE
  FogSource fog_source = FogSource::kFragmentDepth;  ///< GL_FOG_COORD_SRC

  // Vertex processing that a vertex shader replaces.
  uint8_t clip_planes = 0;  ///< bit i: GL_CLIP_PLANEi enabled (planes 0..7); the program writes gl_ClipVertex

  // State outside the subset (unsupported_reason() names it).
  bool point_sprite = false;          ///< GL_POINT_SPRITE (texture coordinate replacement)
  bool point_attenuation = false;     ///< GL_POINT_DISTANCE_ATTENUATION is not (1, 0, 0)
  bool arb_vertex_program = false;    ///< GL_VERTEX_PROGRAM_ARB enabled
  bool arb_fragment_program = false;  ///< GL_FRAGMENT_PROGRAM_ARB enabled

  bool operator==(const FixedFunctionState& o) const;
  bool operator!=(const FixedFunctionState& o) const { return !(*this == o); }
};

/// Reads the state from the current context through `gl` (a compatibility
/// context with no program in use). Per-unit state is read by selecting each
/// unit with ActiveTexture; GL_ACTIVE_TEXTURE is restored. It raises no GL
/// error in an OpenGL 2.1+ compatibility context with GL_ARB_vertex_program
/// and GL_ARB_fragment_program (Mesa's compatibility profile has both).
FixedFunctionState read_fixed_function_state(const GlGetters& gl);

/// "" when the state is inside the supported subset; else the first
/// unsupported feature in a fixed order, e.g. "texture unit 2 enabled",
/// "glTexGen on texture unit 1", "two-sided lighting (GL_LIGHT_MODEL_TWO_SIDE)".
std::string unsupported_reason(const FixedFunctionState& s);

/// A vertex and fragment shader pair (GLSL 4.50 compatibility).
struct GlslProgram {
  std::string vertex, fragment;
};

/// The program equivalent to `s` (meaningful when unsupported_reason(s) is
/// ""; outside the subset it renders the supported part). The fragment shader
/// writes gl_FragColor once, at the end of main(), and discards a fragment the
/// alpha test rejects. The same state gives byte-identical sources, and only
/// the enabled features appear in them, so a caller can cache the linked
/// program by state (or by source).
GlslProgram fixed_function_program(const FixedFunctionState& s);

}  // namespace ropsim::glcapture
