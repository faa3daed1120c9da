#include "util/output_plan.h"

#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <cstring>
#include <filesystem>
#include <system_error>

#include "util/errors.h"

namespace ropsim {

std::string folder_of(const std::string& p) {
  const auto slash = p.find_last_of('/');
  if (slash == std::string::npos) return ".";
  if (slash == 0) return "/";
  return p.substr(0, slash);
}

FileIdentity file_identity(const std::string& path) {
  namespace fs = std::filesystem;
  FileIdentity id;
  std::error_code ec;
  fs::path p = fs::absolute(resolve_symlinks(path), ec);
  if (ec) p = resolve_symlinks(path);
  // The folders' symlinks resolved where they exist, the rest made normal.
  const fs::path c = fs::weakly_canonical(p, ec);
  id.path = (ec ? p.lexically_normal() : c).string();
  struct stat st;
  if (::stat(id.path.c_str(), &st) == 0) {
    id.exists = true;
    id.char_device = S_ISCHR(st.st_mode);
    id.dev = st.st_dev;
    id.ino = st.st_ino;
  }
  return id;
}

bool same_file(const FileIdentity& a, const FileIdentity& b) {
  if (a.exists && b.exists) return a.dev == b.dev && a.ino == b.ino;
  return a.path == b.path;
}

void OutputPlan::output(std::string what, std::string path) {
  if (path.empty() || path == "-") return;
  entries_.push_back(Entry{std::move(what), std::move(path), false});
}

void OutputPlan::input(std::string what, std::string path) {
  if (path.empty() || path == "-") return;
  entries_.push_back(Entry{std::move(what), std::move(path), true});
}

void OutputPlan::check() const {
  std::vector<FileIdentity> ids;
  ids.reserve(entries_.size());
  for (const auto& e : entries_) ids.push_back(file_identity(e.path));
  for (size_t j = 0; j < entries_.size(); ++j)
    for (size_t i = 0; i < j; ++i) {
      const Entry &a = entries_[i], &b = entries_[j];
      if (a.input && b.input) continue;
      if (!same_file(ids[i], ids[j]) || ids[i].char_device) continue;
      const Entry& out = a.input ? b : a;  // the first output named, then the other
      const Entry& other = a.input ? a : b;
      const std::string other_what = other.input ? "the input " + other.what : other.what;
      std::string msg = out.path == other.path
                            ? out.what + " and " + other_what + " both name " + out.path
                            : out.what + " " + out.path + " and " + other_what + " " + other.path + " are one file";
      msg += other.input ? ": an output must not replace an input" : ": give each output a file of its own";
      throw UserError(msg);
    }
}

std::string resolve_symlinks(const std::string& path) {
  std::string p = path;
  for (int hops = 0; hops < 40; ++hops) {
    struct stat st;
    if (::lstat(p.c_str(), &st) != 0 || !S_ISLNK(st.st_mode)) return p;
    std::vector<char> buf(PATH_MAX + 1);
    const ssize_t n = ::readlink(p.c_str(), buf.data(), buf.size() - 1);
    if (n < 0) return p;
    std::string link(buf.data(), size_t(n));
    p = (!link.empty() && link[0] == '/') ? link : folder_of(p) + "/" + link;
  }
  throw UserError(path + ": " + std::strerror(ELOOP));
}

}  // namespace ropsim
