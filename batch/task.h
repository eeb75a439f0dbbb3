// A batch folder on disk, the per-task status files, and running one task with atomic publishing.
//
// Layout of a batch folder DIR (README, "Batch processing on a Slurm cluster"):
//   DIR/manifest.txt        the manifest, copied at submission
//   DIR/batch.json          the manifest's folder, the binary, and every submission (sbatch command, job id)
//   DIR/batch.lock          locked (flock) by the submit or resubmit that runs tasks here (--local) or calls sbatch
//   DIR/tasks/<index>/      the outputs of task <index>, present only when it succeeded (or partly succeeded)
//   DIR/tasks/.tmp-<index>-<attempt>-<pid>/   where a task runs; renamed to tasks/<index>/ on success
//   DIR/status/<index>.json the task's status (BatchTaskStatus), replaced atomically
//   DIR/logs/<index>.log    the task command's stdout and stderr, appended by every run
//   DIR/slurm/              job script and Slurm's output files (<job>_<array index>.out, opened for append; the
//                           array index is the task index less the job's array_offset, 0 unless a batch above
//                           MaxArraySize was split)
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "batch/manifest.h"

namespace rangebayes {

// Paths inside a batch folder; `dir` is absolute.
struct BatchLayout {
  std::string dir;
  explicit BatchLayout(const std::string& folder);  // makes `folder` absolute
  std::string manifest() const;
  std::string record() const;
  std::string tasks_dir() const;
  std::string task_dir(int index) const;
  std::string status_file(int index) const;
  std::string log_file(int index) const;
  std::string slurm_dir() const;
};

// One submission of (some of) a batch's tasks.
struct BatchSubmission {
  std::string kind;          // "slurm" or "local"
  std::string time_utc;      // ISO 8601
  std::vector<int> indices;  // the task indices it ran
  std::string job_id;        // Slurm array job id (kind slurm)
  int array_offset = 0;      // task index = array_offset + array index (kind slurm; ArrayJob::offset)
  std::vector<std::string> command;  // the sbatch command line (kind slurm)
  int workers = 0;                   // worker processes (kind local)
  double task_timeout_s = 0;         // each task's time limit (--task-timeout); 0: none
};

// DIR/batch.json.
struct BatchRecord {
  std::string manifest_source;  // the manifest as given to submit (absolute)
  std::string manifest_dir;     // inputs resolve against this folder (absolute)
  std::string binary;           // the rangebayes binary the jobs run (absolute)
  int num_tasks = 0;
  std::vector<BatchSubmission> submissions;
};

// Throws Error naming DIR/batch.json when a path is not UTF-8 (JSON cannot hold it, and the paths are read back).
void WriteBatchRecord(const BatchLayout& layout, const BatchRecord& record);
// Throws naming DIR when it holds no batch (no batch.json) or the file is malformed.
BatchRecord ReadBatchRecord(const BatchLayout& layout);

// The status of one task, DIR/status/<index>.json.
struct BatchTaskStatus {
  int index = 0;
  // "running", "succeeded", "partial" (the command exited 3: some of its work failed or was skipped, the rest is
  // published), "failed", or "timeout" (stopped at its time limit: run-task's --task-timeout, or Slurm's)
  std::string state;
  int exit_code = -1;     // of the task's command; 128 + signal when a signal ended it; -1 while running
  int attempt = 0;        // SLURM_RESTART_COUNT (0 on the first run of a job, and for --local)
  int run = 1;            // how many times run-task started this index in this folder, this run included
  std::string job_id;     // SLURM_ARRAY_JOB_ID, empty outside Slurm
  std::string host;       // gethostname()
  int pid = 0;            // run-task's process id on `host` (0: not recorded)
  std::int64_t pid_start_ticks = -1;  // when that process started (clock ticks after boot; -1: not recorded)
  std::string boot_id;                // the kernel's boot id on `host` when it started (empty: not recorded)
  std::string node;       // SLURMD_NODENAME, empty outside Slurm
  std::string start_utc, end_utc;  // ISO 8601 with milliseconds; end empty while running
  double duration_s = 0;           // wall time of the command
  std::string error_line;          // failed or partial: the line that says why (TaskErrorLine), or why else
  std::string line;                // the manifest line this run ran, as written (ManifestTask::line)
  std::string command;             // the manifest line as run, paths resolved
};

// Bytes of its strings that are not UTF-8 (an error line naming such a file) are written as U+FFFD.
std::string BatchTaskStatusJson(const BatchTaskStatus& status);
BatchTaskStatus ParseBatchTaskStatus(const std::string& json, const std::string& source);
// Written to a temporary file and renamed over the old one, so a reader sees the old or the new status.
void WriteBatchTaskStatus(const BatchLayout& layout, const BatchTaskStatus& status);
// nullopt when the task has no status file yet.
std::optional<BatchTaskStatus> ReadBatchTaskStatus(const BatchLayout& layout, int index);

// After SIGTERM at its time limit, a task's command has this long to end before SIGKILL (Slurm's KillWait is 30 s
// by default; the command's own cleanup takes well under a second).
constexpr double kTaskTimeoutGraceS = 10;

struct RunTaskOptions {
  std::string binary;  // the rangebayes binary that runs the task's line; empty: this executable
  // Forward SIGTERM/SIGINT/SIGHUP (Slurm's cancel, preemption, requeue, time limit) to the command, then clean up
  // the temporary folder and record the task as failed (or as timeout when Slurm says its time limit was reached).
  // A signal that was ignored when run-task started (nohup, a background job of a script) stays ignored, for
  // run-task and its command.
  bool forward_signals = true;
  // > 0: the command's time limit (s, finite, at most kMaxTaskTimeoutS): then SIGTERM to its process group (it
  // runs in one of its own), SIGKILL after timeout_grace_s more, and the task is recorded as "timeout".
  double task_timeout_s = 0;
  double timeout_grace_s = kTaskTimeoutGraceS;  // > 0, finite
  // Asked (`scontrol show job -o $SLURM_JOB_ID`) whether a stop signal inside a Slurm job was its time limit.
  std::string scontrol = "scontrol";
  SubcommandSyntaxes syntaxes;  // where each subcommand names its outputs (OutputWordIndices)
  void Check() const;
};

// The largest --task-timeout: a year, in seconds.
constexpr double kMaxTaskTimeoutS = 365.0 * 24 * 3600;

// Throws naming --task-timeout unless `seconds` is a finite number in (0, kMaxTaskTimeoutS].
void CheckTaskTimeout(double seconds);

// Whether `scontrol show job -o` output says that job `job_id` was stopped at its time limit: its line (JobId=ID;
// an array's own id lists every task of the array, one line each) says JobState=TIMEOUT, or Reason=TimeLimit (while
// it completes, which is when its processes get SIGTERM). *limit gets its TimeLimit value ("00:01:00").
bool JobReachedTimeLimit(const std::string& scontrol_output, const std::string& job_id, std::string* limit);

// Seconds as a short decimal ("30", "0.25"), as written on the command lines of run-task.
std::string FormatSeconds(double seconds);

// Runs task `index` of the batch in DIR: resolves the line's paths (ResolveTaskArguments), runs it in
// DIR/tasks/.tmp-<index>-<attempt>-<pid>/ with its output appended to DIR/logs/<index>.log, and renames the
// folder to DIR/tasks/<index>/ (replacing an older result) only when the command exited 0 (succeeded) or 3
// (partial) and was neither stopped by a signal nor at its time limit; otherwise removes it. A line whose output is
// absolute or leaves the task's folder (CheckTaskOutputs) fails without running. Writes the status file at the start
// (running) and the end. On success it also removes the temporary folders that earlier runs of the same task left when
// they were killed (SIGKILL, a lost node), but not one whose process (the pid in its name) is alive on this host.
// Returns the final status; throws only when DIR is not a batch, its manifest has another number of tasks than it was
// submitted with, or `index` is out of range.
BatchTaskStatus RunBatchTask(const std::string& dir, int index, const RunTaskOptions& options = {});

// True when `status` says running but its run-task process is gone: it ran on this host and no process
// `status.pid` exists any more (killed with SIGKILL), or the machine restarted since (another boot id), or the
// process with that pid now is another one (another start time: pids are reused).
bool RunTaskIsGone(const BatchTaskStatus& status);

// True when `status` says running and its run-task process is alive on this host (RunTaskIsGone says it is not
// gone).
bool RunTaskRunsHere(const BatchTaskStatus& status);

// When process `pid` started, in clock ticks after the boot (field 22 of /proc/PID/stat); -1 when there is no such
// process or /proc does not say. A pid and its start identify a process: pids are reused, their starts are not.
std::int64_t ProcessStartTicks(int pid);

// The line of a command's output that says why it failed or only partly succeeded: its last line containing
// "error:"; but a line naming a frame that failed or was skipped (or a system error such as "No space left on
// device") is preferred to an "error:" line that only sums up ("… (and 3 more above)": then both), and is the line of a
// partial success; else the last line.
std::string TaskErrorLine(const std::string& output);

// The state of every task of a batch, from its status files and task folders (no Slurm accounting).
struct BatchReport {
  std::string dir;
  std::vector<ManifestTask> tasks;
  // Per task: "succeeded" (status says so and tasks/<index>/ exists), "partial" (likewise, the command exited 3),
  // "changed" (it ran another line than the manifest now has: DIR/manifest.txt was edited since), "failed",
  // "timeout" (stopped at its time limit), "running", "interrupted" (status says running, but it was written by a
  // run-task process on this host that is gone: RunTaskIsGone; one on another host cannot be checked from here and
  // stays "running"), or "missing" (never started, or its result folder is gone). A status file that cannot be read
  // counts as "failed", its error line saying why.
  std::vector<std::string> states;
  std::vector<std::optional<BatchTaskStatus>> statuses;
  int succeeded = 0, partial = 0, changed = 0, failed = 0, timeout = 0, running = 0, interrupted = 0, missing = 0;

  // Counts, then one line per partial, changed, failed, timeout or interrupted task, and per running task of a
  // --local run on another host (which cannot be checked from here: if that host is down, only
  // resubmit --include-running takes it).
  std::string BriefReport() const;
  std::string Json() const;
  // Indices whose state is missing, partial, changed, failed, timeout or interrupted, ascending.
  std::vector<int> UnfinishedIndices() const;
};

// Throws naming DIR when it holds no batch, or when DIR/manifest.txt has another number of tasks than the batch
// was submitted with (task i's results belong to line i: edit lines, but do not add or remove them).
BatchReport CollectBatchReport(const std::string& dir);

// ISO 8601 UTC with milliseconds, e.g. 2026-12-01T20:15:03.125Z.
std::string NowUtc();

}  // namespace rangebayes
