// The fixed-function module's program half (ff_program.h): the GLSL 4.50
// compatibility vertex and fragment shaders equivalent to a fixed-function
// state inside the subset. Reading the state and the subset are
// ff_state.cpp's.
#include "traces/glcapture/ff_program.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <string>
#include <system_error>

#include "traces/glcapture/ff_names.h"

namespace ropsim::glcapture {

using namespace ff_names;

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
