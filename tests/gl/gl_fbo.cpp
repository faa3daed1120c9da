// Draws into a framebuffer object, then post-processes it to the window:
// FBO 1 (the first name glGenFramebuffers returns; --fbo-size WxH, default
// 40x24, an RGBA8 texture) gets a clear and one opaque red triangle; then
// the window gets one full-window quad sampling the FBO's texture and
// writing 1 - its colour (opaque), and a blit of the FBO into the window's
// bottom-left corner (a copy, not a draw). --target fbo:1 captures the
// triangle; --target presented the quad.
#include "tests/gl/gl_app.h"

int main(int argc, char** argv) {
  gltest::App a = gltest::open(argc, argv, "gl_fbo");
  int fw = 40, fh = 24;
  if (std::sscanf(gltest::arg(argc, argv, "--fbo-size", "40x24"), "%dx%d", &fw, &fh) != 2 || fw < 1 || fh < 1)
    gltest::die(a, "--fbo-size: not WxH");
  GLuint tex = 0, fbo = 0;
  glGenTextures(1, &tex);
  glBindTexture(GL_TEXTURE_2D, tex);
  glTexStorage2D(GL_TEXTURE_2D, 1, GL_RGBA8, fw, fh);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  glGenFramebuffers(1, &fbo);
  glBindFramebuffer(GL_FRAMEBUFFER, fbo);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, tex, 0);
  if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE) gltest::die(a, "FBO incomplete");
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  const GLuint tri = gltest::program(a,
                                     "#version 450\n"
                                     "layout(location = 0) in vec2 p;\n"
                                     "void main() { gl_Position = vec4(p, 0.5, 1.0); }\n",
                                     "#version 450\n"
                                     "out vec4 colour;\n"
                                     "void main() { colour = vec4(1.0, 0.0, 0.0, 1.0); }\n",
                                     "scene");
  const GLuint post = gltest::program(a,
                                      "#version 450\n"
                                      "layout(location = 0) in vec2 p;\n"
                                      "out vec2 uv;\n"
                                      "void main() { uv = 0.5 * p + 0.5; gl_Position = vec4(p, 0.5, 1.0); }\n",
                                      "#version 450\n"
                                      "uniform sampler2D scene;\n"
                                      "in vec2 uv;\n"
                                      "out vec4 colour;\n"
                                      "void main() { colour = vec4(1.0 - texture(scene, uv).rgb, 1.0); }\n",
                                      "post-process");
  const float t[] = {-0.8f, -0.8f, 0.7f, -0.5f, -0.2f, 0.8f};
  const float quad[] = {-1, -1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1};
  GLuint vao[2] = {0, 0};
  glGenVertexArrays(2, vao);
  glBindVertexArray(vao[0]);
  gltest::attribute(0, 2, t, 6);
  glBindVertexArray(vao[1]);
  gltest::attribute(0, 2, quad, 12);
  return gltest::run(a, [&](int) {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo);
    glViewport(0, 0, fw, fh);
    glClearColor(0, 0, 0.5f, 1);
    glClear(GL_COLOR_BUFFER_BIT);
    glUseProgram(tri);
    glBindVertexArray(vao[0]);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glViewport(0, 0, a.width, a.height);
    glUseProgram(post);
    glBindTexture(GL_TEXTURE_2D, tex);
    glUniform1i(glGetUniformLocation(post, "scene"), 0);
    glBindVertexArray(vao[1]);
    glDrawArrays(GL_TRIANGLES, 0, 6);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo);
    glBlitFramebuffer(0, 0, fw, fh, 0, 0, fw / 2, fh / 2, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
  });
}
