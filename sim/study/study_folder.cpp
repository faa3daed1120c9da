#include "sim/study/study_folder.h"

#include <fcntl.h>
#include <stdlib.h>
#include <sys/file.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <system_error>
#include <vector>

#include "util/errors.h"

namespace fs = std::filesystem;

namespace ropsim {

std::string read_whole_file(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

fs::path point_dir(const std::string& dir, const StudyPoint& p) { return fs::path(dir) / "points" / p.hash; }
fs::path ref_path(const std::string& dir, const std::string& key) { return fs::path(dir) / "refs" / (key + ".exr"); }

fs::path capture_path(const std::string& dir, const std::string& key) {
  return fs::path(dir) / "traces" / (key + ".rtr");
}

fs::path capture_error_path(const std::string& dir, const std::string& key) {
  return fs::path(dir) / "traces" / (key + ".error");
}

fs::path ref_error_path(const std::string& dir, const std::string& key) {
  return fs::path(dir) / "refs" / (key + ".error");
}

fs::path host_error_path(const fs::path& error_path) {
  return error_path.parent_path() /
         (error_path.extension() == ".txt" ? "host-error.txt" : error_path.stem().string() + ".host-error");
}

std::string recorded_error(const fs::path& f) {
  std::string e = read_whole_file(f);
  while (!e.empty() && e.back() == '\n') e.pop_back();
  return e;
}

void clear_point_errors(const std::string& dir, const StudyPoint& p) {
  fs::remove(point_dir(dir, p) / "error.txt");
  fs::remove(point_dir(dir, p) / "host-error.txt");
}

namespace {
/// Folder -> the descriptor of its lock, kept until the process ends.
std::map<std::string, int>& held_folder_locks() {
  static std::map<std::string, int> held;
  return held;
}

/// The names in a study folder that hold its results (--force removes them;
/// nothing else in the folder is touched).
const char* const kResultNames[] = {"results.db", "results.db-wal", "results.db-shm", "results.db-journal",
                                    "study.toml", "points",         "refs",           "traces",
                                    "livepoints", "report",         "slurm"};
}  // namespace

void close_inherited_folder_locks() {
  for (const auto& [dir, fd] : held_folder_locks()) ::close(fd);
  held_folder_locks().clear();
}

void hold_study_folder(const std::string& dir) {
  std::map<std::string, int>& held = held_folder_locks();
  const std::string key = fs::weakly_canonical(dir).string();
  if (held.count(key)) return;
  const std::string path = (fs::path(dir) / ".lock").string();
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd < 0) throw UserError(path + ": cannot open the study folder's lock: " + std::strerror(errno));
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    ::close(fd);
    if (e == EWOULDBLOCK)
      throw UserError(dir +
                      ": another ropsim is running or collecting a study in this folder; wait for it to "
                      "finish, or use another --out");
    throw UserError(path + ": cannot lock the study folder: " + std::strerror(e));
  }
  held[key] = fd;
}

void remove_study_results(const std::string& dir) {
  std::string tmpl = (fs::path(dir) / ".replaced-XXXXXX").string();
  if (!::mkdtemp(tmpl.data()))
    throw SystemError(dir + ": cannot replace the study's results: " + std::strerror(errno), errno);
  const fs::path trash = tmpl;
  for (const char* name : kResultNames) {
    std::error_code ec;
    const fs::path from = fs::path(dir) / name;
    if (!fs::exists(fs::symlink_status(from, ec))) continue;
    fs::rename(from, trash / name, ec);
    if (ec) throw UserError(from.string() + ": cannot remove the study's results: " + ec.message());
  }
  std::vector<fs::path> replaced;  // this removal's and any an interrupted one left
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string().rfind(".replaced-", 0) == 0 && e.is_directory() && !e.is_symlink())
      replaced.push_back(e.path());
  for (const auto& r : replaced) {
    std::error_code ec;
    fs::remove_all(r, ec);
    if (ec) throw UserError(r.string() + ": cannot remove the study's former results: " + ec.message());
  }
}

}  // namespace ropsim
