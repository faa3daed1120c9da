#include "glsl_rewrite.h"

#include <cctype>
#include <regex>
#include <vector>

namespace ropsim::glcapture {

namespace {

bool ident_char(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }

const char* version_line(GlslProfile p) {
  return p == GlslProfile::kCompatibility ? "#version 450 compatibility" : "#version 450 core";
}

/// Replaces the #version directive (or adds one at the top).
std::string set_version(const std::string& src, GlslProfile profile) {
  static const std::regex kVersion(R"((^|\n)[ \t]*#[ \t]*version[^\n]*)");
  std::smatch m;
  if (std::regex_search(src, m, kVersion))
    return src.substr(0, size_t(m.position(0))) + m[1].str() + version_line(profile) +
           src.substr(size_t(m.position(0) + m.length(0)));
  // No directive: GLSL 1.10 (compile logs count the added line).
  return std::string(version_line(profile)) + "\n" + src;
}

/// Renames every `main` followed by `(` (the definition and any prototype).
/// Returns the number renamed.
int rename_main(std::string& s) {
  int n = 0;
  std::string out;
  out.reserve(s.size() + 64);
  for (size_t i = 0; i < s.size();) {
    if (s.compare(i, 4, "main") == 0 && (i == 0 || !ident_char(s[i - 1])) &&
        (i + 4 >= s.size() || !ident_char(s[i + 4]))) {
      size_t j = i + 4;
      while (j < s.size() && std::isspace(static_cast<unsigned char>(s[j]))) ++j;
      if (j < s.size() && s[j] == '(') {
        out += "ropsim_app_main";
        i += 4;
        ++n;
        continue;
      }
    }
    out += s[i++];
  }
  s = std::move(out);
  return n;
}

/// The source with everything inside braces blanked: the global scope only.
std::string global_scope(const std::string& s) {
  std::string out = s;
  int depth = 0;
  for (char& c : out) {
    if (c == '{') {
      ++depth;
      c = ' ';
    } else if (c == '}') {
      --depth;
      c = ' ';
    } else if (depth > 0 && c != '\n') {
      c = ' ';
    }
  }
  return out;
}

bool uses(const std::string& s, const char* name) {
  const std::regex re(std::string(R"((^|[^A-Za-z0-9_]))") + name + R"(([^A-Za-z0-9_]|$))");
  return std::regex_search(s, re);
}

}  // namespace

std::string strip_comments(const std::string& src) {
  std::string out;
  out.reserve(src.size());
  for (size_t i = 0; i < src.size();) {
    if (src.compare(i, 2, "//") == 0) {
      while (i < src.size() && src[i] != '\n') ++i;
      out += ' ';
    } else if (src.compare(i, 2, "/*") == 0) {
      size_t end = src.find("*/", i + 2);
      end = end == std::string::npos ? src.size() : end + 2;
      out += ' ';
      for (size_t k = i; k < end; ++k)
        if (src[k] == '\n') out += '\n';
      i = end;
    } else {
      out += src[i++];
    }
  }
  return out;
}

std::string fragment_color_expression(const std::string& s) {
  // `[layout(...)] out [precision] vec4 NAME;` at global scope.
  static const std::regex kOut(
      R"((layout\s*\(([^)]*)\)\s*)?\bout\s+((highp|mediump|lowp)\s+)?vec4\s+([A-Za-z_][A-Za-z0-9_]*)\s*(;|\[))");
  static const std::regex kLocation(R"(location\s*=\s*([0-9]+))");
  const std::string g = global_scope(s);
  std::string first, at_zero;
  int outs = 0;
  for (auto it = std::sregex_iterator(g.begin(), g.end(), kOut); it != std::sregex_iterator(); ++it) {
    const std::smatch& m = *it;
    std::string name = m[5].str();
    if (m[6].str() == "[") name += "[0]";
    ++outs;
    if (first.empty()) first = name;
    std::smatch loc;
    const std::string layout = m[2].str();
    if (std::regex_search(layout, loc, kLocation) && loc[1].str() == "0" && at_zero.empty()) at_zero = name;
  }
  if (!at_zero.empty()) return at_zero;
  if (outs > 0) return first;
  if (uses(s, "gl_FragData")) return "gl_FragData[0]";
  if (uses(s, "gl_FragColor")) return "gl_FragColor";
  return "vec4(0.0, 0.0, 0.0, 1.0)";
}

Rewritten instrument_vertex_shader(const std::string& src, GlslProfile profile) {
  std::string s = set_version(strip_comments(src), profile);
  const int mains = rename_main(s);
  if (mains == 0) return {s, ""};
  s += "\n// ropsim capture: the instance for the fragment records, the geometry moved by the pass's sample offset\n"
       "uniform vec2 ropsim_offset;\n"
       "uniform bool ropsim_upside_down;\n"
       "flat out int ropsim_instance;\n"
       "void main() {\n"
       "  ropsim_app_main();\n"
       "  ropsim_instance = gl_InstanceID;\n"
       "  gl_Position.xy += ropsim_offset * gl_Position.w;\n"
       "  if (ropsim_upside_down) gl_Position.y = -gl_Position.y;\n"
       "}\n";
  return {s, ""};
}

Rewritten instrument_fragment_shader(const std::string& src, GlslProfile profile, int binding) {
  std::string s = set_version(strip_comments(src), profile);
  const std::string color = fragment_color_expression(s);
  const int mains = rename_main(s);
  if (mains == 0) return {s, ""};
  s += "\n// ropsim capture: one record per fragment that survives the shader\n"
       "layout(std430, binding = " +
       std::to_string(binding) +
       ") buffer RopsimFragments { uint ropsim_count; uint ropsim_pad; uint ropsim_rec[]; };\n"
       "uniform uint ropsim_capacity;\n"
       "flat in int ropsim_instance;\n"
       "void main() {\n"
       "  ropsim_app_main();\n"
       "  if (!gl_HelperInvocation) {\n"
       "    vec4 ropsim_color = " +
       color +
       ";\n"
       "    uint i = atomicAdd(ropsim_count, 1u);\n"
       "    if (i < ropsim_capacity) {\n"
       "      uint b = i * " +
       std::to_string(kRecordWords) +
       "u;\n"
       "      ropsim_rec[b + 0u] = uint(gl_FragCoord.x) | (uint(gl_FragCoord.y) << 16);\n"
       "      ropsim_rec[b + 1u] = uint(gl_PrimitiveID);\n"
       "      ropsim_rec[b + 2u] = uint(ropsim_instance);\n"
       "      ropsim_rec[b + 3u] = floatBitsToUint(gl_FragCoord.z);\n"
       "      ropsim_rec[b + 4u] = floatBitsToUint(ropsim_color.r);\n"
       "      ropsim_rec[b + 5u] = floatBitsToUint(ropsim_color.g);\n"
       "      ropsim_rec[b + 6u] = floatBitsToUint(ropsim_color.b);\n"
       "      ropsim_rec[b + 7u] = floatBitsToUint(ropsim_color.a);\n"
       "    }\n"
       "  }\n"
       "}\n";
  return {s, ""};
}

}  // namespace ropsim::glcapture
