// Submitting a batch: Slurm job arrays through the sbatch command line (one, or one per MaxArraySize tasks), or
// local worker processes.
#pragma once

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "batch/task.h"

namespace rangebayes {

struct BatchSubmitOptions {
  std::string partition;                // sbatch --partition; empty: the cluster's default
  int max_parallel = 0;                 // array throttle (--array=...%N); 0: no limit; 1-100000
  std::vector<std::string> slurm_args;  // passed to sbatch as they are (e.g. --time=1:00:00, --cpus-per-task=4)
  int local_workers = 0;                // > 0: run here with this many worker processes instead of Slurm
  // Resubmit only: take the tasks whose status says running too (a --local run on a host that died, which cannot
  // be checked from here). Still refused while squeue lists a job of the batch or such a task's run-task runs on
  // this host.
  bool include_running = false;
  // > 0: each task's time limit (s; CheckTaskTimeout), on either path: run-task stops the command (SIGTERM to its
  // process group, SIGKILL kTaskTimeoutGraceS later) and records "timeout". On Slurm it also sets sbatch's --time
  // (SlurmTimeMinutes), so it cannot be given with a --time in slurm_args.
  double task_timeout_s = 0;
  std::string binary;                   // rangebayes binary the tasks run (absolute); empty: this executable
  std::string sbatch = "sbatch";        // sbatch program (a name on PATH or a path)
  std::string squeue = "squeue";        // squeue program, for resubmit's check that nothing is still queued
  std::string scontrol = "scontrol";    // scontrol program, for the cluster's MaxArraySize before sbatch
  std::string scancel = "scancel";      // scancel program, for CancelBatch
  // When not empty: the subcommands a task line may start with (the binary's own), checked for every line before
  // anything is written or submitted.
  std::vector<std::string> subcommands;
  // When set: parses a task line's words (its inputs resolved as run-task resolves them) as the binary does, and
  // throws Error with the parser's message (an unknown option, a bad value, a missing argument). Submit and
  // resubmit call it for every line before anything is written or submitted, naming the manifest line.
  std::function<void(const std::vector<std::string>& arguments)> check_line;
  // Where each subcommand names its outputs: every line's outputs are checked (CheckTaskOutputs) before anything
  // is written or submitted, and the local workers' run-task takes the binary's own.
  SubcommandSyntaxes syntaxes;
  // Called (in the submitting process) when a local task has ended.
  std::function<void(const BatchTaskStatus&)> on_task_end;
  void Check() const;
};

struct BatchSubmitSummary {
  std::string dir;
  std::vector<int> indices;                  // the tasks submitted
  std::vector<BatchSubmission> submissions;  // as recorded in DIR/batch.json: one per Slurm job array, or one local
  std::string job_script;                    // Slurm: the script sbatch ran
  std::optional<int> max_array_size;         // Slurm: the cluster's MaxArraySize, when scontrol told it
  // One line: "submitted 6 tasks as Slurm job 12 (array 0-5) in DIR", "submitted 250 tasks as 3 Slurm jobs
  // (MaxArraySize 100): 12 (tasks 0-99), ... in DIR" or "ran 6 tasks on 2 local workers in DIR".
  std::string BriefReport() const;
  // The Slurm job ids, space-separated ("12 13 14"); empty for a local run.
  std::string JobIds() const;
};

// Creates DIR (it must not hold a batch yet, unless its only submit was refused), copies the manifest into it and
// submits every task. With local_workers > 0 it returns when every task has ended (see BatchReport for the
// outcome); otherwise it returns after sbatch accepted the arrays: one, or, when a task index is not below the
// cluster's MaxArraySize (scontrol show config), one per MaxArraySize task indices (SplitArrayJobs), each recorded
// in DIR/batch.json as a submission of its own (with --max-parallel, each after the one before:
// --dependency=afterany, so that at most N tasks run at once in all). Holds an exclusive lock on DIR/batch.lock
// meanwhile, so another submit or resubmit of DIR is refused (naming this process) while tasks run here or sbatch
// is called. Throws, before anything is written, on a line that options.check_line refuses or whose output is
// absolute or leaves its task's folder (CheckTaskOutputs); throws with sbatch's own error line when sbatch is
// missing or refuses a job (after recording the jobs it accepted before, which the message names).
BatchSubmitSummary SubmitBatch(const std::string& manifest_path, const std::string& dir,
                               const BatchSubmitOptions& options);

// Submits exactly the missing, partial, changed, failed and interrupted tasks of DIR again (a new array, or local
// workers; interrupted: marked running, but their run-task process on this host is gone, RunTaskIsGone); when the batch
// has Slurm jobs and squeue lists none of them any more, also the tasks whose status still says running (killed
// on another node before they could record their end). Throws when none is left, or when squeue lists a job of
// this batch still queued or running, when another submit or resubmit of DIR holds its lock, and when the
// manifest has another number of tasks than was submitted (CollectBatchReport). With include_running, the tasks
// that still read running are taken too, unless one's run-task runs on this host (then it throws, naming it).
BatchSubmitSummary ResubmitBatch(const std::string& dir, const BatchSubmitOptions& options);

// Cancels (scancel) every Slurm job of the batch in DIR that squeue still lists (queued or running), and returns
// their ids. Throws when DIR is not a batch, when squeue cannot be run, when it lists no job of the batch, and with
// scancel's own error line when scancel fails.
std::vector<std::string> CancelBatch(const std::string& dir, const BatchSubmitOptions& options);

// Runs the given tasks of DIR with `workers` processes of `binary batch run-task DIR I` and returns when all
// have ended; their own output goes to DIR/local/run-task.out.
void RunBatchLocally(const BatchLayout& layout, const std::vector<int>& indices, const BatchSubmitOptions& options);

// sbatch's --time in minutes for a task limit of `task_timeout_s`: Slurm counts whole minutes, and run-task needs the
// grace after SIGTERM and a minute to start and record, so that run-task, not Slurm, stops the task:
// ceil((task_timeout_s + kTaskTimeoutGraceS) / 60) + 1.
long SlurmTimeMinutes(double task_timeout_s);

// sbatch's --array value: ascending indices as ranges ("0-5", "1,3,7-9"), with "%N" when max_parallel > 0.
std::string ArraySpec(const std::vector<int>& indices, int max_parallel);

// One Slurm job array of a submission.
struct ArrayJob {
  int offset = 0;            // task index = offset + SLURM_ARRAY_TASK_ID (the job script's argument)
  std::vector<int> indices;  // task indices, ascending
  std::string after_job;     // not empty: sbatch --dependency=afterany:after_job
};

// The job arrays for task `indices`: one, with offset 0 (array index = task index), when every index is below
// `max_array_size` or that is not known; else one per block of max_array_size task indices that holds any
// (offset k * max_array_size), so that every array index is below MaxArraySize.
std::vector<ArrayJob> SplitArrayJobs(const std::vector<int>& indices, std::optional<int> max_array_size);

// The sbatch command line for `job` of the batch: options, the job script, then the offset when it is not 0.
std::vector<std::string> SbatchCommand(const BatchLayout& layout, const ArrayJob& job,
                                       const BatchSubmitOptions& options, const std::string& job_script);

// MaxArraySize in `scontrol show config` output ("MaxArraySize            = 1001"); nullopt when it is not there.
std::optional<int> ParseMaxArraySize(const std::string& output);

// The job id in sbatch --parsable output ("12" or "12;cluster"); throws when there is none.
std::string ParseSbatchJobId(const std::string& output);

}  // namespace rangebayes
