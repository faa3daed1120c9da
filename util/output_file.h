// One discipline for every file ropsim writes (images, reports, traces, VCD,
// vectors, dumps); docs/outputs.md.
//
//  - A regular target (or a new name) is written to a unique temporary file in
//    the target's folder (.NAME.XXXXXX) and renamed onto the target only after
//    every write, the flush, fsync and the close succeeded. Readers never see a
//    partial file under the final name; concurrent writers never share a
//    temporary file.
//  - A symlink is resolved (the whole chain): the link's target is replaced and
//    the link is kept.
//  - A target that exists and is not a regular file (a character device, a
//    FIFO) is opened O_WRONLY and written in place; it stays what it was. A
//    FIFO is opened without blocking, retried until a reader opens it or
//    --output-timeout passes (set_output_timeout), saying once on stderr that
//    it waits.
//  - SIGPIPE is ignored (install_output_signal_handling): a reader that
//    closes a FIFO or pipe early is the error "PATH: the reader closed it";
//    standard output closed early ends the process quietly, as by SIGPIPE.
//  - "-" is standard output, where the caller allows it (a single text output).
//  - Any failure (ENOSPC, EFBIG under `ulimit -f`, EIO...) throws UserError
//    "PATH: <strerror>" (a SystemError with the errno, errors.h); the temporary file is removed and nothing appears
//    under the final name. An OutputFile destroyed without commit() discards.
//  - Targets this process created (the name did not exist) are remembered, so
//    a failing run can remove them with remove_created_outputs(); a
//    pre-existing file and a concurrent run's file are never removed.
//
// Bottom layer: POSIX and the standard library only.
#pragma once
#include <sys/types.h>

#include <cstdio>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "util/output_plan.h"

namespace ropsim {

class OutputFile {
 public:
  struct Options {
    /// "-" means standard output (only where one text output is asked for).
    bool allow_stdout = false;
    /// A library writes the file by name (write_name()); there is no stream.
    bool named = false;
    /// named: write_name() is a FIFO whose bytes a thread copies to the
    /// target with every write checked (for libraries that ignore write
    /// errors and write sequentially, e.g. SystemC's VCD writer).
    bool via_pipe = false;
    /// named: write_name() ends with this (e.g. ".vcd").
    std::string suffix;
  };

  explicit OutputFile(std::string path);
  OutputFile(std::string path, Options opt);
  ~OutputFile();  ///< discard() unless committed
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  /// The path as the user gave it (what error messages name).
  const std::string& path() const { return path_; }
  /// The stream to write (stream mode): a temporary file, the target itself
  /// (in place), or stdout.
  FILE* stream();
  /// Writes n bytes to stream(); throws UserError "PATH: <strerror>".
  void write(const void* data, size_t n);
  void write(std::string_view s) { write(s.data(), s.size()); }
  /// named mode: the file name the library must write.
  const std::string& write_name() const { return write_name_; }
  /// Throws UserError "PATH: <what>", discarding the output.
  [[noreturn]] void fail(const std::string& what);

  /// The stream is a temporary file, so patch() can rewrite what was
  /// written (not stdout, an in-place target such as a FIFO or a device, or
  /// a by-name output).
  bool can_patch() const { return mode_ == Mode::kReplace && f_ && !opt_.named; }
  /// Overwrites n bytes at offset of what was written so far when
  /// can_patch(); otherwise returns false, writing nothing. Throws UserError
  /// on a write error.
  bool patch(uint64_t offset, const void* data, size_t n);
  /// Finishes the output: flush, fsync, close, all checked; then rename onto
  /// the target (or copy into an in-place target). Throws UserError.
  void commit();
  /// Removes the temporary file (or closes an in-place target). No-throw.
  void discard() noexcept;

  bool committed() const { return committed_; }
  bool to_stdout() const { return mode_ == Mode::kStdout; }
  bool in_place() const { return mode_ == Mode::kInPlace; }

 private:
  enum class Mode { kStdout, kInPlace, kReplace };
  struct Pipe;
  [[noreturn]] void fail_errno(int err);
  /// Opens the in-place target for writing (a FIFO: without blocking, waiting
  /// for its reader up to --output-timeout). Throws UserError.
  int open_in_place();
  void commit_stream();
  void commit_named();
  void rename_onto_target(int fd_for_mode);

  std::string path_;    ///< as given
  std::string target_;  ///< the resolved target (symlinks followed)
  std::string temp_;    ///< the temporary file ("" in place / stdout)
  std::string write_name_;
  Options opt_;
  Mode mode_ = Mode::kReplace;
  FILE* f_ = nullptr;
  int target_mode_ = -1;  ///< permission bits of a replaced file, -1 when new
  bool existed_ = false;
  bool committed_ = false;
  std::unique_ptr<Pipe> pipe_;
};

/// Writes text to path through an OutputFile (allow_stdout: "-" is stdout).
void write_text_output(const std::string& path, std::string_view text, bool allow_stdout = false);

/// Creates the folders leading to path ("-" and bare names: nothing); throws
/// UserError "PATH: cannot create the folder DIR: <reason>". The folders it
/// creates are remembered with the created targets: remove_created_outputs()
/// removes them again when they are empty.
void ensure_parent_dir(const std::string& path);

/// Removes every target this process created through OutputFile::commit that
/// is still the file it wrote (same device and inode), then the folders
/// ensure_parent_dir created that are empty, deepest first. Returns how many
/// files it removed.
int remove_created_outputs() noexcept;
/// Forgets the created targets and folders (after a run succeeded).
void forget_created_outputs() noexcept;

/// Process setup for a CLI: ignore SIGXFSZ (a write beyond RLIMIT_FSIZE then
/// fails with EFBIG instead of killing the process) and SIGPIPE (a closed
/// reader is then EPIPE, reported by the writer), and remove the pending
/// temporary files on SIGINT, SIGTERM and SIGHUP before dying of the signal.
void install_output_signal_handling();

/// How long opening a FIFO target waits for its reader (--output-timeout),
/// in seconds: negative waits forever (the default), 0 not at all.
void set_output_timeout(double seconds);

/// Flushes standard output and checks that everything written to it arrived
/// (once, at the end of a command). A write error (ENOSPC, EIO...) throws
/// UserError "standard output: <reason>"; a reader that closed it (EPIPE)
/// ends the process quietly, as SIGPIPE would, after removing the pending
/// temporary files.
void finish_standard_output();
/// A write to standard output failed with err (e.g. fmt::print's
/// std::system_error): EPIPE ends the process quietly, as above; anything
/// else throws UserError "standard output: <reason>".
[[noreturn]] void standard_output_failed(int err);

/// The process's file mode creation mask (read without changing it where
/// /proc tells; else umask() twice).
mode_t current_umask();

}  // namespace ropsim
