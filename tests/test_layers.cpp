// Layers only point down (docs/architecture.md "Layers"): bit-level
// algorithms and generic containers at the bottom; the input formats and
// scenes; the functional ROP and the golden model; the SystemC models; the
// drivers and the CLI on top. This test reads every source file's
// `#include "..."` lines and fails when a file includes a header of a higher
// layer. Within the SystemC models, memory and the sorters sit below core,
// core below the units, the units below the pipeline top.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

struct Layer {
  const char* folder;
  int level;  ///< a file may include headers of its own level or below
  const char* what;
};

// The layer table. A new source folder must be added here (the test fails
// otherwise), and docs/architecture.md shows the same table.
constexpr Layer kLayers[] = {
    {"util", 0, "base: output files and errors"},
    {"util/containers", 0, "base: generic containers"},
    {"util/codec", 0, "base: image decoding and encoding (OpenImageIO, loaded on first use)"},
    {"rtl_models/algo", 0, "base: bit-level algorithms"},
    {"rtl_models/cost", 0, "base: silicon cost of the reference RTL (synthesis sweep, models)"},
    {"traces/format", 10, "input: trace format v1"},
    {"traces/raster", 11, "input: rasterizer, sample patterns"},
    {"traces/scenes", 12, "input: built-in scenes"},
    {"traces/capture", 13, "input: capture from meshes"},
    {"traces/glcapture", 14,
     "input: capture from OpenGL applications (the preloaded library, the fixed-function emulation)"},
    {"sim/functional", 20, "functional ROP: methods, store, stages, counters, fragment sources"},
    {"sim/golden", 21, "functional: the golden model"},
    {"rtl_models/config", 30, "models: the hardware config"},
    {"rtl_models/memory", 31, "models: ROP cache, DRAM, address map"},
    {"rtl_models/sorter", 31, "models: sorter variants"},
    {"rtl_models/core", 32, "models: units, FIFOs, scheduler, tokens"},
    {"rtl_models/units", 33, "models: the ROP units"},
    {"sim/top", 34, "models: the pipeline top and the cycle run"},
    {"sim/image", 40, "drivers: image files"},
    {"sim/driver", 41, "drivers: runs, reports, vectors"},
    {"sim/study", 42, "drivers: studies (sweeps, the local executor, the results database)"},
    {"sim/cli", 43, "drivers: the ropsim command"},
};
// Folders with sources that sit above every layer (nothing includes them);
// tests/rtl: the Verilator testbenches, tests/gl: the GL test programs.
const std::set<std::string> kTop = {"tests", "tests/rtl", "tests/gl", "bench", "fuzz"};

bool is_source(const fs::path& p) {
  const auto e = p.extension().string();
  return e == ".h" || e == ".hpp" || e == ".cpp" || e == ".cc";
}

struct Scan {
  std::vector<std::string> problems;  ///< upward includes, unlayered folders, ambiguous names
  size_t checked = 0;                 ///< includes resolved to a layered header
};

/// Scans every source under root.
Scan scan(const fs::path& root) {
  Scan r;
  std::map<std::string, const Layer*> by_folder;
  for (const auto& l : kLayers) by_folder[l.folder] = &l;

  // Every source file, by folder; every header, by bare name (includes name
  // headers without a folder, so a name must be unique).
  std::map<std::string, std::vector<fs::path>> files;  // folder -> sources
  std::map<std::string, std::string> header_folder;    // name -> folder
  for (auto it = fs::recursive_directory_iterator(root); it != fs::recursive_directory_iterator(); ++it) {
    const fs::path rel = fs::relative(it->path(), root);
    const std::string first = rel.begin()->string();
    if (it->is_directory() && (first.rfind("build", 0) == 0 || first[0] == '.' || first == "docs")) {
      it.disable_recursion_pending();
      continue;
    }
    if (!it->is_regular_file() || !is_source(rel)) continue;
    const std::string folder = rel.parent_path().generic_string();
    if (kTop.count(folder)) continue;
    if (!by_folder.count(folder)) {
      r.problems.push_back(folder +
                           " holds sources but has no layer: add it to kLayers in tests/test_layers.cpp "
                           "and to docs/architecture.md");
      continue;
    }
    files[folder].push_back(it->path());
    const std::string name = rel.filename().string();
    if (rel.extension() == ".h" || rel.extension() == ".hpp") {
      auto [pos, fresh] = header_folder.emplace(name, folder);
      if (!fresh)
        r.problems.push_back("header " + name + " exists in " + pos->second + " and " + folder +
                             ": includes name headers without their folder, so names must be unique");
    }
  }

  const std::regex include_re(R"re(^\s*#\s*include\s*"([^"]+)")re");
  for (const auto& [folder, paths] : files) {
    const Layer& from = *by_folder.at(folder);
    for (const auto& p : paths) {
      std::ifstream in(p);
      std::string line;
      for (int n = 1; std::getline(in, line); ++n) {
        std::smatch m;
        if (!std::regex_search(line, m, include_re)) continue;
        const std::string name = fs::path(m[1].str()).filename().string();
        auto h = header_folder.find(name);
        if (h == header_folder.end()) continue;  // a generated or third-party header
        ++r.checked;
        const Layer& to = *by_folder.at(h->second);
        if (to.level > from.level)
          r.problems.push_back(fs::relative(p, root).generic_string() + ":" + std::to_string(n) + " includes " + name +
                               " of " + to.folder + " (layer " + std::to_string(to.level) + ", " + to.what +
                               ") from layer " + std::to_string(from.level) + " (" + from.what +
                               "): layers only point down");
      }
    }
  }
  return r;
}

TEST(Layers, NoSourceIncludesAHeaderOfAHigherLayer) {
  const Scan r = scan(ROPSIM_SOURCE_DIR);
  for (const auto& p : r.problems) ADD_FAILURE() << p;
  EXPECT_GT(r.checked, 150u) << "too few includes checked: the scan is broken";
}

// The scan finds an upward include, an unlayered folder and an ambiguous
// header name in a synthetic tree, and accepts downward includes.
TEST(Layers, TheScanCatchesWhatItMustOnASyntheticTree) {
  const fs::path root = fs::temp_directory_path() / ("ropsim-layers-" + std::to_string(::getpid()));
  fs::remove_all(root);
  auto put = [&](const std::string& rel, const std::string& text) {
    fs::create_directories((root / rel).parent_path());
    std::ofstream(root / rel) << text;
  };
  put("sim/functional/stage.h", "#include \"unit.h\"\n#include \"bits.h\"\n");  // up, then down
  put("rtl_models/units/unit.h", "#include \"stage.h\"\n");                     // down
  put("rtl_models/algo/bits.h", "#pragma once\n");
  put("sim/newfolder/x.cpp", "int x;\n");  // no layer
  put("traces/format/stage.h", "\n");      // name clash
  const Scan r = scan(root);
  fs::remove_all(root);
  auto has = [&](const std::string& needle) {
    for (const auto& p : r.problems)
      if (p.find(needle) != std::string::npos) return true;
    return false;
  };
  EXPECT_TRUE(has("sim/functional/stage.h:1 includes unit.h")) << "the upward include was not caught";
  EXPECT_FALSE(has("stage.h:2")) << "a downward include was rejected";
  EXPECT_FALSE(has("rtl_models/units/unit.h:1")) << "a downward include was rejected";
  EXPECT_TRUE(has("sim/newfolder holds sources but has no layer")) << "an unlayered folder was not caught";
  EXPECT_TRUE(has("header stage.h exists in")) << "an ambiguous header name was not caught";
}

}  // namespace

namespace {

int run(const std::string& cmd, std::string& out) {
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return -1;
  char buf[4096];
  for (size_t n; (n = fread(buf, 1, sizeof buf, p)) > 0;) out.append(buf, n);
  return pclose(p);
}

// Every C++ source follows .clang-format (scripts/format.sh formats them).
TEST(Format, EverySourceIsClangFormatted) {
  std::string out;
  const int st = run("bash '" ROPSIM_SOURCE_DIR "/scripts/format.sh' --check", out);
  EXPECT_EQ(st, 0) << out;
}

// The check sees a file that is not formatted (so the test above can fail).
TEST(Format, TheCheckRejectsAnUnformattedFile) {
  const fs::path dir = fs::temp_directory_path() / ("ropsim-format-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  fs::copy_file(ROPSIM_SOURCE_DIR "/.clang-format", dir / ".clang-format");
  std::ofstream(dir / "bad.cpp") << "int  f( int x ){return x;}\n";
  std::string out;
  const int st = run("cd '" + dir.string() + "' && clang-format --dry-run --Werror bad.cpp", out);
  fs::remove_all(dir);
  EXPECT_NE(st, 0) << "clang-format accepted an unformatted file: " << out;
}

}  // namespace
