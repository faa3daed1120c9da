// Running a study on this machine: a work graph of reference renders, then
// points, on N worker processes (SystemC allows one simulation context per
// process; each worker runs many tasks, so start-up is paid once per worker).
// Results go to DIR/results.db (SQLite, one row per point) and to a folder per
// point; a run that was killed runs only what is missing when started again.
// This file plans and schedules; study_tasks.h runs one task, study_db.h
// records the results, study_folder.h is the folder's layout and lock.
#pragma once
#include <string>
#include <utility>
#include <vector>

#include "sim/study/study.h"
#include "sim/study/study_db.h"
#include "sim/study/study_folder.h"
#include "sim/study/study_tasks.h"

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

struct StudyPointFailure {
  std::string point;  ///< its hash and parameters (describe_point)
  std::string error;  ///< one line (failure_status)
  StudyFailure kind = StudyFailure::kInput;
  int status = 1;  ///< its exit status (failure_status): 1 user error, 2 broken invariant
};

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
/// Creates the folder and takes its lock (hold_study_folder), checks that the
/// folder holds this study (o.use: else UserError naming the folder and the
/// study it holds), records in the database every point whose folder holds
/// its result or its error (a killed run's, or another executor's tasks'),
/// and returns what is left: the points not run yet, those whose host failed,
/// and with o.retry_failed those with an input error. `sum` gets the points
/// recorded.
StudyPlan plan_study(const Study& s, const StudyRunOptions& o, StudySummary& sum);

/// Runs the points of s that the folder does not hold yet. A point that fails
/// records its error and the others go on. Throws UserError when the folder
/// cannot be used.
StudySummary run_study(const Study& s, const StudyRunOptions& o);

}  // namespace ropsim
