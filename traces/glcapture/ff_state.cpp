// The fixed-function module's state half (ff_program.h): reading the
// current fixed-function state through GlGetters, its comparison, and the
// subset it is captured in (unsupported_reason()). The generated programs
// are ff_program.cpp's.
#include "traces/glcapture/ff_program.h"

// clang-format off
#include <GL/gl.h>
#include <GL/glext.h>
// clang-format on

#include <algorithm>
#include <charconv>
#include <cmath>
#include <system_error>

#include "traces/glcapture/ff_names.h"

namespace ropsim::glcapture {

using namespace ff_names;

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

}  // namespace ropsim::glcapture
