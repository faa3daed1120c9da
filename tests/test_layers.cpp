// Layers only point down (docs/architecture.md "Layers"): the base (generic
// utilities, containers and the bit-level rules), the input (trace format,
// rasterizer, scenes, capture), the functional ROP and the golden model, the
// SystemC models, the fidelities, and the drivers and the CLI on top. Every
// include names its header from the source root, so a header's layer is read
// from its path. This test reads every source file's `#include "..."` lines
// and fails when one runs up a layer, when two folders of one layer include
// each other, or when a project header is named without its folder.
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
    {"util", 0, "base: output files, errors, progress, child processes"},
    {"util/containers", 0, "base: generic containers"},
    {"util/codec", 0,
     "base: image decoding and encoding (OpenImageIO as a module loaded on first use; PNG written by libpng in the "
     "process)"},
    {"rtl_models/algo", 0, "base: the bit-level rules every fidelity calls"},
    {"rtl_models/cost", 0, "base: silicon cost of the reference RTL (synthesis sweep, models)"},
    {"traces/format", 10, "input: the trace format"},
    {"traces/raster", 11, "input: rasterizer, sample patterns"},
    {"traces/scenes", 12, "input: built-in scenes"},
    {"traces/capture", 13, "input: capture from meshes"},
    {"traces/glcapture", 14,
     "input: capture from OpenGL applications (the preloaded library, the fixed-function emulation, the launcher)"},
    {"rtl_models/functional", 20, "functional ROP: methods, store, stages, counters, fragment sources"},
    {"rtl_models/golden", 21, "functional: the golden model"},
    {"rtl_models/config", 30, "models: the design's parameters"},
    {"rtl_models/observe", 31, "models: observation (waveform, interval log, attribution)"},
    {"rtl_models/memory", 32, "models: ROP caches, DRAM, address map, compression"},
    {"rtl_models/sorter", 32, "models: sorter variants"},
    {"rtl_models/core", 33, "models: units, FIFOs, scheduler, tokens"},
    {"rtl_models/units", 34, "models: the ROP units"},
    {"rtl_models/top", 35, "models: the pipeline top and its memory estimate"},
    {"sim/image", 40, "drivers: image files"},
    {"sim/fidelity/common", 41, "fidelities: what they share (the bottleneck rule)"},
    {"sim/fidelity/functional", 42, "fidelities: the functional run"},
    {"sim/fidelity/cycle", 43, "fidelities: the cycle run"},
    {"sim/fidelity/approximate", 43, "fidelities: the analytical model"},
    {"sim/fidelity/sampled", 44, "fidelities: sampled simulation from live-points"},
    {"sim/fidelity", 45, "fidelities: the fidelity, its run request and result, one entry that runs any"},
    {"sim/report", 46, "drivers: JSON reports and summaries"},
    {"sim/driver", 47, "drivers: RTL vectors, pixels by kind"},
    {"sim/study", 48, "drivers: studies (sweeps, the local executor, the results database)"},
    {"sim/cli", 49, "drivers: the ropsim command"},
};
// Folders with sources that sit above every layer (nothing includes them);
// tests/rtl: the Verilator testbenches, tests/gl: the GL test programs.
const std::set<std::string> kTop = {"tests", "tests/rtl", "tests/gl", "bench", "fuzz"};

bool is_source(const fs::path& p) {
  const auto e = p.extension().string();
  return e == ".h" || e == ".hpp" || e == ".cpp" || e == ".cc";
}

struct Scan {
  std::vector<std::string> problems;  ///< upward includes, unlayered folders, includes without their folder
  size_t checked = 0;                 ///< includes resolved to a layered header
  std::set<std::pair<std::string, std::string>> edges;  ///< folder -> a folder it includes
};

/// Scans every source under root.
Scan scan(const fs::path& root) {
  Scan r;
  std::map<std::string, const Layer*> by_folder;
  for (const auto& l : kLayers) by_folder[l.folder] = &l;

  // Every source file, by folder; every header's path, by bare name (to name
  // the path an include without its folder should have used).
  std::map<std::string, std::vector<fs::path>> files;  // folder -> sources
  std::map<std::string, std::string> header_path;      // name -> path from root
  for (auto it = fs::recursive_directory_iterator(root); it != fs::recursive_directory_iterator(); ++it) {
    const fs::path rel = fs::relative(it->path(), root);
    const std::string first = rel.begin()->string();
    if (it->is_directory() && (first.rfind("build", 0) == 0 || first[0] == '.' || first == "docs" || first == "out")) {
      it.disable_recursion_pending();
      continue;
    }
    if (!it->is_regular_file() || !is_source(rel)) continue;
    const std::string folder = rel.parent_path().generic_string();
    if (rel.extension() == ".h" || rel.extension() == ".hpp")
      header_path.emplace(rel.filename().string(), rel.generic_string());
    if (!kTop.count(folder) && !by_folder.count(folder)) {
      r.problems.push_back(folder +
                           " holds sources but has no layer: add it to kLayers in tests/test_layers.cpp "
                           "and to docs/architecture.md");
      continue;
    }
    files[folder].push_back(it->path());
  }

  const std::regex include_re(R"re(^\s*#\s*include\s*"([^"]+)")re");
  for (const auto& [folder, paths] : files) {
    const bool top = kTop.count(folder) > 0;
    for (const auto& p : paths) {
      const std::string where = fs::relative(p, root).generic_string();
      std::ifstream in(p);
      std::string line;
      for (int n = 1; std::getline(in, line); ++n) {
        std::smatch m;
        if (!std::regex_search(line, m, include_re)) continue;
        const fs::path inc = m[1].str();
        if (!fs::exists(root / inc)) {
          auto h = header_path.find(inc.filename().string());
          if (h != header_path.end())
            r.problems.push_back(where + ":" + std::to_string(n) + " includes \"" + inc.generic_string() +
                                 "\": name it from the source root, \"" + h->second + "\"");
          continue;  // a generated or third-party header
        }
        if (top) continue;  // tests, benchmarks and fuzz targets sit above every layer
        const std::string to_folder = inc.parent_path().generic_string();
        auto to = by_folder.find(to_folder);
        if (to == by_folder.end()) {
          r.problems.push_back(where + ":" + std::to_string(n) + " includes " + inc.generic_string() +
                               ", which is in no layer");
          continue;
        }
        ++r.checked;
        const Layer& from = *by_folder.at(folder);
        if (to_folder != folder) r.edges.emplace(folder, to_folder);
        if (to->second->level > from.level)
          r.problems.push_back(where + ":" + std::to_string(n) + " includes " + inc.generic_string() + " (layer " +
                               std::to_string(to->second->level) + ", " + to->second->what + ") from layer " +
                               std::to_string(from.level) + " (" + from.what + "): layers only point down");
      }
    }
  }
  // The folder-level picture: two folders of one layer may not include each other.
  for (const auto& [a, b] : r.edges)
    if (a < b && r.edges.count({b, a}))
      r.problems.push_back(a + " and " + b + " include each other: split them into two layers");
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
  put("rtl_models/functional/stage.h",
      "#include \"rtl_models/units/unit.h\"\n#include \"rtl_models/algo/bits.h\"\n");  // up, then down
  put("rtl_models/units/unit.h", "#include \"rtl_models/functional/stage.h\"\n");      // down
  put("rtl_models/algo/bits.h", "#pragma once\n");
  put("rtl_models/memory/a.h", "#include \"rtl_models/sorter/b.h\"\n");  // one layer, both ways
  put("rtl_models/sorter/b.h", "#include \"rtl_models/memory/a.h\"\n");
  put("sim/newfolder/x.cpp", "int x;\n");         // no layer
  put("sim/cli/y.cpp", "#include \"bits.h\"\n");  // without its folder
  const Scan r = scan(root);
  fs::remove_all(root);
  auto has = [&](const std::string& needle) {
    for (const auto& p : r.problems)
      if (p.find(needle) != std::string::npos) return true;
    return false;
  };
  EXPECT_TRUE(has("rtl_models/functional/stage.h:1 includes rtl_models/units/unit.h"))
      << "the upward include was not caught";
  EXPECT_FALSE(has("stage.h:2")) << "a downward include was rejected";
  EXPECT_FALSE(has("rtl_models/units/unit.h:1")) << "a downward include was rejected";
  EXPECT_TRUE(has("rtl_models/memory and rtl_models/sorter include each other"))
      << "two folders of one layer including each other were not caught";
  EXPECT_TRUE(has("sim/newfolder holds sources but has no layer")) << "an unlayered folder was not caught";
  EXPECT_TRUE(has("sim/cli/y.cpp:1 includes \"bits.h\": name it from the source root, \"rtl_models/algo/bits.h\""))
      << "an include without its folder was not caught";
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

// The check sees a file that is not formatted (so the test above can fail):
// scripts/format.sh --check in a tree of its own names the unformatted files,
// and only them, and passes once they are formatted.
TEST(Format, TheCheckRejectsAnUnformattedFile) {
  const fs::path dir = fs::temp_directory_path() / ("ropsim-format-" + std::to_string(::getpid()));
  fs::create_directories(dir / "scripts");
  for (const char* d : {"rtl_models", "sim", "traces", "tests", "bench", "util"}) fs::create_directories(dir / d);
  fs::copy_file(ROPSIM_SOURCE_DIR "/.clang-format", dir / ".clang-format");
  fs::copy_file(ROPSIM_SOURCE_DIR "/scripts/format.sh", dir / "scripts" / "format.sh");
  std::ofstream(dir / "sim" / "bad.cpp") << "int  f( int x ){return x;}\n";
  std::ofstream(dir / "util" / "good.h") << "int g(int x);\n";
  std::ofstream(dir / "tests" / "worse.h") << "int h( int x ) ;\n";
  std::string out;
  const std::string check = "bash '" + (dir / "scripts" / "format.sh").string() + "' --check";
  const int st = run(check, out);
  EXPECT_NE(st, 0) << "the check accepted unformatted files: " << out;
  EXPECT_NE(out.find("sim/bad.cpp"), std::string::npos) << out;
  EXPECT_NE(out.find("tests/worse.h"), std::string::npos) << "only the first bad file was named: " << out;
  EXPECT_EQ(out.find("util/good.h"), std::string::npos) << "a formatted file was named: " << out;
  std::string fixed;
  EXPECT_EQ(run("bash '" + (dir / "scripts" / "format.sh").string() + "'", fixed), 0) << fixed;
  std::string again;
  EXPECT_EQ(run(check, again), 0) << "the check rejects what the script formatted: " << again;
  fs::remove_all(dir);
}

}  // namespace
