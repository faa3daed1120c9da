// A known mesh drawn with a shader: the clip-space triangles of a file
// (--vertices FILE: a little-endian uint32 triangle count, then 3 x count
// vertices of 4 binary32 each, x y z w; tests/test_capture_gl.cpp writes it
// from ropsim's own prepare_scene), in one glDrawArrays, with depth 0..1 = z/w
// (glClipControl) as ropsim's capture has it, constant colour, alpha 0.4,
// src-over blending, no depth test. So the coverage `ropsim capture gl` sees
// can be compared sample by sample with `ropsim capture` of the same scene.
#include <vector>

#include "tests/gl/gl_app.h"

int main(int argc, char** argv) {
  gltest::App a = gltest::open(argc, argv, "gl_mesh");
  const char* path = gltest::arg(argc, argv, "--vertices", nullptr);
  if (!path) gltest::die(a, "give --vertices FILE");
  FILE* f = std::fopen(path, "rb");
  if (!f) gltest::die(a, std::string(path) + ": cannot open");
  uint32_t count = 0;
  if (std::fread(&count, 4, 1, f) != 1) gltest::die(a, std::string(path) + ": no triangle count");
  std::vector<float> pos(size_t(count) * 12);
  if (std::fread(pos.data(), sizeof(float), pos.size(), f) != pos.size())
    gltest::die(a, std::string(path) + ": fewer vertices than the count says");
  std::fclose(f);

  const GLuint prog = gltest::program(a,
                                      "#version 450\n"
                                      "layout(location = 0) in vec4 clip;\n"
                                      "void main() { gl_Position = clip; }\n",
                                      "#version 450\n"
                                      "out vec4 colour;\n"
                                      "void main() { colour = vec4(0.2, 0.6, 0.9, 0.4); }\n",
                                      "mesh");
  GLuint vao = 0;
  glGenVertexArrays(1, &vao);
  glBindVertexArray(vao);
  gltest::attribute(0, 4, pos.data(), pos.size());
  glClipControl(GL_LOWER_LEFT, GL_ZERO_TO_ONE);
  return gltest::run(a, [&](int) {
    glClearColor(0, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
    glDisable(GL_DEPTH_TEST);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glUseProgram(prog);
    glDrawArrays(GL_TRIANGLES, 0, GLsizei(count * 3));
  });
}
