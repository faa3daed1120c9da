// A shader that discards a known region: a full-window quad (two triangles,
// one draw, opaque) whose fragment shader discards every pixel whose centre
// is inside the disc of radius width/4 about the window's centre, or in the
// left quarter (x < width/4). The region is symmetric under a vertical flip,
// so it reads the same top-down and bottom-up. The fragment shader declares
// an input that the vertex shader does not write and that it reads only
// under a branch the preprocessor drops (as OpenArena's shaders do): the
// program links, and so must the capture's instrumented twin.
#include "tests/gl/gl_app.h"

int main(int argc, char** argv) {
  gltest::App a = gltest::open(argc, argv, "gl_discard");
  const GLuint prog = gltest::program(a,
                                      "#version 450\n"
                                      "layout(location = 0) in vec2 p;\n"
                                      "void main() { gl_Position = vec4(p, 0.5, 1.0); }\n",
                                      "#version 450\n"
                                      "uniform vec2 size;\n"
                                      "in vec3 v_light;\n"
                                      "out vec4 colour;\n"
                                      "void main() {\n"
                                      "  vec2 c = gl_FragCoord.xy - 0.5 * size;\n"
                                      "  if (dot(c, c) < 0.0625 * size.x * size.x || gl_FragCoord.x < 0.25 * size.x)\n"
                                      "    discard;\n"
                                      "  colour = vec4(0.25, 0.5, 0.75, 1.0);\n"
                                      "#if defined(USE_LIGHT)\n"
                                      "  colour.rgb *= v_light;\n"
                                      "#endif\n"
                                      "}\n",
                                      "discard");
  const float quad[] = {-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1};
  GLuint vao = 0;
  glGenVertexArrays(1, &vao);
  glBindVertexArray(vao);
  gltest::attribute(0, 2, quad, 12);
  return gltest::run(a, [&](int) {
    glClearColor(0, 0, 0, 1);
    glClear(GL_COLOR_BUFFER_BIT);
    glUseProgram(prog);
    glUniform2f(glGetUniformLocation(prog, "size"), float(a.width), float(a.height));
    glDrawArrays(GL_TRIANGLES, 0, 6);
  });
}
