// A stand-in for the capture library (libropsim_glcapture.so) that tests
// `ropsim capture gl`'s process handling without GL: preloaded like the real
// one and, like it, inert unless ROPSIM_GL_CONTROL is set. In every process it
// is loaded into it appends "PID" to CONTROL/pids and writes the pid of the
// Xvfb ropsim started to CONTROL/xvfb.pid (so a test can check that every
// process is gone afterwards), and writes the ROPSIM_GL_* and
// Mesa variables it sees to CONTROL/env.txt. Then, by
// $ROPSIM_TEST_STAND_IN:
//   ok          status ok (2 draws, one of them unsupported), list.json, a
//               trace of 16 bytes at ROPSIM_GL_OUT unless LIST_ONLY; _exit(0)
//   error       status ok=false with the error $ROPSIM_TEST_STAND_IN_ERROR; _exit(0)
//   exit-early  at the process's exit: status ok=false "the application
//               exited after 0 frames, before frame N" (as the library on an
//               early exit)
//   silent      nothing more (the application runs as it is: exits, crashes
//               or hangs)
// Used by tests/test_capture_gl.cpp only; never installed.
#include <dirent.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>

namespace {

std::string control() {
  const char* c = std::getenv("ROPSIM_GL_CONTROL");
  return c ? c : "";
}

std::string env(const char* name) {
  const char* v = std::getenv(name);
  return v ? v : "";
}

void write_file(const std::string& path, const std::string& text, const char* mode = "w") {
  FILE* f = std::fopen(path.c_str(), mode);
  if (!f) return;
  std::fputs(text.c_str(), f);
  std::fclose(f);
}

/// As the library does: a temporary name, then renamed.
void write_status(const std::string& text) {
  const std::string dir = control();
  write_file(dir + "/.status.json.tmp", text);
  std::rename((dir + "/.status.json.tmp").c_str(), (dir + "/status.json").c_str());
}

void at_exit() {
  write_status("{\"ok\": false, \"error\": \"the application exited after 0 frames, before frame " +
               env("ROPSIM_GL_FRAME") + "\", \"frames_seen\": 0}");
}

__attribute__((constructor)) void stand_in() {
  const std::string dir = control();
  if (dir.empty()) return;
  // The Xvfb ropsim started is this process's sibling: a child of ropsim
  // named Xvfb (only the application itself, ropsim's child, finds it).
  if (DIR* proc = opendir("/proc")) {
    while (dirent* e = readdir(proc)) {
      FILE* f = std::fopen(("/proc/" + std::string(e->d_name) + "/stat").c_str(), "r");
      if (!f) continue;
      long pid = 0, ppid = 0;
      char comm[64] = {}, state = 0;
      if (std::fscanf(f, "%ld (%63[^)]) %c %ld", &pid, comm, &state, &ppid) == 4 && ppid == long(getppid()) &&
          !std::strcmp(comm, "Xvfb"))
        write_file(dir + "/xvfb.pid", std::to_string(pid) + "\n");
      std::fclose(f);
    }
    closedir(proc);
  }
  std::string seen;
  for (const char* v :
       {"ROPSIM_GL_FRAME", "ROPSIM_GL_SPP", "ROPSIM_GL_TARGET", "ROPSIM_GL_OUT", "ROPSIM_GL_LIST_ONLY",
        "ROPSIM_GL_COUNT_SAMPLES", "ROPSIM_GL_REFERENCE_MSAA", "LIBGL_ALWAYS_SOFTWARE", "GALLIUM_DRIVER", "DISPLAY"})
    if (std::getenv(v)) seen += std::string(v) + "=" + env(v) + "\n";
  write_file(dir + "/env.txt", seen);
  // Last: a test that waits for this line finds the other files written.
  write_file(dir + "/pids", std::to_string(getpid()) + "\n", "a");
  const std::string mode = env("ROPSIM_TEST_STAND_IN");
  if (mode == "ok") {
    write_file(dir + "/list.json",
               "{\"framebuffers\": [{\"name\": \"presented\", \"width\": 32, \"height\": 16, \"samples\": 1, "
               "\"encoding\": \"unorm8\", \"draws\": 2, \"presented\": true}],"
               " \"draws\": [{\"index\": 0, \"framebuffer\": \"presented\", \"program\": 3, \"name\": \"glass\", "
               "\"kind\": \"src-over\", \"blend\": \"add(src_alpha, one_minus_src_alpha)\", \"depth\": \"less, no "
               "writes\", \"fragments\": 10, \"covered_samples\": 40, \"samples_passed\": null},"
               " {\"index\": 1, \"framebuffer\": \"presented\", \"program\": 0, \"name\": \"program 0\", \"kind\": "
               "\"opaque\", \"blend\": \"off\", \"depth\": \"off\", \"fragments\": 0, \"covered_samples\": 0, "
               "\"samples_passed\": 7}]}");
    if (env("ROPSIM_GL_LIST_ONLY") != "1") write_file(env("ROPSIM_GL_OUT"), "stand-in trace\n");
    write_status("{\"ok\": true, \"error\": \"\", \"frames_seen\": " + env("ROPSIM_GL_FRAME") +
                 ", \"frame\": " + env("ROPSIM_GL_FRAME") + ", \"target\": \"" + env("ROPSIM_GL_TARGET") +
                 "\", \"width\": 32, \"height\": 16, \"spp\": " + env("ROPSIM_GL_SPP") +
                 ", \"draws\": 1, \"fragments\": 10, \"unsupported\": [{\"draw\": 1, \"name\": \"program 0\", "
                 "\"reason\": \"fog mode GL_EXP2 is not emulated\"}]}");
    _exit(0);
  }
  if (mode == "error") {
    write_status("{\"ok\": false, \"error\": \"" + env("ROPSIM_TEST_STAND_IN_ERROR") + "\"}");
    _exit(0);
  }
  if (mode == "exit-early") std::atexit(at_exit);
}

}  // namespace
