// A study's tasks and how they fail: capturing an input, rendering a
// reference, running a point (its report and folder), each in the process
// that calls it or in a study worker (the one-line task protocol). A task's
// failure is an input failure or a host failure (StudyFailure), recorded in
// the task's error file (study_folder.h) on one line.
#pragma once
#include <exception>
#include <string>
#include <utility>
#include <vector>

#include "sim/study/study.h"
#include "util/errors.h"

namespace ropsim {

/// Why a point failed. A host failure (a full disk, an I/O error, no memory,
/// a worker killed, a SLURM task that ended without a result) says nothing of
/// the point: a plain rerun runs it again. An input failure (a bad input or
/// design, a broken invariant) would fail again: only --retry-failed reruns it.
enum class StudyFailure { kInput, kHost };
const char* to_string(StudyFailure f);  ///< "input", "host": the database's `failure` column

/// A task's error is classified by the rule main applies (util/errors.h) and
/// recorded (error files, the database, a worker's reply) on one line: a user
/// error's text, or a broken invariant's as main prints it, "internal error:
/// <what>: please report it". The exit status a recorded error stands for: 2
/// for a broken invariant, else 1.
int failure_status(const std::string& error);
/// What a broken invariant's recorded error names: "<what>" of "internal
/// error: <what>: please report it" (any other error as it is).
std::string broken_invariant(const std::string& error);

/// A task's failure: its kind, and its error on one line as a study records
/// it (recorded_form). Its exit status is the one rule's (util/errors.h);
/// whether its host failed is the study's own question (a plain rerun
/// retries it).
std::pair<StudyFailure, std::string> failure_of(const std::exception_ptr& e);
/// A classified error as a study records it: a user error's text, or a
/// broken invariant's message (failure_status).
std::string recorded_form(const ErrorVerdict& v);

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

/// A task in a worker process: "c N", "r N" or "p N" (a capture, a
/// reference, a point of `points`, the expansion of s); answers "ok" or
/// "fail KIND ERROR" (KIND: host or input; the error on one line), the error
/// also in the task's error file.
std::string serve_study_task(const Study& s, const std::vector<StudyPoint>& points, const std::string& dir,
                             const std::string& task);
/// A worker's reply (serve_study_task) as the task's result.
StudyTaskResult parse_task_reply(const std::string& line);

}  // namespace ropsim
