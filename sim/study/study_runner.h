// Running a study on this machine: a work graph of reference renders, then
// points, on N worker processes (SystemC allows one simulation context per
// process; each worker runs many tasks, so start-up is paid once per worker).
// Results go to DIR/results.db (SQLite, one row per point) and to a folder per
// point; a run that was killed runs only what is missing when started again.
#pragma once
#include <string>
#include <utility>
#include <vector>

#include "study.h"

namespace ropsim {

struct StudyRunOptions {
  std::string out_dir;        ///< the study folder: results.db, points/, refs/
  unsigned jobs = 1;          ///< worker processes
  bool retry_failed = false;  ///< run again the points whose error is recorded
  bool progress = true;       ///< a progress line on stderr
};

struct StudySummary {
  size_t points = 0;                                          ///< in the study
  size_t reused = 0;                                          ///< already in the folder: not run again
  size_t ran = 0;                                             ///< run now and succeeded
  size_t failed = 0;                                          ///< with a recorded error (now or before)
  std::vector<std::pair<std::string, std::string>> failures;  ///< (point hash and parameters, error)
};

/// A point as the summaries list it: its hash, input and parameters.
std::string describe_point(const StudyPoint& p);

/// What a study folder still needs, as point indices: the captures and the
/// references to make (each named by its first point), then the points to run.
struct StudyPlan {
  std::vector<size_t> captures, references, points;
};
/// Creates the folder, records in the database every point whose folder holds
/// its result or its error (a killed run's, or another executor's tasks'), and
/// returns what is left. `sum` gets the points recorded.
StudyPlan plan_study(const Study& s, const StudyRunOptions& o, StudySummary& sum);

/// Runs one task in this process: 'c' the capture, 'r' the reference or 'p'
/// the point named by point_index. Returns false when it failed (its error
/// written to the task's error file); throws UserError for a bad index or kind.
bool run_study_task(const Study& s, char kind, size_t point_index, const std::string& dir);

/// Runs the points of s that the folder does not hold yet. A point that fails
/// records its error and the others go on. Throws UserError when the folder
/// cannot be used.
StudySummary run_study(const Study& s, const StudyRunOptions& o);

/// The study file a study folder was made from (its database records it).
std::string study_file_of(const std::string& dir);

/// Writes the results table of a study folder as CSV: one row per point, one
/// column per parameter and metric (the report JSON left out). Throws UserError.
void export_study_csv(const std::string& dir, const std::string& csv_path);

}  // namespace ropsim
