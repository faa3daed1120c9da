#include "traces/glcapture/glsl_rewrite.h"

#include <algorithm>
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

/// A fragment-shader input that the wrapper reads at the pixel centre.
struct CentreInput {
  std::string type, name;
  bool perspective;  ///< smooth (perspective-correct), not noperspective
};

/// The fragment shader's interpolated inputs, read at the pixel centre: each
/// global `[layout(...)] [smooth|noperspective] in|varying [precision]
/// float|vecN NAME;` (at the start of a line or after a `;` or `}`) gets a
/// global copy `ropsim_c_NAME` and a #define that sends the shader's reads
/// to it (a #line after keeps the application's line numbers). Returns the
/// inputs; the wrapper's main fills each copy with interpolateAtOffset(NAME,
/// ropsim_pixel_offset) after #undef-ing it, where #define ropsim_has_NAME
/// says the preprocessor kept the declaration (a declaration under an #if
/// branch that is not compiled has no copy). Flat, centroid and sample
/// inputs, arrays, blocks, GL's built-in inputs and inputs the shader never
/// names outside their declaration are left as they are.
std::vector<CentreInput> centre_inputs(std::string& s, const std::vector<std::string>& as_is) {
  static const std::regex kIn(
      R"((layout\s*\([^)]*\)\s*)?((smooth|noperspective)\s+)?(in|varying)\s+((highp|mediump|lowp)\s+)?)"
      R"((float|vec2|vec3|vec4)\s+([A-Za-z_][A-Za-z0-9_]*)\s*;)");
  const std::string g = global_scope(s);
  struct Hit {
    size_t end;
    CentreInput in;
  };
  std::vector<Hit> hits;
  // The source without its input declarations: an input that it never
  // names is not read at the centre (the wrapper's read would be a static
  // use, and a declared input that the vertex shader does not write links
  // only while nothing uses it, as OpenArena's var_ColorAmbient).
  std::string rest = s;
  for (auto it = std::sregex_iterator(g.begin(), g.end(), kIn); it != std::sregex_iterator(); ++it)
    std::fill(rest.begin() + it->position(0), rest.begin() + it->position(0) + it->length(0), ' ');
  for (auto it = std::sregex_iterator(g.begin(), g.end(), kIn); it != std::sregex_iterator(); ++it) {
    const std::smatch& m = *it;
    // A declaration of its own: what comes before it on its line is
    // nothing, or the end of another statement (not `flat`, `centroid`).
    size_t k = size_t(m.position(0));
    while (k > 0 && (g[k - 1] == ' ' || g[k - 1] == '\t')) --k;
    if (k > 0 && g[k - 1] != '\n' && g[k - 1] != ';' && g[k - 1] != '}') continue;
    const std::string name = m[8].str();
    if (name.compare(0, 3, "gl_") == 0 || name.compare(0, 7, "ropsim_") == 0) continue;
    if (!uses(rest, name.c_str())) continue;
    if (std::find(as_is.begin(), as_is.end(), name) != as_is.end()) continue;
    hits.push_back({size_t(m.position(0) + m.length(0)), {m[7].str(), name, m[3].str() != "noperspective"}});
  }
  std::vector<CentreInput> inputs;
  for (auto h = hits.rbegin(); h != hits.rend(); ++h) {
    const size_t line = size_t(std::count(s.begin(), s.begin() + std::ptrdiff_t(h->end), '\n')) + 1;
    // ropsim_has_NAME: the copy exists where the preprocessor keeps the
    // declaration (one under `#ifdef GL_ES` is not compiled here), and the
    // wrapper fills it only then.
    s.insert(h->end, "\n" + h->in.type + " ropsim_c_" + h->in.name + ";\n#define " + h->in.name + " ropsim_c_" +
                         h->in.name + "\n#define ropsim_has_" + h->in.name + "\n#line " + std::to_string(line) + "\n");
    inputs.push_back(h->in);
  }
  return inputs;
}

/// GL's built-in interpolated inputs of the compatibility profile that the
/// shader reads (and does not redeclare), read at the pixel centre like
/// centre_inputs': a global copy each, a #define that sends the reads to it
/// (placed after the leading directives, #line keeping the line numbers),
/// and the wrapper's statements that fill the copies (after the returned
/// #undef lines). Returns {undefs, fill statements}.
std::pair<std::string, std::string> centre_builtin_inputs(std::string& s) {
  struct Builtin {
    const char* name;
    const char* decl;  ///< the copy's declaration
    const char* fill;  ///< the wrapper's statement
  };
  static const Builtin kBuiltins[] = {
      {"gl_Color", "vec4 ropsim_c_gl_Color;",
       "  ropsim_c_gl_Color = ropsim_moved ? ropsim_at_offset(gl_Color * ropsim_q) / ropsim_q_at : gl_Color;\n"},
      {"gl_SecondaryColor", "vec4 ropsim_c_gl_SecondaryColor;",
       "  ropsim_c_gl_SecondaryColor =\n"
       "      ropsim_moved ? ropsim_at_offset(gl_SecondaryColor * ropsim_q) / ropsim_q_at : gl_SecondaryColor;\n"},
      {"gl_FogFragCoord", "float ropsim_c_gl_FogFragCoord;",
       "  ropsim_c_gl_FogFragCoord =\n"
       "      ropsim_moved ? ropsim_at_offset(gl_FogFragCoord * ropsim_q) / ropsim_q_at : gl_FogFragCoord;\n"},
  };
  const std::string g = global_scope(s);
  std::string decls, undefs, fills;
  for (const Builtin& b : kBuiltins) {
    if (!uses(s, b.name)) continue;
    const std::regex redeclared(std::string(R"(\b(in|varying)\s+[^;]*\b)") + b.name + R"(\b)");
    if (std::regex_search(g, redeclared)) continue;
    decls += std::string(b.decl) + "\n#define " + b.name + " ropsim_c_" + b.name + "\n";
    undefs += std::string("\n#undef ") + b.name;
    fills += b.fill;
  }
  // gl_TexCoord (implicitly sized): the elements up to the highest constant
  // index the shader reads; all 8 of llvmpipe's with a variable index.
  if (uses(s, "gl_TexCoord") && !std::regex_search(g, std::regex(R"(\b(in|varying)\s+[^;]*\bgl_TexCoord\b)"))) {
    static const std::regex kIndex(R"(gl_TexCoord\s*\[\s*([^\]]*)\])");
    int top = -1;
    for (auto it = std::sregex_iterator(s.begin(), s.end(), kIndex); it != std::sregex_iterator(); ++it) {
      const std::string i = (*it)[1].str();
      const bool constant = !i.empty() && i.size() < 3 && std::all_of(i.begin(), i.end(), ::isdigit);
      top = std::max(top, constant ? std::stoi(i) : 7);
    }
    if (top >= 0) {
      decls +=
          "vec4 ropsim_c_gl_TexCoord[" + std::to_string(top + 1) + "];\n#define gl_TexCoord ropsim_c_gl_TexCoord\n";
      undefs += "\n#undef gl_TexCoord";
      for (int k = 0; k <= top; ++k)
        fills += "  ropsim_c_gl_TexCoord[" + std::to_string(k) + "] = ropsim_moved ? ropsim_at_offset(gl_TexCoord[" +
                 std::to_string(k) + "] * ropsim_q) / ropsim_q_at : gl_TexCoord[" + std::to_string(k) + "];\n";
    }
  }
  if (decls.empty()) return {"", ""};
  // After the leading lines that are directives (#version, #extension) or blank.
  size_t at = 0, line = 1;
  while (at < s.size()) {
    size_t end = s.find('\n', at);
    if (end == std::string::npos) break;
    size_t k = at;
    while (k < end && (s[k] == ' ' || s[k] == '\t')) ++k;
    if (k < end && s[k] != '#') break;
    at = end + 1;
    ++line;
  }
  s.insert(at, decls + "#line " + std::to_string(line) + "\n");
  return {undefs, fills};
}

/// The node buffers' declarations (glsl_rewrite.h kCaptureBindings) at
/// `binding` on.
std::string node_buffers(int binding) {
  auto at = [binding](int k) { return std::to_string(binding + k); };
  return "layout(std430, binding = " + at(0) +
         ") coherent buffer RopsimHeads { uint ropsim_count; uint ropsim_pad[3]; uint ropsim_head[]; };\n"
         "layout(std430, binding = " +
         at(1) +
         ") coherent buffer RopsimKeys { uvec4 ropsim_key[]; };\n"
         "layout(std430, binding = " +
         at(2) +
         ") buffer RopsimState { uint ropsim_state[]; };\n"
         "layout(std430, binding = " +
         at(3) +
         ") writeonly buffer RopsimColour { vec4 ropsim_colour[]; };\n"
         "layout(std430, binding = " +
         at(4) + ") writeonly buffer RopsimDepth { uint ropsim_depth[]; };\n";
}

/// The shading passes' declaration: the stencil test before the shader, so
/// that llvmpipe skips the blocks of pixels it rejects (a shader that writes
/// memory is otherwise tested after it runs).
constexpr const char* kEarlyTests = "layout(early_fragment_tests) in;\n";

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

Rewritten instrument_fragment_shader(const std::string& src, GlslProfile profile, int binding,
                                     const std::vector<std::string>& as_is, bool early_tests) {
  std::string s = set_version(strip_comments(src), profile);
  const std::string color = fragment_color_expression(s);
  const int mains = rename_main(s);
  if (mains == 0) return {s, ""};
  const auto inputs = centre_inputs(s, as_is);
  const auto [builtin_undefs, builtin_fills] = centre_builtin_inputs(s);
  s += builtin_undefs;
  std::string centre = builtin_fills;
  for (const CentreInput& in : inputs) {
    s += "\n#undef " + in.name;
    centre += "#ifdef ropsim_has_" + in.name + "\n  ropsim_c_" + in.name + " = ropsim_moved ? " +
              (in.perspective ? "ropsim_at_offset(" + in.name + " * ropsim_q) / ropsim_q_at"
                              : "ropsim_at_offset(" + in.name + ")") +
              " : " + in.name + ";\n#endif\n";
  }
  // An input at the pixel centre, ropsim_pixel_offset from where the pass
  // shades, from its derivatives: exact for what is affine in window
  // coordinates, as a noperspective input is, and as a smooth input times
  // 1/w (gl_FragCoord.w) is, which is then divided by 1/w at the centre. No
  // interpolateAtOffset: llvmpipe's divides a smooth input read at an offset
  // by w at the fragment, not at the offset. Without a shift (the centre
  // pass, the 4x reference) each input is read as it is.
  if (!centre.empty())
    centre =
        "  bool ropsim_moved = ropsim_pixel_offset != vec2(0.0);\n"
        "  float ropsim_q = gl_FragCoord.w;\n"
        "  float ropsim_q_at = ropsim_at_offset(ropsim_q);\n" +
        centre;
  s += "\n// ropsim capture: one node per fragment (pixel, part, instance, primitive), its coverage, depths and the\n"
       "// colour of its one shaded invocation; its inputs read at the pixel centre\n"
       "uniform vec2 ropsim_pixel_offset;\n" +
       std::string(early_tests ? kEarlyTests : "") +
       "#define ropsim_at_offset(v) ((v) + dFdx(v) * ropsim_pixel_offset.x + dFdy(v) * ropsim_pixel_offset.y)\n" +
       node_buffers(binding) +
       // ropsim_pass: 0 writes nothing (the 4x reference); 1 the centre pass;
       // 2 a sample pass, of sample ropsim_sample. ropsim_gate: a sample
       // pass ends the invocations it does not shade before the
       // application's main (off when GL_SAMPLES_PASSED counts the passes).
       "uniform int ropsim_pass;\n"
       "uniform uint ropsim_sample;\n"
       "uniform bool ropsim_gate;\n"
       "uniform uint ropsim_part;\n"
       "uniform uint ropsim_capacity;\n"
       "uniform uint ropsim_width;\n"
       "uniform uint ropsim_lists;\n"
       "flat in int ropsim_instance;\n"
       // A compatibility context's alpha test (GL_ALPHA_TEST) with a GLSL
       // program: GL applies it after the shader, so the wrapper applies it
       // first, before the fragment is kept. ropsim_alpha_func: 0 off, else
       // the function's enum less GL_NEVER - 1 (1 never ... 8 always);
       // ropsim_alpha_one: 0 compares floats, else 2^bits - 1 for a target
       // of <= 8 bits a channel, compared as llvmpipe does there: both rounded
       // to that many bits, ties to even (the reference rounded by the host).
       "uniform int ropsim_alpha_func;\n"
       "uniform float ropsim_alpha_ref;\n"
       "uniform float ropsim_alpha_one;\n"
       "bool ropsim_alpha_passes(float a) {\n"
       "  if (ropsim_alpha_one > 0.0) a = roundEven(clamp(a, 0.0, 1.0) * ropsim_alpha_one);\n"
       "  switch (ropsim_alpha_func) {\n"
       "    case 1: return false;\n"
       "    case 2: return a < ropsim_alpha_ref;\n"
       "    case 3: return a == ropsim_alpha_ref;\n"
       "    case 4: return a <= ropsim_alpha_ref;\n"
       "    case 5: return a > ropsim_alpha_ref;\n"
       "    case 6: return a != ropsim_alpha_ref;\n"
       "    case 7: return a >= ropsim_alpha_ref;\n"
       "    default: return true;\n"
       "  }\n"
       "}\n"
       // The fragment's node in its pixel's list: found, else made and
       // pushed on the list (lock-free: the head swapped in by
       // atomicCompSwap; a failed swap walks only the nodes pushed since).
       // A pass covers a pixel at most once per primitive, so no two
       // invocations of one pass make the same node. kNoNode when the nodes
       // overflow ropsim_capacity (the count goes on, and the draw is
       // captured again with room for them).
       "uint ropsim_node(uint pixel, uint pixel_index, out bool made) {\n"
       "  uvec3 key = uvec3(uint(gl_PrimitiveID), uint(ropsim_instance), ropsim_part);\n"
       "  uint list = pixel_index * ropsim_lists + ((key.x + key.y + key.z) & (ropsim_lists - 1u));\n"
       "  uint head = ropsim_head[list], stop = 0xFFFFFFFFu, mine = 0xFFFFFFFFu;\n"
       "  made = false;\n"
       "  for (;;) {\n"
       "    for (uint n = head; n != stop; n = ropsim_key[n].w)\n"
       "      if (ropsim_key[n].xyz == key) return n;\n"
       "    if (mine == 0xFFFFFFFFu) {\n"
       "      mine = atomicAdd(ropsim_count, 1u);\n"
       "      if (mine >= ropsim_capacity) return 0xFFFFFFFFu;\n"
       "      ropsim_state[mine] = pixel | (ropsim_pass == 1 ? " +
       std::to_string(kNodeCentre) +
       "u : 0u);\n"
       "    }\n"
       "    ropsim_key[mine] = uvec4(key, head);\n"
       "    memoryBarrierBuffer();\n"
       "    uint seen = atomicCompSwap(ropsim_head[list], head, mine);\n"
       "    if (seen == head) {\n"
       "      made = true;\n"
       "      return mine;\n"
       "    }\n"
       "    stop = head;\n"
       "    head = seen;\n"
       "  }\n"
       "}\n"
       "void main() {\n"
       "  uint ropsim_n = 0xFFFFFFFFu;\n"
       "  bool ropsim_shade = true;\n"
       "  if (ropsim_pass != 0 && !gl_HelperInvocation) {\n"
       "    uint x = uint(gl_FragCoord.x), y = uint(gl_FragCoord.y);\n"
       "    bool made;\n"
       "    ropsim_n = ropsim_node(x | (y << 16), y * ropsim_width + x, made);\n"
       "    if (ropsim_n != 0xFFFFFFFFu && ropsim_pass == 2) {\n"
       // The sample's depth word (its bits inverted: a word that is not
       // kNoDepth is the sample's coverage); the fragment is shaded here when this pass made
       // its node: its primitive misses the pixel centre and this is its
       // lowest covered sample (the passes run in sample order after the
       // centre's).
       "      ropsim_shade = made;\n"
       "      ropsim_depth[ropsim_n] = ~floatBitsToUint(gl_FragCoord.z);\n"
       "    }\n"
       "  }\n"
       "  if (ropsim_gate && !ropsim_shade) discard;\n" +
       centre +
       "  ropsim_app_main();\n"
       "  vec4 ropsim_color = " +
       color +
       ";\n"
       "  if (ropsim_alpha_func != 0 && !ropsim_alpha_passes(ropsim_color.a)) discard;\n"
       // Kept: the shaded invocation did not discard (flag 2).
       "  if (ropsim_n != 0xFFFFFFFFu && ropsim_shade) {\n"
       "    ropsim_colour[ropsim_n] = ropsim_color;\n"
       "    ropsim_state[ropsim_n] |= " +
       std::to_string(kNodeKept) +
       "u;\n"
       "  }\n"
       "}\n";
  return {s, ""};
}

Rewritten coverage_fragment_shader(GlslProfile profile, int binding, int unit) {
  // The walk of the pixel's list is the wrapper's (ropsim_node()) without
  // the making of a node, through texel fetches: llvmpipe runs every branch
  // of a shader on its lanes (masked) and reads a storage buffer a lane at a
  // time, where a texel fetch gathers the lanes at once. Helper invocations
  // stay out of the walk: llvmpipe runs a loop until every lane of the exec
  // mask leaves it, and a helper's reads are not the list's.
  return {std::string(version_line(profile)) +
              "\n// ropsim capture: a sample pass's depth in the fragment's node; a fragment without a node is kept\n"
              "// (it marks its pixel in the stencil buffer) for the shading pass that makes it\n"
              "layout(std430, binding = " +
              std::to_string(binding + 4) +
              ") writeonly buffer RopsimDepth { uint ropsim_depth[]; };\n"
              "layout(binding = " +
              std::to_string(unit) +
              ") uniform usamplerBuffer ropsim_heads;\n"
              "layout(binding = " +
              std::to_string(unit + 1) +
              ") uniform usamplerBuffer ropsim_keys;\n"
              "uniform uint ropsim_part;\n"
              "uniform uint ropsim_width;\n"
              "uniform uint ropsim_lists;\n"
              "flat in int ropsim_instance;\n"
              "void main() {\n"
              "  bool found = false;\n"
              "  if (!gl_HelperInvocation) {\n"
              "    uint x = uint(gl_FragCoord.x), y = uint(gl_FragCoord.y);\n"
              "    uvec3 key = uvec3(uint(gl_PrimitiveID), uint(ropsim_instance), ropsim_part);\n"
              "    uint n = texelFetch(ropsim_heads, int(" +
              std::to_string(kHeadsHeaderWords) +
              "u + (y * ropsim_width + x) * ropsim_lists + ((key.x + key.y + key.z) & (ropsim_lists - 1u)))).x;\n"
              "    while (n != 0xFFFFFFFFu) {\n"
              "      uvec4 k = texelFetch(ropsim_keys, int(n));\n"
              "      if (k.xyz == key) break;\n"
              "      n = k.w;\n"
              "    }\n"
              "    if (n != 0xFFFFFFFFu) {\n"
              "      ropsim_depth[n] = ~floatBitsToUint(gl_FragCoord.z);\n"
              "      found = true;\n"
              "    }\n"
              "  }\n"
              "  if (found) discard;\n"
              "}\n",
          ""};
}

}  // namespace ropsim::glcapture
