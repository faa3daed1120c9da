// A fixed-function draw and the same frame drawn by an equivalent shader
// (--mode ff | shader): one quad with per-vertex colours, one 4x4 RGBA
// texture (nearest filtering) under GL_MODULATE, and the alpha test
// GL_GREATER 0.5 (texels of alpha 0.25 are dropped). ff draws it with no
// program; shader with a GLSL program computing colour x texel and discarding
// alpha <= 0.5, from the same vertex data (compatibility built-ins: gl_Vertex,
// gl_Color, gl_MultiTexCoord0); shader-alpha-test with the same program
// without its discard, under GL's own alpha test (GL_ALPHA_TEST, GL_GREATER
// 0.5), which a compatibility context applies after the shader. --submit arrays (default) gives the vertices
// through fixed-function arrays in a buffer (glVertexPointer, glColorPointer,
// glTexCoordPointer) and one glDrawArrays(GL_TRIANGLE_FAN); --submit
// immediate through glBegin(GL_QUADS) ... glEnd.
#include "tests/gl/gl_app.h"

int main(int argc, char** argv) {
  gltest::App a = gltest::open(argc, argv, "gl_fixed_function");
  const std::string mode = gltest::arg(argc, argv, "--mode", "ff");
  if (mode != "ff" && mode != "shader" && mode != "shader-alpha-test")
    gltest::die(a, "--mode " + mode + ": not ff, shader or shader-alpha-test");
  const std::string submit = gltest::arg(argc, argv, "--submit", "arrays");
  if (submit != "arrays" && submit != "immediate") gltest::die(a, "--submit " + submit + ": not arrays or immediate");
  unsigned char texels[4 * 4 * 4];
  for (int y = 0; y < 4; ++y)
    for (int x = 0; x < 4; ++x) {
      unsigned char* t = texels + 4 * (y * 4 + x);
      t[0] = (unsigned char)(64 + 48 * x);
      t[1] = (unsigned char)(255 - 40 * y);
      t[2] = (unsigned char)((x + y) % 2 ? 255 : 32);
      t[3] = (x + y) % 3 == 0 ? 64 : 255;  // 0.25: below the alpha test's reference
    }
  GLuint tex = 0;
  glGenTextures(1, &tex);
  glBindTexture(GL_TEXTURE_2D, tex);
  glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, 4, 4, 0, GL_RGBA, GL_UNSIGNED_BYTE, texels);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  GLuint prog = 0;
  const std::string fs = std::string(
                             "#version 450 compatibility\n"
                             "uniform sampler2D tex;\n"
                             "void main() {\n"
                             "  vec4 c = gl_Color * texture(tex, gl_TexCoord[0].st);\n") +
                         (mode == "shader" ? "  if (!(c.a > 0.5)) discard;\n" : "") +
                         "  gl_FragColor = c;\n"
                         "}\n";
  if (mode != "ff")
    prog = gltest::program(a,
                           "#version 450 compatibility\n"
                           "void main() {\n"
                           "  gl_Position = gl_ModelViewProjectionMatrix * gl_Vertex;\n"
                           "  gl_FrontColor = gl_Color;\n"
                           "  gl_TexCoord[0] = gl_MultiTexCoord0;\n"
                           "}\n",
                           fs.c_str(), "modulate-alpha-test");
  // Corners: position (x, y), colour, texture coordinate.
  const float v[4][8] = {{-0.8f, -0.7f, 1.0f, 0.2f, 0.2f, 1.0f, 0.0f, 0.0f},
                         {0.9f, -0.8f, 0.2f, 1.0f, 0.2f, 0.9f, 1.0f, 0.0f},
                         {0.7f, 0.8f, 0.2f, 0.2f, 1.0f, 0.8f, 1.0f, 1.0f},
                         {-0.9f, 0.6f, 1.0f, 1.0f, 0.2f, 1.0f, 0.0f, 1.0f}};
  GLuint vbo = 0;
  glGenBuffers(1, &vbo);
  glBindBuffer(GL_ARRAY_BUFFER, vbo);
  glBufferData(GL_ARRAY_BUFFER, sizeof v, v, GL_STATIC_DRAW);
  const GLsizei stride = 8 * sizeof(float);
  glVertexPointer(2, GL_FLOAT, stride, reinterpret_cast<const void*>(0));
  glColorPointer(4, GL_FLOAT, stride, reinterpret_cast<const void*>(2 * sizeof(float)));
  glTexCoordPointer(2, GL_FLOAT, stride, reinterpret_cast<const void*>(6 * sizeof(float)));
  return gltest::run(a, [&](int) {
    glClearColor(0.1f, 0.1f, 0.1f, 1);
    glClear(GL_COLOR_BUFFER_BIT);
    glBindTexture(GL_TEXTURE_2D, tex);
    if (prog) {
      glUseProgram(prog);
      glUniform1i(glGetUniformLocation(prog, "tex"), 0);
      if (mode == "shader-alpha-test") {
        glEnable(GL_ALPHA_TEST);
        glAlphaFunc(GL_GREATER, 0.5f);
      }
    } else {
      glUseProgram(0);
      glEnable(GL_TEXTURE_2D);
      glTexEnvi(GL_TEXTURE_ENV, GL_TEXTURE_ENV_MODE, GL_MODULATE);
      glEnable(GL_ALPHA_TEST);
      glAlphaFunc(GL_GREATER, 0.5f);
    }
    if (submit == "immediate") {
      glBegin(GL_QUADS);
      for (const auto& c : v) {
        glColor4f(c[2], c[3], c[4], c[5]);
        glTexCoord2f(c[6], c[7]);
        glVertex2f(c[0], c[1]);
      }
      glEnd();
    } else {
      glEnableClientState(GL_VERTEX_ARRAY);
      glEnableClientState(GL_COLOR_ARRAY);
      glEnableClientState(GL_TEXTURE_COORD_ARRAY);
      glDrawArrays(GL_TRIANGLE_FAN, 0, 4);
    }
    glDisable(GL_TEXTURE_2D);
    glDisable(GL_ALPHA_TEST);
  });
}
