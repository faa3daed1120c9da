// Running a study on this machine: a work graph of reference renders, then
// points, on N worker processes (SystemC allows one simulation context per
// process; each worker runs many tasks, so start-up is paid once per worker).
// Results go to DIR/results.db (SQLite, one row per point) and to a folder per
// point; a run that was killed runs only what is missing when started again.
#pragma once
#include <string>
#include <utility>
#include <vector>

#include "sim/study/study.h"

namespace ropsim {

/// What a folder that holds another study's results (or this study's with
/// other points) gets (docs/studies.md "One study a folder").
enum class StudyFolderUse {
  kSameStudy,  ///< refused: the folder holds another study
  kReplace,    ///< --force: its results (whatever study they are of) are removed, then the study runs
  kExtend,     ///< --extend: its points are kept (they must be points of the study), the new ones run
};

struct StudyRunOptions {
  std::string out_dir;        ///< the study folder: results.db, points/, refs/
  unsigned jobs = 1;          ///< worker processes
  bool retry_failed = false;  ///< run again the points whose input error is recorded (host failures always are)
  StudyFolderUse use = StudyFolderUse::kSameStudy;
  bool progress = true;  ///< a progress line on stderr
};

/// Why a point failed. A host failure (a full disk, an I/O error, no memory,
/// a worker killed, a SLURM task that ended without a result) says nothing of
/// the point: a plain rerun runs it again. An input failure (a bad input or
/// design, a broken invariant) would fail again: only --retry-failed reruns it.
enum class StudyFailure { kInput, kHost };
const char* to_string(StudyFailure f);  ///< "input", "host": the database's `failure` column

struct StudyPointFailure {
  std::string point;  ///< its hash and parameters (describe_point)
  std::string error;  ///< one line (failure_status)
  StudyFailure kind = StudyFailure::kInput;
  int status = 1;  ///< its exit status (failure_status): 1 user error, 2 broken invariant
};

/// A task's error is classified by the rule main applies (util/errors.h) and
/// recorded (error files, the database, a worker's reply) on one line: a user
/// error's text, or a broken invariant's as main prints it, "internal error:
/// <what>: please report it". The exit status a recorded error stands for: 2
/// for a broken invariant, else 1.
int failure_status(const std::string& error);
/// What a broken invariant's recorded error names: "<what>" of "internal
/// error: <what>: please report it" (any other error as it is).
std::string broken_invariant(const std::string& error);

struct StudySummary {
  size_t points = 0;       ///< in the study
  size_t reused = 0;       ///< already in the folder: not run again
  size_t ran = 0;          ///< run now and succeeded
  size_t failed = 0;       ///< with a recorded error (now or before)
  size_t failed_host = 0;  ///< of failed: host failures
  std::vector<StudyPointFailure> failures;
};

/// The exit status of a study run (or collect) whose summary this is: 0 when
/// no point failed and none is left to run, else the highest status of its
/// failures (1, or 2 when a point broke an invariant).
int study_exit_status(const StudySummary& sum, size_t not_run = 0);

/// "1 point", "2 points".
std::string count_of(size_t n, const char* noun);

/// The failures of a summary in words: "2 failed (input errors; --retry-failed
/// reruns them)", or "0 failed".
std::string describe_failures(const StudySummary& sum);

/// A point as the summaries list it: its hash, input and parameters.
std::string describe_point(const StudyPoint& p);

/// What a study folder still needs, as point indices: the captures and the
/// references to make (each named by its first point), then the points to run.
struct StudyPlan {
  std::vector<size_t> captures, references, points;
};
/// Takes the study folder's lock (DIR/.lock, flock) for the rest of the
/// process: one `study run` or `study collect` writes a folder at a time (the
/// per-point tasks of a cluster run do not take it). Another holder is a
/// UserError naming the folder. Idempotent within a process.
void hold_study_folder(const std::string& dir);

/// Creates the folder and takes its lock (hold_study_folder), checks that the
/// folder holds this study (o.use: else UserError naming the folder and the
/// study it holds), records in the database every point whose folder holds
/// its result or its error (a killed run's, or another executor's tasks'),
/// and returns what is left: the points not run yet, those whose host failed,
/// and with o.retry_failed those with an input error. `sum` gets the points
/// recorded.
StudyPlan plan_study(const Study& s, const StudyRunOptions& o, StudySummary& sum);

/// How a task ended.
struct StudyTaskResult {
  bool ok = false;
  StudyFailure failure = StudyFailure::kInput;  ///< when not ok
  std::string error;                            ///< when not ok: one line (failure_status)
  /// Whether the error is in the task's error file (a full disk may keep it out).
  bool recorded = false;
};

/// Runs one task in this process: 'c' the capture, 'r' the reference or 'p'
/// the point named by point_index. A failure's error is written to the
/// task's error file (an input error to error.txt, refs/<key>.error or
/// traces/<key>.error; a host failure to host-error.txt, <key>.host-error).
/// Throws UserError for a bad index or kind.
StudyTaskResult run_study_task(const Study& s, char kind, size_t point_index, const std::string& dir);

/// Runs the points of s that the folder does not hold yet. A point that fails
/// records its error and the others go on. Throws UserError when the folder
/// cannot be used.
StudySummary run_study(const Study& s, const StudyRunOptions& o);

/// The study file a study folder was made from (its database records it).
std::string study_file_of(const std::string& dir);

/// What an export wrote.
struct StudyExport {
  std::string study;  ///< the study's name, as its database records it
  size_t rows = 0, ok = 0, failed = 0, columns = 0;
};

/// Writes the results table of a study folder as CSV: one row per point, one
/// column per parameter and metric (the report JSON left out). Opens the
/// database read-only, so a finished study on read-only media exports.
/// Throws UserError.
StudyExport export_study_csv(const std::string& dir, const std::string& csv_path);

}  // namespace ropsim
