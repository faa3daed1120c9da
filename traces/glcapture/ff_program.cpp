#include "ff_program.h"

// clang-format off
#include <GL/gl.h>
#include <GL/glext.h>
// clang-format on

#include <algorithm>
#include <charconv>
#include <cmath>
#include <system_error>

namespace ropsim::glcapture {

bool TextureUnitState::operator==(const TextureUnitState& o) const {
  return target == o.target && complete == o.complete && base == o.base && env == o.env && texgen == o.texgen &&
         lod_bias == o.lod_bias;
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
    if (t.env == TexEnvMode::kCombine) return "GL_COMBINE texture environment" + on;
    if (t.env == TexEnvMode::kOther)
      return "a texture environment mode other than MODULATE, REPLACE, DECAL, ADD, BLEND, COMBINE" + on;
    if (t.texgen) return "glTexGen" + on;
    if (t.lod_bias) return "a texture environment LOD bias (GL_TEXTURE_LOD_BIAS)" + on;
    if (t.base == TexBaseFormat::kDepth) return "a depth texture" + on;
    if (t.env == TexEnvMode::kDecal && t.base != TexBaseFormat::kRgb && t.base != TexBaseFormat::kRgba)
      return std::string("GL_DECAL with a ") + base_name(t.base) + " texture (undefined in GL)" + on;
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
  f += "  vec4 " + tex + " = textureProj(ff_texture" + std::to_string(u) + ", ff_texcoord" + std::to_string(u) + ");\n";
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
  for (int u = 0; u < FixedFunctionState::kUnits; ++u)
    if (s.units[size_t(u)].active()) emit_texture_env(s.units[size_t(u)], u, f);
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
