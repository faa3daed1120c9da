// A study folder's layout and its lock. DIR/points/<hash>/ holds a point's
// params.json, report.json (its presence means done), image, log and error;
// DIR/traces/<key>.rtr and DIR/refs/<key>.exr the captures and references
// the points share, each beside its recorded error; DIR/.lock is held by the
// one `study run` or `study collect` that writes the folder.
#pragma once
#include <filesystem>
#include <string>

#include "sim/study/study.h"

namespace ropsim {

/// The folder of point p: DIR/points/<hash>.
std::filesystem::path point_dir(const std::string& dir, const StudyPoint& p);
/// The reference named key: DIR/refs/<key>.exr (its PNG beside it).
std::filesystem::path ref_path(const std::string& dir, const std::string& key);
/// The capture named key: DIR/traces/<key>.rtr.
std::filesystem::path capture_path(const std::string& dir, const std::string& key);
/// Where a failed capture or reference records its error, by its key: the
/// points that need it (run by this process or by another executor's task)
/// record the same error as theirs.
std::filesystem::path capture_error_path(const std::string& dir, const std::string& key);
std::filesystem::path ref_error_path(const std::string& dir, const std::string& key);
/// A task whose host failed records its error here instead (host-error.txt
/// in a point's folder, <key>.host-error beside a capture or reference): it
/// is not the task's verdict, and a plain rerun runs it again.
std::filesystem::path host_error_path(const std::filesystem::path& error_path);

/// A file's whole contents ("" when it cannot be read).
std::string read_whole_file(const std::filesystem::path& p);
/// A recorded error (a task's error file), without its newline.
std::string recorded_error(const std::filesystem::path& f);
/// Removes a point's recorded errors before it runs again.
void clear_point_errors(const std::string& dir, const StudyPoint& p);

/// Takes the study folder's lock (DIR/.lock, flock) for the rest of the
/// process: one `study run` or `study collect` writes a folder at a time (the
/// per-point tasks of a cluster run do not take it). Another holder is a
/// UserError naming the folder. Idempotent within a process.
void hold_study_folder(const std::string& dir);
/// In a forked worker: closes the inherited lock descriptors (close only: an
/// unlock would release the parent's lock, which shares them), so that a
/// worker outliving a killed parent does not keep the folder locked.
void close_inherited_folder_locks();

/// Removes a study folder's results (its lock held): each is first renamed
/// into DIR/.replaced-XXXXXX, the database first, then that folder is
/// removed, so that an interrupted removal leaves no old result beside the
/// new ones under the names the study reads. A .replaced- folder an
/// interrupted removal left is removed too. Nothing else in the folder is
/// touched.
void remove_study_results(const std::string& dir);

}  // namespace ropsim
