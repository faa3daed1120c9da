#include "fuzz_targets.h"

#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <cstdlib>
#include <stdexcept>
#include <vector>

#include "errors.h"
#include "golden_model.h"
#include "hw_config.h"
#include "livepoint_file.h"
#include "scene_file.h"
#include "study.h"
#include "trace.h"

namespace ropsim_fuzz {

namespace {

/// The screen whose resolved rows are also read back (every pixel, so a
/// larger screen would only cost time): any screen is modelled and resolved,
/// since the state, image and directory follow what the trace touches.
constexpr uint64_t kMaxRowsPixels = uint64_t{1} << 20;
/// Fragments read from one input (a fuzzed header may promise billions).
constexpr uint64_t kMaxFuzzFragments = 1u << 16;
/// Studies expanded in full (a fuzzed study may ask for 100,000 points).
constexpr uint64_t kMaxFuzzStudyPoints = 4096;

/// Runs fn; an input error (std::runtime_error) is an expected outcome.
template <class F>
int expect_input_errors(F&& fn) {
  try {
    fn();
  } catch (const std::runtime_error&) {
  }
  return 0;
}

}  // namespace

std::string input_file(const uint8_t* data, size_t size, const char* suffix) {
  const char* tmp = std::getenv("TMPDIR");
  const std::string path =
      std::string(tmp && *tmp ? tmp : "/tmp") + "/ropsim-fuzz-" + std::to_string(::getpid()) + suffix;
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f || (size && std::fwrite(data, 1, size, f) != size) || std::fclose(f) != 0) std::abort();
  return path;
}

int fuzz_trace(const uint8_t* data, size_t size) {
  const std::string path = input_file(data, size, ".rtrace");
  return expect_input_errors([&] {
    ropsim::TraceReader r(path);
    const ropsim::TraceHeader& h = r.header();
    ropsim::GoldenConfig cfg;
    cfg.method = ropsim::Method::kLk;
    ropsim::StochasticModel model(h, cfg);
    ropsim::Fragment f;
    for (uint64_t n = 0; n < kMaxFuzzFragments && r.next(f); ++n) model.draw(f);
    const ropsim::Image img = model.resolve();
    if (img.width != h.width || img.height != h.height) std::abort();
    if (img.tiles() > model.store().tiles()) std::abort();  // the image holds only touched tiles
    if (uint64_t(h.width) * h.height <= kMaxRowsPixels) {
      std::vector<float> row(size_t(h.width) * 3);
      for (uint32_t y = 0; y < h.height; ++y) img.row(y, row.data());
    }
  });
}

int fuzz_scene(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  return expect_input_errors([&] { (void)ropsim::parse_scene_text(text, "fuzz-scene.toml"); });
}

int fuzz_design(const uint8_t* data, size_t size) {
  std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<std::string> overrides;
  if (const auto sep = text.find("\n%%\n"); sep != std::string::npos) {
    std::string rest = text.substr(sep + 4);
    text.resize(sep + 1);
    for (size_t a = 0; a <= rest.size();) {
      const size_t b = std::min(rest.find('\n', a), rest.size());
      if (b > a) overrides.push_back(rest.substr(a, b - a));
      a = b + 1;
    }
  }
  ropsim::HwConfig cfg;
  bool loaded = false;
  expect_input_errors([&] {
    cfg = ropsim::parse_hw_config(text, "fuzz-design.toml", overrides);  // resolve_hw_config, from memory
    loaded = true;
  });
  if (!loaded) return 0;
  // Printed and read back, the design is the same design.
  const std::string printed = ropsim::hw_config_to_toml(cfg);
  ropsim::HwConfig again;
  try {
    again = ropsim::parse_hw_config(printed, "printed.toml");
  } catch (const std::runtime_error& e) {
    std::fprintf(stderr, "a loaded design, printed, does not load: %s\n%s", e.what(), printed.c_str());
    std::abort();
  }
  if (ropsim::hw_config_digest(again) != ropsim::hw_config_digest(cfg) || ropsim::hw_config_to_toml(again) != printed) {
    std::fprintf(stderr, "a design printed and read back differs:\n%s---\n%s", printed.c_str(),
                 ropsim::hw_config_to_toml(again).c_str());
    std::abort();
  }
  return 0;
}

int fuzz_study(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  return expect_input_errors([&] {
    // Named in the current folder: the files it names are looked for there.
    const ropsim::Study s = ropsim::parse_study(text, "fuzz-study.toml");
    // Expanding 100,000 points runs the code 10,000 do, for 100 ms an input:
    // the large ones are checked for their count only, so the campaign
    // reaches its executions (docs/testing.md "Fuzzing").
    if (s.points_at_most <= kMaxFuzzStudyPoints) (void)ropsim::expand_study(s);
  });
}

int fuzz_livepoints(const uint8_t* data, size_t size) {
  std::vector<uint8_t> file;
  if (size >= 8 && std::memcmp(data, "ROPSIMLP", 8) == 0) {
    file.assign(data, data + size);
  } else {
    file = ropsim::wrap_livepoint_payload(data, size);
  }
  const std::string path = input_file(file.data(), file.size(), ".rlp");
  return expect_input_errors([&] {
    const ropsim::LivePoints lib = ropsim::read_livepoints(path);
    // What reads, writes and reads back to the same bytes.
    const std::string again = path + ".again.rlp", third = path + ".third.rlp";
    ropsim::write_livepoints(again, lib);
    ropsim::write_livepoints(third, ropsim::read_livepoints(again));
    auto bytes = [](const std::string& p) {
      std::ifstream f(p, std::ios::binary);
      return std::vector<char>((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    };
    const bool same = bytes(again) == bytes(third);
    std::remove(again.c_str());
    std::remove(third.c_str());
    if (!same) std::abort();
  });
}

}  // namespace ropsim_fuzz
