#include "traces/glcapture/ff_program.h"

// clang-format off
#include <GL/gl.h>
#include <GL/glext.h>
// clang-format on

#include <algorithm>
#include <charconv>
#include <cmath>
#include <system_error>

namespace ropsim::glcapture {

bool CombineState::operator==(const CombineState& o) const {
  return rgb == o.rgb && alpha == o.alpha && rgb_args == o.rgb_args && alpha_args == o.alpha_args &&
         rgb_scale == o.rgb_scale && alpha_scale == o.alpha_scale;
}

bool TextureUnitState::operator==(const TextureUnitState& o) const {
  return target == o.target && complete == o.complete && base == o.base && env == o.env && combine == o.combine &&
         texgen == o.texgen && lod_bias == o.lod_bias;
}

bool LightState::operator==(const LightState& o) const {
  return enabled == o.enabled && directional == o.directional && attenuated == o.attenuated && spot == o.spot;
}

bool FixedFunctionState::operator==(const FixedFunctionState& o) const {
  return flat_shading == o.flat_shading && color_sum == o.color_sum && lighting == o.lighting && lights == o.lights &&
         local_viewer == o.local_viewer && two_sided == o.two_sided && separate_specular == o.separate_specular &&
         color_material == o.color_material && color_material_parameter == o.color_material_parameter &&
         normalize == o.normalize && rescale_normal == o.rescale_normal && units == o.units &&
         other_unit == o.other_unit && alpha_test == o.alpha_test && alpha_func == o.alpha_func &&
         (alpha_ref == o.alpha_ref || (std::isnan(alpha_ref) && std::isnan(o.alpha_ref))) &&
         alpha_test_bits == o.alpha_test_bits && fog == o.fog && fog_mode == o.fog_mode && fog_source == o.fog_source &&
         clip_planes == o.clip_planes && point_sprite == o.point_sprite && point_attenuation == o.point_attenuation &&
         arb_vertex_program == o.arb_vertex_program && arb_fragment_program == o.arb_fragment_program;
}

// ---------------------------------------------------------------------------
// Reading the state

namespace {

class Reader {
 public:
  explicit Reader(const GlGetters& gl) : gl_(gl) {}
  bool on(GLenum cap) const { return gl_.IsEnabled(cap) != GL_FALSE; }
  GLint geti(GLenum pname) const {
    GLint v[4] = {};
    gl_.GetIntegerv(pname, v);
    return v[0];
  }
  GLint tex_param(GLenum target, GLenum pname) const {
    GLint v[4] = {};
    gl_.GetTexParameteriv(target, pname, v);
    return v[0];
  }
  GLint level_param(GLenum target, GLint level, GLenum pname) const {
    GLint v = 0;
    gl_.GetTexLevelParameteriv(target, level, pname, &v);
    return v;
  }
  const GlGetters& gl() const { return gl_; }

 private:
  const GlGetters& gl_;
};

/// The unit's enabled target of highest precedence (the active unit).
TexTarget enabled_target(const Reader& r) {
  if (r.on(GL_TEXTURE_CUBE_MAP)) return TexTarget::kCubeMap;
  if (r.on(GL_TEXTURE_3D)) return TexTarget::k3D;
  if (r.on(GL_TEXTURE_RECTANGLE)) return TexTarget::kRectangle;
  if (r.on(GL_TEXTURE_2D)) return TexTarget::k2D;
  if (r.on(GL_TEXTURE_1D)) return TexTarget::k1D;
  return TexTarget::kNone;
}

GLenum gl_target(TexTarget t) {
  switch (t) {
    case TexTarget::k1D:
      return GL_TEXTURE_1D;
    case TexTarget::k2D:
      return GL_TEXTURE_2D;
    case TexTarget::k3D:
      return GL_TEXTURE_3D;
    case TexTarget::kCubeMap:
      return GL_TEXTURE_CUBE_MAP;
    case TexTarget::kRectangle:
      return GL_TEXTURE_RECTANGLE;
    case TexTarget::kNone:
      break;
  }
  return GL_NONE;
}

/// Whether the texture bound to `t` on the active unit has the images its
/// filter samples: the base level exists and, for a mipmapped minification
/// filter, so does the last level of the chain (up to GL_TEXTURE_MAX_LEVEL).
/// It does not check that the levels' sizes and formats agree.
bool texture_complete(const Reader& r, TexTarget t) {
  const GLenum target = gl_target(t);
  const GLenum image = t == TexTarget::kCubeMap ? GLenum(GL_TEXTURE_CUBE_MAP_POSITIVE_X) : target;
  const GLint base = r.tex_param(target, GL_TEXTURE_BASE_LEVEL);
  const GLint w = r.level_param(image, base, GL_TEXTURE_WIDTH);
  const GLint h = r.level_param(image, base, GL_TEXTURE_HEIGHT);
  const GLint d = r.level_param(image, base, GL_TEXTURE_DEPTH);
  if (w <= 0 || h <= 0 || d <= 0) return false;
  const GLint min_filter = r.tex_param(target, GL_TEXTURE_MIN_FILTER);
  if (t == TexTarget::kRectangle || min_filter == GL_NEAREST || min_filter == GL_LINEAR) return true;
  int levels = 1;
  for (GLint size = std::max({w, h, t == TexTarget::k3D ? d : 1}); size > 1; size /= 2) ++levels;
  const GLint last = std::min<GLint>(base + levels - 1, r.tex_param(target, GL_TEXTURE_MAX_LEVEL));
  return r.level_param(image, last, GL_TEXTURE_WIDTH) > 0;
}

/// The base format of the active unit's texture, from which component sizes
/// GL reports for its base level (GL reports only the base format's components).
TexBaseFormat base_format(const Reader& r, TexTarget t) {
  const GLenum target = gl_target(t);
  const GLenum image = t == TexTarget::kCubeMap ? GLenum(GL_TEXTURE_CUBE_MAP_POSITIVE_X) : target;
  const GLint base = r.tex_param(target, GL_TEXTURE_BASE_LEVEL);
  auto size = [&](GLenum pname) { return r.level_param(image, base, pname); };
  if (size(GL_TEXTURE_DEPTH_SIZE) > 0) return TexBaseFormat::kDepth;
  if (size(GL_TEXTURE_INTENSITY_SIZE) > 0) return TexBaseFormat::kIntensity;
  const bool alpha = size(GL_TEXTURE_ALPHA_SIZE) > 0;
  if (size(GL_TEXTURE_LUMINANCE_SIZE) > 0) return alpha ? TexBaseFormat::kLuminanceAlpha : TexBaseFormat::kLuminance;
  if (size(GL_TEXTURE_RED_SIZE) > 0) return alpha ? TexBaseFormat::kRgba : TexBaseFormat::kRgb;
  return alpha ? TexBaseFormat::kAlpha : TexBaseFormat::kRgba;
}

TexEnvMode env_mode(GLint mode) {
  switch (mode) {
    case GL_MODULATE:
      return TexEnvMode::kModulate;
    case GL_REPLACE:
      return TexEnvMode::kReplace;
    case GL_DECAL:
      return TexEnvMode::kDecal;
    case GL_ADD:
      return TexEnvMode::kAdd;
    case GL_BLEND:
      return TexEnvMode::kBlend;
    case GL_COMBINE:
      return TexEnvMode::kCombine;
    default:
      return TexEnvMode::kOther;
  }
}

CombineFunc combine_func(GLint f) {
  switch (f) {
    case GL_REPLACE:
      return CombineFunc::kReplace;
    case GL_MODULATE:
      return CombineFunc::kModulate;
    case GL_ADD:
      return CombineFunc::kAdd;
    case GL_ADD_SIGNED:
      return CombineFunc::kAddSigned;
    case GL_INTERPOLATE:
      return CombineFunc::kInterpolate;
    case GL_SUBTRACT:
      return CombineFunc::kSubtract;
    case GL_DOT3_RGB:
      return CombineFunc::kDot3Rgb;
    case GL_DOT3_RGBA:
      return CombineFunc::kDot3Rgba;
    default:
      return CombineFunc::kOther;
  }
}

CombineOperand combine_operand(GLint o) {
  switch (o) {
    case GL_SRC_COLOR:
      return CombineOperand::kSrcColor;
    case GL_ONE_MINUS_SRC_COLOR:
      return CombineOperand::kOneMinusSrcColor;
    case GL_SRC_ALPHA:
      return CombineOperand::kSrcAlpha;
    case GL_ONE_MINUS_SRC_ALPHA:
      return CombineOperand::kOneMinusSrcAlpha;
    default:
      return CombineOperand::kOther;
  }
}

/// The argument of source `src` and operand `operand` on unit `unit`
/// (GL_TEXTUREi of the unit itself is GL_TEXTURE).
CombineArg combine_arg(GLint src, GLint operand, int unit) {
  CombineArg a;
  a.operand = combine_operand(operand);
  if (src == GL_TEXTURE) {
    a.source = CombineSource::kTexture;
  } else if (src >= GL_TEXTURE0 && src <= GL_TEXTURE31) {
    const int n = src - GL_TEXTURE0;
    a.source = n == unit ? CombineSource::kTexture : CombineSource::kTextureUnit;
    a.unit = n == unit ? 0 : uint8_t(n);
  } else if (src == GL_CONSTANT) {
    a.source = CombineSource::kConstant;
  } else if (src == GL_PRIMARY_COLOR) {
    a.source = CombineSource::kPrimaryColor;
  } else if (src == GL_PREVIOUS) {
    a.source = CombineSource::kPrevious;
  } else {
    a.source = CombineSource::kOther;
  }
  return a;
}

/// How many arguments (Arg0 ...) a combiner function reads.
int combine_args(CombineFunc f) {
  switch (f) {
    case CombineFunc::kReplace:
      return 1;
    case CombineFunc::kInterpolate:
      return 3;
    case CombineFunc::kOther:
      return 0;
    default:
      return 2;
  }
}

uint8_t combine_scale(float v) { return v == 1 ? 1 : v == 2 ? 2 : v == 4 ? 4 : 0; }

/// The GL_COMBINE state of the active unit `unit`, canonical (see CombineState).
CombineState read_combine(const GlGetters& gl, int unit) {
  auto env = [&](GLenum pname) {
    GLint v = 0;
    gl.GetTexEnviv(GL_TEXTURE_ENV, pname, &v);
    return v;
  };
  const GLenum src_rgb[] = {GL_SRC0_RGB, GL_SRC1_RGB, GL_SRC2_RGB};
  const GLenum src_alpha[] = {GL_SRC0_ALPHA, GL_SRC1_ALPHA, GL_SRC2_ALPHA};
  const GLenum op_rgb[] = {GL_OPERAND0_RGB, GL_OPERAND1_RGB, GL_OPERAND2_RGB};
  const GLenum op_alpha[] = {GL_OPERAND0_ALPHA, GL_OPERAND1_ALPHA, GL_OPERAND2_ALPHA};
  CombineState c;
  c.rgb = combine_func(env(GL_COMBINE_RGB));
  for (int i = 0; i < combine_args(c.rgb); ++i)
    c.rgb_args[size_t(i)] = combine_arg(env(src_rgb[i]), env(op_rgb[i]), unit);
  if (c.rgb != CombineFunc::kDot3Rgba) {  // DOT3_RGBA ignores COMBINE_ALPHA
    c.alpha = combine_func(env(GL_COMBINE_ALPHA));
    for (int i = 0; i < combine_args(c.alpha); ++i)
      c.alpha_args[size_t(i)] = combine_arg(env(src_alpha[i]), env(op_alpha[i]), unit);
  }
  float scale = 1;
  gl.GetTexEnvfv(GL_TEXTURE_ENV, GL_RGB_SCALE, &scale);
  c.rgb_scale = combine_scale(scale);
  scale = 1;
  gl.GetTexEnvfv(GL_TEXTURE_ENV, GL_ALPHA_SCALE, &scale);
  c.alpha_scale = combine_scale(scale);
  return c;
}

CompareFunc compare_func(GLint f) {
  switch (f) {
    case GL_NEVER:
      return CompareFunc::kNever;
    case GL_LESS:
      return CompareFunc::kLess;
    case GL_EQUAL:
      return CompareFunc::kEqual;
    case GL_LEQUAL:
      return CompareFunc::kLequal;
    case GL_GREATER:
      return CompareFunc::kGreater;
    case GL_NOTEQUAL:
      return CompareFunc::kNotequal;
    case GL_GEQUAL:
      return CompareFunc::kGequal;
    default:
      return CompareFunc::kAlways;
  }
}

void read_lighting(const Reader& r, FixedFunctionState& s) {
  for (int i = 0; i < FixedFunctionState::kLights; ++i) {
    const GLenum light = GL_LIGHT0 + GLenum(i);
    LightState& l = s.lights[size_t(i)];
    l.enabled = r.on(light);
    if (!l.enabled) continue;
    float position[4] = {}, cutoff = 180, k0 = 1, k1 = 0, k2 = 0;
    r.gl().GetLightfv(light, GL_POSITION, position);
    r.gl().GetLightfv(light, GL_SPOT_CUTOFF, &cutoff);
    l.directional = position[3] == 0;
    l.spot = cutoff != 180;
    if (!l.directional) {
      r.gl().GetLightfv(light, GL_CONSTANT_ATTENUATION, &k0);
      r.gl().GetLightfv(light, GL_LINEAR_ATTENUATION, &k1);
      r.gl().GetLightfv(light, GL_QUADRATIC_ATTENUATION, &k2);
      l.attenuated = k0 != 1 || k1 != 0 || k2 != 0;
    }
  }
  s.local_viewer = r.geti(GL_LIGHT_MODEL_LOCAL_VIEWER) != 0;
  s.two_sided = r.geti(GL_LIGHT_MODEL_TWO_SIDE) != 0;
  s.separate_specular = r.geti(GL_LIGHT_MODEL_COLOR_CONTROL) == GL_SEPARATE_SPECULAR_COLOR;
  if (r.on(GL_COLOR_MATERIAL) && r.geti(GL_COLOR_MATERIAL_FACE) != GL_BACK) {
    s.color_material = true;
    switch (r.geti(GL_COLOR_MATERIAL_PARAMETER)) {
      case GL_AMBIENT:
        s.color_material_parameter = ColorMaterialParameter::kAmbient;
        break;
      case GL_DIFFUSE:
        s.color_material_parameter = ColorMaterialParameter::kDiffuse;
        break;
      case GL_SPECULAR:
        s.color_material_parameter = ColorMaterialParameter::kSpecular;
        break;
      case GL_EMISSION:
        s.color_material_parameter = ColorMaterialParameter::kEmission;
        break;
      default:
        s.color_material_parameter = ColorMaterialParameter::kAmbientAndDiffuse;
        break;
    }
  }
  s.normalize = r.on(GL_NORMALIZE);
  s.rescale_normal = !s.normalize && r.on(GL_RESCALE_NORMAL);
}

}  // namespace

FixedFunctionState read_fixed_function_state(const GlGetters& gl) {
  const Reader r(gl);
  FixedFunctionState s;
  s.flat_shading = r.geti(GL_SHADE_MODEL) == GL_FLAT;
  s.lighting = r.on(GL_LIGHTING);
  if (s.lighting)
    read_lighting(r, s);
  else
    s.color_sum = r.on(GL_COLOR_SUM);

  const bool point_sprite = r.on(GL_POINT_SPRITE);
  const GLint saved_unit = r.geti(GL_ACTIVE_TEXTURE);
  const GLint units = std::max(r.geti(GL_MAX_TEXTURE_UNITS), FixedFunctionState::kUnits);
  for (GLint u = 0; u < units; ++u) {
    gl.ActiveTexture(GL_TEXTURE0 + GLenum(u));
    const TexTarget target = enabled_target(r);
    if (target == TexTarget::kNone || !texture_complete(r, target)) continue;
    if (u >= FixedFunctionState::kUnits) {
      s.other_unit = u;
      break;
    }
    TextureUnitState& t = s.units[size_t(u)];
    t.target = target;
    t.complete = true;
    t.base = base_format(r, target);
    GLint mode = GL_MODULATE;
    gl.GetTexEnviv(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, &mode);
    t.env = env_mode(mode);
    if (t.env == TexEnvMode::kCombine) t.combine = read_combine(gl, int(u));
    t.texgen = r.on(GL_TEXTURE_GEN_S) || r.on(GL_TEXTURE_GEN_T) || r.on(GL_TEXTURE_GEN_R) || r.on(GL_TEXTURE_GEN_Q);
    float bias = 0;
    gl.GetTexEnvfv(GL_TEXTURE_FILTER_CONTROL, GL_TEXTURE_LOD_BIAS, &bias);
    t.lod_bias = bias != 0;
    if (point_sprite) {
      GLint replace = GL_FALSE;
      gl.GetTexEnviv(GL_POINT_SPRITE, GL_COORD_REPLACE, &replace);
      s.point_sprite = s.point_sprite || replace != GL_FALSE;
    }
  }
  gl.ActiveTexture(GLenum(saved_unit));

  if (r.on(GL_ALPHA_TEST)) {
    const CompareFunc f = compare_func(r.geti(GL_ALPHA_TEST_FUNC));
    if (f != CompareFunc::kAlways) {
      s.alpha_test = true;
      s.alpha_func = f;
      gl.GetFloatv(GL_ALPHA_TEST_REF, &s.alpha_ref);
      const GLint bits = r.geti(GL_RED_BITS);
      s.alpha_test_bits = bits >= 1 && bits <= 8 ? int(bits) : 0;
    }
  }
  if (r.on(GL_FOG)) {
    s.fog = true;
    const GLint mode = r.geti(GL_FOG_MODE);
    s.fog_mode = mode == GL_EXP ? FogMode::kExp : mode == GL_EXP2 ? FogMode::kExp2 : FogMode::kLinear;
    s.fog_source = r.geti(GL_FOG_COORD_SRC) == GL_FOG_COORD ? FogSource::kFogCoord : FogSource::kFragmentDepth;
  }
  const GLint planes = std::min(r.geti(GL_MAX_CLIP_PLANES), 8);
  for (GLint i = 0; i < planes; ++i)
    if (r.on(GL_CLIP_PLANE0 + GLenum(i))) s.clip_planes = uint8_t(s.clip_planes | (1u << i));
  float attenuation[3] = {1, 0, 0};
  gl.GetFloatv(GL_POINT_DISTANCE_ATTENUATION, attenuation);
  s.point_attenuation = attenuation[0] != 1 || attenuation[1] != 0 || attenuation[2] != 0;
  s.arb_vertex_program = r.on(GL_VERTEX_PROGRAM_ARB);
  s.arb_fragment_program = r.on(GL_FRAGMENT_PROGRAM_ARB);
  return s;
}

// ---------------------------------------------------------------------------
// The supported subset

namespace {

const char* target_name(TexTarget t) {
  switch (t) {
    case TexTarget::k1D:
      return "GL_TEXTURE_1D";
    case TexTarget::k2D:
      return "GL_TEXTURE_2D";
    case TexTarget::k3D:
      return "GL_TEXTURE_3D";
    case TexTarget::kCubeMap:
      return "GL_TEXTURE_CUBE_MAP";
    case TexTarget::kRectangle:
      return "GL_TEXTURE_RECTANGLE";
    case TexTarget::kNone:
      break;
  }
  return "no texture target";
}

const char* base_name(TexBaseFormat b) {
  switch (b) {
    case TexBaseFormat::kAlpha:
      return "GL_ALPHA";
    case TexBaseFormat::kLuminance:
      return "GL_LUMINANCE";
    case TexBaseFormat::kLuminanceAlpha:
      return "GL_LUMINANCE_ALPHA";
    case TexBaseFormat::kIntensity:
      return "GL_INTENSITY";
    case TexBaseFormat::kRgb:
      return "GL_RGB";
    case TexBaseFormat::kRgba:
      return "GL_RGBA";
    case TexBaseFormat::kDepth:
      return "GL_DEPTH_COMPONENT";
  }
  return "?";
}

const char* combine_func_name(CombineFunc f) {
  switch (f) {
    case CombineFunc::kReplace:
      return "REPLACE";
    case CombineFunc::kModulate:
      return "MODULATE";
    case CombineFunc::kAdd:
      return "ADD";
    case CombineFunc::kAddSigned:
      return "ADD_SIGNED";
    case CombineFunc::kInterpolate:
      return "INTERPOLATE";
    case CombineFunc::kSubtract:
      return "SUBTRACT";
    case CombineFunc::kDot3Rgb:
      return "DOT3_RGB";
    case CombineFunc::kDot3Rgba:
      return "DOT3_RGBA";
    case CombineFunc::kOther:
      break;
  }
  return "?";
}

/// Why unit u's GL_COMBINE state is outside the subset ("" inside).
std::string combine_unsupported(const FixedFunctionState& s, int u) {
  const CombineState& c = s.units[size_t(u)].combine;
  if (c.rgb == CombineFunc::kOther)
    return "a GL_COMBINE_RGB function other than REPLACE, MODULATE, ADD, ADD_SIGNED, INTERPOLATE, SUBTRACT, DOT3_RGB, "
           "DOT3_RGBA";
  const bool alpha = c.rgb != CombineFunc::kDot3Rgba;
  if (alpha &&
      (c.alpha == CombineFunc::kOther || c.alpha == CombineFunc::kDot3Rgb || c.alpha == CombineFunc::kDot3Rgba))
    return "a GL_COMBINE_ALPHA function other than REPLACE, MODULATE, ADD, ADD_SIGNED, INTERPOLATE, SUBTRACT";
  for (int pass = 0; pass < (alpha ? 2 : 1); ++pass) {
    const char* which = pass ? "ALPHA" : "RGB";
    const CombineFunc f = pass ? c.alpha : c.rgb;
    const auto& args = pass ? c.alpha_args : c.rgb_args;
    for (int i = 0; i < combine_args(f); ++i) {
      const CombineArg& a = args[size_t(i)];
      const std::string n = std::to_string(i);
      if (a.source == CombineSource::kOther)
        return std::string("a GL_SRC") + n + "_" + which +
               " other than TEXTURE, TEXTUREi, CONSTANT, PRIMARY_COLOR, PREVIOUS";
      if (a.operand == CombineOperand::kOther ||
          (pass && a.operand != CombineOperand::kSrcAlpha && a.operand != CombineOperand::kOneMinusSrcAlpha))
        return std::string("a GL_OPERAND") + n + "_" + which + " GL does not define";
      if (a.source == CombineSource::kTextureUnit &&
          (a.unit >= FixedFunctionState::kUnits || !s.units[a.unit].active()))
        return std::string("GL_SRC") + n + "_" + which + " = GL_TEXTURE" + std::to_string(a.unit) +
               ", a unit without an enabled complete texture (undefined in GL)";
    }
  }
  if (c.rgb_scale == 0) return "a GL_RGB_SCALE other than 1, 2, 4";
  if (c.alpha_scale == 0) return "a GL_ALPHA_SCALE other than 1, 2, 4";
  return "";
}

}  // namespace

std::string unsupported_reason(const FixedFunctionState& s) {
  if (s.arb_vertex_program) return "an ARB vertex program (GL_VERTEX_PROGRAM_ARB enabled)";
  if (s.arb_fragment_program) return "an ARB fragment program (GL_FRAGMENT_PROGRAM_ARB enabled)";
  if (s.lighting && s.two_sided) return "two-sided lighting (GL_LIGHT_MODEL_TWO_SIDE)";
  if (s.other_unit >= 0) return "texture unit " + std::to_string(s.other_unit) + " enabled";
  for (int u = 0; u < FixedFunctionState::kUnits; ++u) {
    const TextureUnitState& t = s.units[size_t(u)];
    if (!t.active()) continue;
    const std::string on = " on texture unit " + std::to_string(u);
    if (t.target != TexTarget::k2D) return std::string(target_name(t.target)) + on;
    if (t.env == TexEnvMode::kOther)
      return "a texture environment mode other than MODULATE, REPLACE, DECAL, ADD, BLEND, COMBINE" + on;
    if (t.texgen) return "glTexGen" + on;
    if (t.lod_bias) return "a texture environment LOD bias (GL_TEXTURE_LOD_BIAS)" + on;
    if (t.base == TexBaseFormat::kDepth) return "a depth texture" + on;
    if (t.env == TexEnvMode::kDecal && t.base != TexBaseFormat::kRgb && t.base != TexBaseFormat::kRgba)
      return std::string("GL_DECAL with a ") + base_name(t.base) + " texture (undefined in GL)" + on;
    if (t.env == TexEnvMode::kCombine) {
      const std::string why = combine_unsupported(s, u);
      if (!why.empty()) return "GL_COMBINE: " + why + on;
    }
  }
  if (s.point_sprite) return "point sprite texture coordinates (GL_COORD_REPLACE)";
  if (s.point_attenuation) return "point size distance attenuation (GL_POINT_DISTANCE_ATTENUATION)";
  return "";
}

// ---------------------------------------------------------------------------
// The program

namespace {

/// A float as a GLSL literal that reads back as the same binary32 value
/// (shortest round-trip digits, independent of the C locale).
std::string glsl_float(float v) {
  if (std::isnan(v)) return "(0.0 / 0.0)";
  if (std::isinf(v)) return v > 0 ? "(1.0 / 0.0)" : "(-1.0 / 0.0)";
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  std::string out(buf, res.ec == std::errc() ? res.ptr : buf);
  if (out.find_first_of(".e") == std::string::npos) out += ".0";
  return out;
}

/// x rounded to the nearest integer, ties to even (the conversion of the
/// reference to fixed point that Mesa makes: 0.3 x 255 = 76.5 -> 76).
float round_half_even(float x) {
  const float lo = std::floor(x), frac = x - lo;
  if (frac > 0.5f) return lo + 1;
  if (frac < 0.5f) return lo;
  return std::fmod(lo, 2.0f) == 0 ? lo : lo + 1;
}

const char* compare_op(CompareFunc f) {
  switch (f) {
    case CompareFunc::kLess:
      return "<";
    case CompareFunc::kEqual:
      return "==";
    case CompareFunc::kLequal:
      return "<=";
    case CompareFunc::kGreater:
      return ">";
    case CompareFunc::kNotequal:
      return "!=";
    case CompareFunc::kGequal:
      return ">=";
    case CompareFunc::kNever:
    case CompareFunc::kAlways:
      break;
  }
  return "";
}

bool tracks(const FixedFunctionState& s, ColorMaterialParameter p) {
  if (!s.color_material) return false;
  const ColorMaterialParameter m = s.color_material_parameter;
  if (m == p) return true;
  return m == ColorMaterialParameter::kAmbientAndDiffuse &&
         (p == ColorMaterialParameter::kAmbient || p == ColorMaterialParameter::kDiffuse);
}

/// Whether the program has a secondary colour (added after texturing).
bool has_secondary(const FixedFunctionState& s) { return s.lighting ? s.separate_specular : s.color_sum; }

bool any_light(const FixedFunctionState& s) {
  return std::any_of(s.lights.begin(), s.lights.end(), [](const LightState& l) { return l.enabled; });
}

/// The lit front colour (GL 4.6 compatibility profile, "Lighting"): the
/// scene colour plus, per enabled light, attenuation x spot x (ambient +
/// diffuse + specular), per vertex; alpha is the diffuse material's.
void emit_lighting(const FixedFunctionState& s, std::string& v) {
  using P = ColorMaterialParameter;
  auto material = [&](P p, const char* member) {
    return tracks(s, p) ? std::string("gl_Color") : std::string("gl_FrontMaterial.") + member;
  };
  auto product = [&](int i, P p, const char* member) {
    const std::string light = "gl_LightSource[" + std::to_string(i) + "]." + member;
    return tracks(s, p) ? light + ".rgb * gl_Color.rgb"
                        : "gl_FrontLightProduct[" + std::to_string(i) + "]." + member + ".rgb";
  };

  v += "  vec3 n = gl_NormalMatrix * gl_Normal;\n";
  if (s.normalize) v += "  n = normalize(n);\n";
  if (s.rescale_normal) v += "  n *= gl_NormalScale;\n";
  if (s.local_viewer && any_light(s)) v += "  vec3 to_eye = -normalize(eye.xyz);\n";
  if (tracks(s, P::kAmbient) || tracks(s, P::kEmission))
    v += "  vec3 lit = " + material(P::kEmission, "emission") + ".rgb + " + material(P::kAmbient, "ambient") +
         ".rgb * gl_LightModel.ambient.rgb;\n";
  else
    v += "  vec3 lit = gl_FrontLightModelProduct.sceneColor.rgb;\n";
  if (any_light(s)) v += "  vec3 specular = vec3(0.0);\n";
  for (int i = 0; i < FixedFunctionState::kLights; ++i) {
    const LightState& l = s.lights[size_t(i)];
    if (!l.enabled) continue;
    const std::string L = "gl_LightSource[" + std::to_string(i) + "]";
    v += "  {  // GL_LIGHT" + std::to_string(i) + "\n";
    if (l.directional) {
      v += "    vec3 vp = normalize(" + L + ".position.xyz);\n";
    } else {
      v += "    vec3 vp = " + L + ".position.xyz - eye.xyz;\n";
      v += "    float inv_d = inversesqrt(dot(vp, vp));\n";
      v += "    vp *= inv_d;\n";
    }
    const bool att = (!l.directional && l.attenuated) || l.spot;
    if (att) v += "    float att = 1.0;\n";
    if (!l.directional && l.attenuated) {
      v += "    float d = 1.0 / inv_d;\n";
      v += "    att = 1.0 / (" + L + ".constantAttenuation + " + L + ".linearAttenuation * d + " + L +
           ".quadraticAttenuation * d * d);\n";
    }
    if (l.spot) {
      v += "    float spot = dot(-vp, normalize(" + L + ".spotDirection));\n";
      v += "    att *= spot > " + L + ".spotCosCutoff ? ff_power(spot, " + L + ".spotExponent) : 0.0;\n";
    }
    if (s.local_viewer)
      v += "    vec3 h = normalize(vp + to_eye);\n";
    else if (l.directional)
      v += "    vec3 h = " + L + ".halfVector.xyz;\n";
    else
      v += "    vec3 h = normalize(vp + vec3(0.0, 0.0, 1.0));\n";
    v += "    float ndotl = dot(n, vp);\n";
    v += "    float diffuse = max(ndotl, 0.0);\n";
    v += "    float shine = ndotl > 0.0 ? ff_power(max(dot(n, h), 0.0), gl_FrontMaterial.shininess) : 0.0;\n";
    const std::string a = att ? "att * " : "";
    v += "    lit += " + a + "(" + product(i, P::kAmbient, "ambient") + " + diffuse * " +
         product(i, P::kDiffuse, "diffuse") + ");\n";
    v += "    specular += " + a + "shine * " + product(i, P::kSpecular, "specular") + ";\n";
    v += "  }\n";
  }
  const std::string alpha = material(P::kDiffuse, "diffuse") + ".a";
  if (!any_light(s)) {
    v += "  ff_color = clamp(vec4(lit, " + alpha + "), 0.0, 1.0);\n";
    if (s.separate_specular) v += "  ff_secondary = vec4(0.0);\n";
  } else if (s.separate_specular) {
    v += "  ff_color = clamp(vec4(lit, " + alpha + "), 0.0, 1.0);\n";
    v += "  ff_secondary = vec4(clamp(specular, 0.0, 1.0), 0.0);\n";
  } else {
    v += "  ff_color = clamp(vec4(lit + specular, " + alpha + "), 0.0, 1.0);\n";
  }
}

/// The texture environment of unit u on `color` (GL 4.6 compatibility
/// profile, "Texture Environments and Texture Functions"), clamped to [0, 1]
/// as every stage's result is.
void emit_texture_env(const TextureUnitState& t, int u, std::string& f) {
  const std::string tex = "t" + std::to_string(u);
  const std::string env = "gl_TextureEnvColor[" + std::to_string(u) + "]";
  const bool has_color = t.base != TexBaseFormat::kAlpha;
  const bool has_alpha = t.base == TexBaseFormat::kAlpha || t.base == TexBaseFormat::kLuminanceAlpha ||
                         t.base == TexBaseFormat::kIntensity || t.base == TexBaseFormat::kRgba;
  const bool intensity = t.base == TexBaseFormat::kIntensity;
  std::string rgb, a;
  switch (t.env) {
    case TexEnvMode::kReplace:
      rgb = tex + ".rgb";
      a = tex + ".a";
      break;
    case TexEnvMode::kDecal:
      rgb = t.base == TexBaseFormat::kRgba ? "mix(color.rgb, " + tex + ".rgb, " + tex + ".a)" : tex + ".rgb";
      break;
    case TexEnvMode::kBlend:
      rgb = "mix(color.rgb, " + env + ".rgb, " + tex + ".rgb)";
      a = intensity ? "mix(color.a, " + env + ".a, " + tex + ".a)" : "color.a * " + tex + ".a";
      break;
    case TexEnvMode::kAdd:
      rgb = "color.rgb + " + tex + ".rgb";
      a = intensity ? "color.a + " + tex + ".a" : "color.a * " + tex + ".a";
      break;
    case TexEnvMode::kModulate:
    case TexEnvMode::kCombine:
    case TexEnvMode::kOther:
      rgb = "color.rgb * " + tex + ".rgb";
      a = "color.a * " + tex + ".a";
      break;
  }
  const char* modes[] = {"MODULATE", "REPLACE", "DECAL", "ADD", "BLEND", "MODULATE", "MODULATE"};
  f += std::string("  // unit ") + std::to_string(u) + ": GL_" + modes[int(t.env)] + ", " + base_name(t.base) +
       " texture\n";
  if (has_color) f += "  color.rgb = clamp(" + rgb + ", 0.0, 1.0);\n";
  if (has_alpha && !a.empty()) f += "  color.a = clamp(" + a + ", 0.0, 1.0);\n";
}

/// Argument `a` of unit u's combiner as a vec3 (RGB) or float (ALPHA)
/// expression. A texture source is the unit's texel as sampled, which is the
/// (Rt, Gt, Bt, At) of GL's table of texture source components for every
/// base format (ALPHA (0, 0, 0, A), LUMINANCE (L, L, L, 1), INTENSITY
/// (I, I, I, I) ...); PREVIOUS is the running colour (the primary colour on
/// the first enabled unit), PRIMARY_COLOR the fragment's primary colour.
std::string combine_operand_expr(const CombineArg& a, int u, bool alpha) {
  std::string src;
  switch (a.source) {
    case CombineSource::kTexture:
      src = "t" + std::to_string(u);
      break;
    case CombineSource::kTextureUnit:
      src = "t" + std::to_string(a.unit);
      break;
    case CombineSource::kConstant:
      src = "gl_TextureEnvColor[" + std::to_string(u) + "]";
      break;
    case CombineSource::kPrimaryColor:
      src = "ff_color";
      break;
    case CombineSource::kPrevious:
    case CombineSource::kOther:
      src = "color";
      break;
  }
  switch (a.operand) {
    case CombineOperand::kSrcColor:
      return alpha ? src + ".a" : src + ".rgb";
    case CombineOperand::kOneMinusSrcColor:
      return alpha ? "(1.0 - " + src + ".a)" : "(1.0 - " + src + ".rgb)";
    case CombineOperand::kSrcAlpha:
      return alpha ? src + ".a" : "vec3(" + src + ".a)";
    case CombineOperand::kOneMinusSrcAlpha:
    case CombineOperand::kOther:
      break;
  }
  return alpha ? "(1.0 - " + src + ".a)" : "vec3(1.0 - " + src + ".a)";
}

/// The combiner function `fn` of arguments `args` (GL 2.1 compatibility,
/// table 3.21), unscaled and unclamped.
std::string combine_expr(CombineFunc fn, const std::array<CombineArg, 3>& args, int u, bool alpha) {
  const std::string a0 = combine_operand_expr(args[0], u, alpha);
  auto arg = [&](int i) { return combine_operand_expr(args[size_t(i)], u, alpha); };
  switch (fn) {
    case CombineFunc::kReplace:
    case CombineFunc::kOther:
      return a0;
    case CombineFunc::kModulate:
      return a0 + " * " + arg(1);
    case CombineFunc::kAdd:
      return a0 + " + " + arg(1);
    case CombineFunc::kAddSigned:
      return a0 + " + " + arg(1) + " - 0.5";
    case CombineFunc::kInterpolate:
      return a0 + " * " + arg(2) + " + " + arg(1) + " * (1.0 - " + arg(2) + ")";
    case CombineFunc::kSubtract:
      return a0 + " - " + arg(1);
    case CombineFunc::kDot3Rgb:
    case CombineFunc::kDot3Rgba:
      // 4 x ((Arg0r - 0.5) x (Arg1r - 0.5) + ... g ... + ... b ...), the RGB arguments.
      return "4.0 * dot(" + combine_operand_expr(args[0], u, false) + " - 0.5, " +
             combine_operand_expr(args[1], u, false) + " - 0.5)";
  }
  return a0;
}

/// Unit u's GL_COMBINE environment on `color`: the RGB and ALPHA functions
/// of the previous colour, each multiplied by its scale and clamped to
/// [0, 1]; DOT3_RGB writes its dot product to R, G and B, DOT3_RGBA to all
/// four components (COMBINE_ALPHA is ignored; ALPHA_SCALE still applies).
void emit_texture_combine(const TextureUnitState& t, int u, std::string& f) {
  const CombineState& c = t.combine;
  const std::string n = std::to_string(u);
  const bool dot3 = c.rgb == CombineFunc::kDot3Rgb || c.rgb == CombineFunc::kDot3Rgba;
  f += "  // unit " + n + ": GL_COMBINE, RGB " + combine_func_name(c.rgb) + " x " + std::to_string(c.rgb_scale) +
       ", ALPHA " + (c.rgb == CombineFunc::kDot3Rgba ? "DOT3_RGBA" : combine_func_name(c.alpha)) + " x " +
       std::to_string(c.alpha_scale) + ", " + base_name(t.base) + " texture\n";
  // Both are computed from the previous colour before either is written.
  if (dot3) {
    f += "  float dot" + n + " = " + combine_expr(c.rgb, c.rgb_args, u, false) + ";\n";
    f += "  vec3 rgb" + n + " = vec3(dot" + n + ");\n";
  } else {
    f += "  vec3 rgb" + n + " = " + combine_expr(c.rgb, c.rgb_args, u, false) + ";\n";
  }
  if (c.rgb == CombineFunc::kDot3Rgba)
    f += "  float alpha" + n + " = dot" + n + ";\n";
  else
    f += "  float alpha" + n + " = " + combine_expr(c.alpha, c.alpha_args, u, true) + ";\n";
  auto scaled = [](const std::string& v, uint8_t scale) {
    return scale == 1 ? v : v + " * " + glsl_float(float(scale == 0 ? 1 : scale));
  };
  f += "  color = vec4(clamp(" + scaled("rgb" + n, c.rgb_scale) + ", 0.0, 1.0), clamp(" +
       scaled("alpha" + n, c.alpha_scale) + ", 0.0, 1.0));\n";
}

}  // namespace

GlslProgram fixed_function_program(const FixedFunctionState& s) {
  const char* interp = s.flat_shading ? "flat " : "";
  const bool secondary = has_secondary(s);
  const bool point_light = s.lighting && std::any_of(s.lights.begin(), s.lights.end(),
                                                     [](const LightState& l) { return l.enabled && !l.directional; });
  const bool need_eye = point_light || (s.lighting && s.local_viewer && any_light(s)) || s.clip_planes != 0 ||
                        (s.fog && s.fog_source == FogSource::kFragmentDepth);
  const bool need_power = s.lighting && any_light(s);

  GlslProgram p;
  std::string& v = p.vertex;
  std::string& f = p.fragment;
  v = "#version 450 compatibility\n// ropsim: fixed-function vertex processing\n";
  f = "#version 450 compatibility\n// ropsim: fixed-function fragment processing\n";

  // Interface.
  v += std::string(interp) + "out vec4 ff_color;\n";
  f += std::string(interp) + "in vec4 ff_color;\n";
  if (secondary) {
    v += std::string(interp) + "out vec4 ff_secondary;\n";
    f += std::string(interp) + "in vec4 ff_secondary;\n";
  }
  for (int u = 0; u < FixedFunctionState::kUnits; ++u) {
    if (!s.units[size_t(u)].active()) continue;
    const std::string n = std::to_string(u);
    v += "out vec4 ff_texcoord" + n + ";\n";
    f += "in vec4 ff_texcoord" + n + ";\n";
    f += "layout(binding = " + n + ") uniform sampler2D ff_texture" + n + ";\n";
  }
  if (s.fog) {
    v += "out float ff_fog_coord;\n";
    f += "in float ff_fog_coord;\n";
  }
  if (need_power) {
    // GLSL's pow is undefined for a base of 0 with exponent <= 0; GL's
    // lighting defines x^0 = 1 and 0^e = 0 for e > 0.
    v += "float ff_power(float x, float e) { return e == 0.0 ? 1.0 : x > 0.0 ? pow(x, e) : 0.0; }\n";
  }

  // Vertex shader body.
  v += "void main() {\n";
  v += "  gl_Position = ftransform();\n";
  if (need_eye) v += "  vec4 eye = gl_ModelViewMatrix * gl_Vertex;\n";
  if (s.clip_planes) v += "  gl_ClipVertex = eye;\n";
  if (s.lighting) {
    emit_lighting(s, v);
  } else {
    v += "  ff_color = clamp(gl_Color, 0.0, 1.0);\n";
    if (secondary) v += "  ff_secondary = clamp(gl_SecondaryColor, 0.0, 1.0);\n";
  }
  for (int u = 0; u < FixedFunctionState::kUnits; ++u) {
    if (!s.units[size_t(u)].active()) continue;
    const std::string n = std::to_string(u);
    v += "  ff_texcoord" + n + " = gl_TextureMatrix[" + n + "] * gl_MultiTexCoord" + n + ";\n";
  }
  if (s.fog)
    v += s.fog_source == FogSource::kFogCoord ? "  ff_fog_coord = gl_FogCoord;\n" : "  ff_fog_coord = abs(eye.z);\n";
  v += "}\n";

  // Fragment shader body.
  f += "void main() {\n";
  f += "  vec4 color = ff_color;\n";
  // Every enabled unit's texel first: a GL_COMBINE source may read another unit's.
  for (int u = 0; u < FixedFunctionState::kUnits; ++u) {
    if (!s.units[size_t(u)].active()) continue;
    const std::string n = std::to_string(u);
    f += "  vec4 t" + n + " = textureProj(ff_texture" + n + ", ff_texcoord" + n + ");\n";
  }
  for (int u = 0; u < FixedFunctionState::kUnits; ++u) {
    const TextureUnitState& t = s.units[size_t(u)];
    if (!t.active()) continue;
    if (t.env == TexEnvMode::kCombine)
      emit_texture_combine(t, u, f);
    else
      emit_texture_env(t, u, f);
  }
  if (secondary) f += "  color.rgb = min(color.rgb + ff_secondary.rgb, 1.0);\n";
  if (s.fog) {
    switch (s.fog_mode) {
      case FogMode::kLinear:
        f += "  float fog = (gl_Fog.end - ff_fog_coord) * gl_Fog.scale;\n";
        break;
      case FogMode::kExp:
        f += "  float fog = exp(-gl_Fog.density * ff_fog_coord);\n";
        break;
      case FogMode::kExp2:
        f += "  float fog_dc = gl_Fog.density * ff_fog_coord;\n";
        f += "  float fog = exp(-fog_dc * fog_dc);\n";
        break;
    }
    f += "  color.rgb = mix(gl_Fog.color.rgb, color.rgb, clamp(fog, 0.0, 1.0));\n";
  }
  if (s.alpha_test) {
    if (s.alpha_func == CompareFunc::kNever)
      f += "  discard;  // GL_ALPHA_TEST, GL_NEVER\n";
    else if (s.alpha_test_bits == 0)
      f += std::string("  if (!(color.a ") + compare_op(s.alpha_func) + " " + glsl_float(s.alpha_ref) +
           ")) discard;  // GL_ALPHA_TEST\n";
    else {
      const int bits = std::clamp(s.alpha_test_bits, 1, 8);
      const float one = float((1 << bits) - 1);
      const float ref = round_half_even(std::clamp(std::isnan(s.alpha_ref) ? 0.0f : s.alpha_ref, 0.0f, 1.0f) * one);
      f += "  if (!(roundEven(color.a * " + glsl_float(one) + ") " + compare_op(s.alpha_func) + " " + glsl_float(ref) +
           ")) discard;  // GL_ALPHA_TEST at " + std::to_string(bits) + " bits\n";
    }
  }
  f += "  gl_FragColor = color;\n";
  f += "}\n";
  return p;
}

}  // namespace ropsim::glcapture
