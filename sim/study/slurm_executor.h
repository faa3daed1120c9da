// Running a study on a SLURM cluster (docs/studies.md, "On a cluster"): the
// study is planned here (plan_study), then each non-empty phase -- captures,
// references, points -- is one job array whose tasks run `ropsim study task`,
// each phase depending (afterok) on the one before. The study folder, on a
// file system the nodes share, is the meeting point; `study collect` (or
// --wait) records the results in its database.
#pragma once
#include <string>
#include <vector>

#include "sim/study/study.h"
#include "sim/study/study_runner.h"

namespace ropsim {

/// The sbatch options: the study file's [slurm] section, then the command
/// line's --slurm-* options over it.
struct SlurmOptions {
  StudySlurm sbatch;
  bool wait = false;        ///< wait for the jobs to end, then collect
  unsigned poll_ms = 1000;  ///< how often --wait asks squeue
};

struct SlurmSubmission {
  StudyPlan plan;                    ///< what was submitted (point indices)
  std::vector<std::string> job_ids;  ///< one per non-empty phase, in order
  std::vector<char> kinds;           ///< the phase of each job: 'c', 'r' or 'p'
  std::vector<std::string> after;    ///< the job each one depends on (afterok), "" for none
};

/// Plans the study and submits what the folder lacks. Writes DIR/slurm/:
/// <phase>.txt (the indices, one a line), <phase>.sbatch, jobs.txt (the job ids
/// of this submission), and the tasks' logs <job>_<task>.log. Throws UserError
/// when sbatch fails or when jobs of an earlier submission are still queued.
SlurmSubmission submit_study_slurm(const Study& s, const StudyRunOptions& o, const SlurmOptions& so, StudySummary& sum);

/// Waits until none of the jobs is queued or running (squeue). Throws
/// UserError when squeue keeps failing (the controller is gone).
void wait_slurm_jobs(const std::vector<std::string>& job_ids, unsigned poll_ms);

}  // namespace ropsim
