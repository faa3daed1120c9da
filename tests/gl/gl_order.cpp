// API order: draw 0 is three overlapping triangles in one glDrawArrays
// (red, green, blue: primitive 0, 1, 2), draw 1 one triangle drawn as three
// instances (yellow, cyan, magenta: instance 0, 1, 2), each shifted a little;
// every primitive and instance covers the window's centre. Alpha 0.5,
// src-over, no depth test: the frame depends on the order of all six.
#include "tests/gl/gl_app.h"

int main(int argc, char** argv) {
  gltest::App a = gltest::open(argc, argv, "gl_order");
  const GLuint tris = gltest::program(a,
                                      "#version 450\n"
                                      "layout(location = 0) in vec2 p;\n"
                                      "layout(location = 1) in vec3 rgb;\n"
                                      "flat out vec3 c;\n"
                                      "void main() { c = rgb; gl_Position = vec4(p, 0.5, 1.0); }\n",
                                      "#version 450\n"
                                      "flat in vec3 c;\n"
                                      "out vec4 colour;\n"
                                      "void main() { colour = vec4(c, 0.5); }\n",
                                      "overlapping");
  const GLuint inst = gltest::program(a,
                                      "#version 450\n"
                                      "layout(location = 0) in vec2 p;\n"
                                      "flat out int i;\n"
                                      "void main() {\n"
                                      "  i = gl_InstanceID;\n"
                                      "  gl_Position = vec4(p + vec2(0.05 * float(gl_InstanceID), 0.0), 0.5, 1.0);\n"
                                      "}\n",
                                      "#version 450\n"
                                      "flat in int i;\n"
                                      "out vec4 colour;\n"
                                      "const vec3 rgb[3] = vec3[3](vec3(1, 1, 0), vec3(0, 1, 1), vec3(1, 0, 1));\n"
                                      "void main() { colour = vec4(rgb[i], 0.5); }\n",
                                      "instanced");
  const float p[] = {-0.9f, -0.8f, 0.8f,  -0.6f, 0.1f, 0.9f,   // red
                     -0.7f, 0.7f,  -0.2f, -0.9f, 0.9f, 0.5f,   // green
                     -0.8f, 0.1f,  0.6f,  -0.8f, 0.5f, 0.8f};  // blue
  const float rgb[] = {1, 0, 0, 1, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  const float one[] = {-0.6f, -0.6f, 0.5f, -0.5f, -0.1f, 0.7f};
  GLuint vao[2] = {0, 0};
  glGenVertexArrays(2, vao);
  glBindVertexArray(vao[0]);
  gltest::attribute(0, 2, p, 18);
  gltest::attribute(1, 3, rgb, 27);
  glBindVertexArray(vao[1]);
  gltest::attribute(0, 2, one, 6);
  return gltest::run(a, [&](int) {
    glClearColor(0, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT);
    glEnable(GL_BLEND);
    glBlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
    glUseProgram(tris);
    glBindVertexArray(vao[0]);
    glDrawArrays(GL_TRIANGLES, 0, 9);
    glUseProgram(inst);
    glBindVertexArray(vao[1]);
    glDrawArraysInstanced(GL_TRIANGLES, 0, 3, 3);
  });
}
