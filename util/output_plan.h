// Where a path leads, and the check that one command's outputs are distinct
// files and replace none of its inputs (docs/outputs.md "Distinct
// outputs"). Bottom layer: POSIX and the standard library only.
#pragma once
#include <sys/types.h>

#include <string>
#include <vector>

namespace ropsim {

/// The folder of a path as written: "." for a bare name, "/" for an entry
/// of the root.
std::string folder_of(const std::string& p);

/// Where a path leads: symlinks followed (the last component's chain, then
/// every folder), made absolute and normal; the device and inode when it
/// exists.
struct FileIdentity {
  std::string path;  ///< absolute, no symlink, no "." or ".."
  bool exists = false;
  bool char_device = false;
  dev_t dev = 0;
  ino_t ino = 0;
};
FileIdentity file_identity(const std::string& path);
/// One file: the same device and inode when both exist, else the same path.
bool same_file(const FileIdentity& a, const FileIdentity& b);

/// The files one command writes and reads, checked before any work is done
/// (docs/outputs.md "Distinct outputs"): two outputs that are one file (the
/// same name, a symlink to it, a hard link of it, or an implied file such as
/// a waveform's GTKWave save file or a --maps folder's images), or an output
/// that is one of the command's inputs, are refused with one line naming both
/// flags and the path. A character device (/dev/null) may take several.
class OutputPlan {
 public:
  /// An output; `what` names it for the user: a flag ("--report") or an
  /// implied file ("--vcd's GTKWave save file"). "" (not given) and "-"
  /// (standard output) are skipped.
  void output(std::string what, std::string path);
  /// An input the outputs must not replace ("--trace").
  void input(std::string what, std::string path);
  /// Throws UserError "A and B both name PATH: ..." for the first clash.
  void check() const;

 private:
  struct Entry {
    std::string what, path;
    bool input;
  };
  std::vector<Entry> entries_;
};

/// Resolves a symlink chain (relative links against their folder). Returns
/// the first path that is not a symlink (it may not exist). Throws UserError
/// on a loop (ELOOP).
std::string resolve_symlinks(const std::string& path);

}  // namespace ropsim
