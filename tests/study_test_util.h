// Helpers of the tests that run the ropsim binary on study folders
// (test_study.cpp, test_study_report.cpp, test_study_slurm.cpp): a scratch
// folder per test, running a command with a time limit, reading a study's
// results through `ropsim study export`.
#pragma once
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#ifndef ROPSIM_BINARY
#error "ROPSIM_BINARY must name the built ropsim executable (tests/CMakeLists.txt)"
#endif

namespace ropsim_test {

namespace fs = std::filesystem;

inline std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// A private folder for the running test, removed afterwards.
struct Scratch {
  fs::path dir;
  explicit Scratch(const std::string& prefix = "ropsim-test-study") {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir = fs::temp_directory_path() / (prefix + "-" + std::to_string(::getpid()) + "-" + (info ? info->name() : "x"));
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  ~Scratch() { fs::remove_all(dir); }
  Scratch(const Scratch&) = delete;
  Scratch& operator=(const Scratch&) = delete;
  fs::path put(const std::string& name, const std::string& text) const {
    std::ofstream(dir / name) << text;
    return dir / name;
  }
};

struct Ran {
  int status;  ///< exit status; 124 when the time limit killed it, -1 for a signal
  std::string out, err;
};

/// Runs a shell command in dir, killed after timeout_s seconds.
inline Ran shell(const fs::path& dir, const std::string& cmd, int timeout_s = 300) {
  const std::string o = (dir / ".stdout").string(), e = (dir / ".stderr").string();
  const std::string full = "cd '" + dir.string() + "' && timeout -k 5 " + std::to_string(timeout_s) + " " + cmd +
                           " >'" + o + "' 2>'" + e + "'";
  const int st = std::system(full.c_str());
  return Ran{WIFEXITED(st) ? WEXITSTATUS(st) : -1, slurp(o), slurp(e)};
}

/// Runs the ropsim binary with args in dir.
inline Ran ropsim(const fs::path& dir, const std::string& args, int timeout_s = 300) {
  return shell(dir, "'" ROPSIM_BINARY "' " + args, timeout_s);
}

/// One CSV line's fields (RFC 4180 quoting).
inline std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> f;
  std::string cur;
  bool q = false;
  for (size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (q) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        cur += '"';
        ++i;
      } else if (c == '"') {
        q = false;
      } else {
        cur += c;
      }
    } else if (c == '"') {
      q = true;
    } else if (c == ',') {
      f.push_back(cur);
      cur.clear();
    } else {
      cur += c;
    }
  }
  f.push_back(cur);
  return f;
}

/// A study folder's results table (`ropsim study export`), rows of column -> value.
using Rows = std::vector<std::map<std::string, std::string>>;
inline Rows export_rows(const fs::path& dir, const std::string& study_dir) {
  const Ran r = ropsim(dir, "study export '" + study_dir + "' --csv out.csv");
  EXPECT_EQ(r.status, 0) << r.err;
  std::ifstream f(dir / "out.csv");
  std::string line;
  std::getline(f, line);
  const auto head = csv_fields(line);
  Rows rows;
  while (std::getline(f, line)) {
    const auto v = csv_fields(line);
    std::map<std::string, std::string> m;
    for (size_t i = 0; i < head.size() && i < v.size(); ++i) m[head[i]] = v[i];
    rows.push_back(m);
  }
  return rows;
}

/// The rows without the host's measurements (times, rates, memory), which
/// differ from run to run.
inline Rows model_results(Rows rows) {
  for (auto& r : rows)
    for (auto it = r.begin(); it != r.end();)
      it = it->first.rfind("host.", 0) == 0 || it->first.rfind("timing.host.", 0) == 0 ? r.erase(it) : std::next(it);
  return rows;
}

}  // namespace ropsim_test
