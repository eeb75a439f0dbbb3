#include "batch/submit.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "batch/process.h"
#include "core/error.h"
#include "core/files.h"

namespace rangebayes {
namespace fs = std::filesystem;

namespace {

// An exclusive flock on DIR/batch.lock for as long as it lives; the file names the holder (pid and host). Not
// inherited by the processes it starts (O_CLOEXEC), and released by the kernel when the holder dies.
class BatchLock {
 public:
  explicit BatchLock(const BatchLayout& layout) {
    const std::string path = layout.dir + "/batch.lock";
    fd_ = open(path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    RB_CHECK(fd_ >= 0, path, ": cannot open the batch's lock (", std::strerror(errno), ")");
    if (flock(fd_, LOCK_EX | LOCK_NB) != 0) {
      const int error = errno;
      char holder[256] = {};
      const ssize_t n = pread(fd_, holder, sizeof(holder) - 1, 0);
      close(fd_);
      std::string who = n > 0 ? std::string(holder, static_cast<size_t>(n)) : "";
      while (!who.empty() && (who.back() == '\n' || who.back() == ' ')) who.pop_back();
      RB_CHECK(error != EWOULDBLOCK, layout.dir, ": another batch submit or resubmit of this batch is running (",
               who.empty() ? "pid unknown" : who, "); wait for it to end, then see rangebayes batch status ",
               layout.dir);
      RB_FAIL(path, ": cannot lock (", std::strerror(error), ")");
    }
    char host[256] = {};
    gethostname(host, sizeof(host) - 1);
    const std::string me = "pid " + std::to_string(getpid()) + " on " + host + "\n";
    if (ftruncate(fd_, 0) != 0 || pwrite(fd_, me.data(), me.size(), 0) != static_cast<ssize_t>(me.size())) {
      // The lock holds without the note; a refused run then says "pid unknown".
    }
  }
  ~BatchLock() { close(fd_); }
  BatchLock(const BatchLock&) = delete;
  BatchLock& operator=(const BatchLock&) = delete;

 private:
  int fd_ = -1;
};

// The cluster's MaxArraySize (scontrol show config); nullopt when scontrol cannot tell (sbatch then says what it
// refuses).
std::optional<int> ClusterMaxArraySize(const BatchSubmitOptions& options) {
  const CapturedRun run = RunAndCapture({options.scontrol, "show", "config"});
  if (!run.started || run.exit.exit_code != 0) return std::nullopt;
  return ParseMaxArraySize(run.out);
}

// run-task's options for the tasks of a submission (its time limit).
std::vector<std::string> RunTaskOptionWords(const BatchSubmitOptions& options) {
  if (options.task_timeout_s <= 0) return {};
  return {"--task-timeout", FormatSeconds(options.task_timeout_s)};
}

std::string JobScript(const BatchRecord& record, const BatchLayout& layout, const BatchSubmitOptions& options) {
  std::ostringstream s;
  s << "#!/bin/sh\n"
    << "# rangebayes batch: runs task $1 + $SLURM_ARRAY_TASK_ID of " << layout.manifest() << "\n"
    << "# ($1: the job's offset, 0 when not given; the sbatch command lines are in " << layout.record() << ").\n"
    << "exec " << QuoteForShell({record.binary, "batch", "run-task", layout.dir})
    << " \"$((${1:-0} + SLURM_ARRAY_TASK_ID))\"";
  const std::vector<std::string> words = RunTaskOptionWords(options);
  if (!words.empty()) s << " " << QuoteForShell(words);
  s << "\n";
  return s.str();
}

// Whether an sbatch argument sets the time limit (--time, --time=T, -t T, -tT; not --time-min).
bool IsSlurmTimeArgument(const std::string& word) {
  return word == "--time" || word.rfind("--time=", 0) == 0 || (word.rfind("-t", 0) == 0 && word.rfind("--", 0) != 0);
}

// "tasks 0-99" or "task 4".
std::string TasksText(const std::vector<int>& indices) {
  return (indices.size() == 1 ? "task " : "tasks ") + ArraySpec(indices, 0);
}

// "12 (tasks 0-99), 13 (tasks 100-120)".
std::string JobsText(const std::vector<BatchSubmission>& jobs) {
  std::string text;
  for (const BatchSubmission& s : jobs) {
    text += (text.empty() ? "" : ", ") + s.job_id + " (" + TasksText(s.indices) + ")";
  }
  return text;
}

BatchSubmitSummary Submit(const BatchLayout& layout, BatchRecord record, const std::vector<int>& indices,
                          const BatchSubmitOptions& options) {
  BatchSubmitSummary summary;
  summary.dir = layout.dir;
  summary.indices = indices;
  BatchSubmission submission;
  submission.time_utc = NowUtc();
  submission.indices = indices;
  submission.task_timeout_s = options.task_timeout_s;
  if (options.local_workers > 0) {
    submission.kind = "local";
    submission.workers = options.local_workers;
    record.submissions.push_back(submission);
    summary.submissions.push_back(submission);
    WriteBatchRecord(layout, record);
    BatchSubmitOptions local = options;
    local.binary = record.binary;
    RunBatchLocally(layout, indices, local);
    return summary;
  }
  submission.kind = "slurm";
  summary.max_array_size = ClusterMaxArraySize(options);
  std::vector<ArrayJob> jobs = SplitArrayJobs(indices, summary.max_array_size);
  fs::create_directories(layout.slurm_dir());
  summary.job_script = layout.slurm_dir() + "/job.sh";
  WriteFileAtomically(summary.job_script, JobScript(record, layout, options));
  fs::permissions(summary.job_script, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                                          fs::perms::others_read | fs::perms::others_exec);
  for (ArrayJob& job : jobs) {
    // With a throttle, each array waits for the one before, so that the throttle holds for the batch.
    if (options.max_parallel > 0 && !summary.submissions.empty()) job.after_job = summary.submissions.back().job_id;
    BatchSubmission s = submission;
    s.indices = job.indices;
    s.array_offset = job.offset;
    s.command = SbatchCommand(layout, job, options, summary.job_script);
    const CapturedRun run = RunAndCapture(s.command);
    // The jobs accepted before a refusal are recorded (their tasks run); the message names them.
    const bool first = summary.submissions.empty();
    const std::string which = first ? "" : " for " + TasksText(job.indices);
    const std::string before = first ? ""
                                     : "; Slurm accepted the jobs before it, " + JobsText(summary.submissions) +
                                           ", recorded in " + layout.record() +
                                           ": once they have ended, 'rangebayes batch resubmit " + layout.dir +
                                           "' submits the rest";
    RB_CHECK(run.started, options.sbatch, ": cannot run sbatch", which, " (", run.error, ")",
             first ? "; submit from a machine with the Slurm client installed, or use --local N to run here" : before);
    if (run.exit.exit_code != 0) {
      std::string line = LastLine(run.err);
      if (line.empty()) line = LastLine(run.out);
      RB_FAIL("sbatch refused the job", which, " (exit ", run.exit.exit_code, "): ", line.empty() ? "no message" : line,
              before);
    }
    s.job_id = ParseSbatchJobId(run.out);
    record.submissions.push_back(s);
    summary.submissions.push_back(s);
    WriteBatchRecord(layout, record);
  }
  return summary;
}

// The Slurm array job ids of the batch's submissions, in order.
std::vector<std::string> SlurmJobsOf(const BatchRecord& record) {
  std::vector<std::string> jobs;
  for (const BatchSubmission& s : record.submissions) {
    if (s.kind == "slurm") jobs.push_back(s.job_id);
  }
  return jobs;
}

// Every task line as the binary's parser reads it (options.check_line), naming the manifest line it refuses.
void CheckTaskLines(const std::vector<ManifestTask>& tasks, const std::string& manifest_dir,
                    const BatchSubmitOptions& options, const std::string& source) {
  if (!options.check_line) return;
  for (const ManifestTask& t : tasks) {
    try {
      options.check_line(ResolveTaskArguments(t.arguments, manifest_dir, options.syntaxes));
    } catch (const Error& e) {
      RB_FAIL(source, ":", t.line_number, ": ", e.what());
    }
  }
}

// Array job ids that squeue lists (queued or running); `*listed` tells whether squeue could be run at all.
std::set<std::string> QueuedArrayJobs(const std::string& squeue, bool* listed) {
  const CapturedRun run = RunAndCapture({squeue, "--noheader", "--array", "--format=%F"});
  std::set<std::string> jobs;
  *listed = run.started;
  if (!run.started) return jobs;
  RB_CHECK(run.exit.exit_code == 0, "squeue failed (exit ", run.exit.exit_code, "): ", LastLine(run.err),
           "; it is asked which jobs of the batch are still queued or running");
  std::istringstream in(run.out);
  std::string id;
  while (in >> id) jobs.insert(id);
  return jobs;
}

}  // namespace

void BatchSubmitOptions::Check() const {
  RB_CHECK(max_parallel >= 0 && max_parallel <= 100000, "--max-parallel must be 0-100000, got ", max_parallel);
  RB_CHECK(local_workers >= 0 && local_workers <= 1024, "--local must be 1-1024 workers, got ", local_workers);
  RB_CHECK(binary.empty() || fs::path(binary).is_absolute(), "BatchSubmitOptions::binary must be absolute: ", binary);
  RB_CHECK(partition.find_first_of(" \t\n") == std::string::npos, "--partition has whitespace: '", partition, "'");
  RB_CHECK(!sbatch.empty() && !squeue.empty(), "BatchSubmitOptions: sbatch and squeue must be named");
  if (task_timeout_s != 0) {
    CheckTaskTimeout(task_timeout_s);
    for (const std::string& a : slurm_args) {
      RB_CHECK(!IsSlurmTimeArgument(a), "--task-timeout sets sbatch's --time (", SlurmTimeMinutes(task_timeout_s),
               " min for ", FormatSeconds(task_timeout_s), " s); give it without --slurm-arg=", a);
    }
  }
}

long SlurmTimeMinutes(double task_timeout_s) {
  return static_cast<long>(std::ceil((task_timeout_s + kTaskTimeoutGraceS) / 60)) + 1;
}

std::string BatchSubmitSummary::BriefReport() const {
  std::ostringstream out;
  const auto plural = [](size_t n, const char* word) { return std::to_string(n) + " " + word + (n == 1 ? "" : "s"); };
  if (!submissions.empty() && submissions.front().kind == "local") {
    out << "ran " << plural(indices.size(), "task") << " on " << plural(submissions.front().workers, "local worker")
        << " in " << dir;
  } else if (submissions.size() == 1) {
    out << "submitted " << plural(indices.size(), "task") << " as Slurm job " << submissions.front().job_id
        << " (array " << ArraySpec(submissions.front().indices, 0) << ") in " << dir;
  } else {
    out << "submitted " << plural(indices.size(), "task") << " as " << submissions.size() << " Slurm jobs";
    if (max_array_size) out << " (MaxArraySize " << *max_array_size << ")";
    out << ": " << JobsText(submissions) << " in " << dir;
  }
  return out.str();
}

std::string BatchSubmitSummary::JobIds() const {
  std::string ids;
  for (const BatchSubmission& s : submissions) {
    if (s.kind == "slurm") ids += (ids.empty() ? "" : " ") + s.job_id;
  }
  return ids;
}

std::string ArraySpec(const std::vector<int>& input, int max_parallel) {
  std::vector<int> indices = input;
  std::sort(indices.begin(), indices.end());
  indices.erase(std::unique(indices.begin(), indices.end()), indices.end());
  RB_CHECK(!indices.empty(), "no tasks to submit");
  std::ostringstream out;
  for (size_t i = 0; i < indices.size();) {
    size_t j = i;
    while (j + 1 < indices.size() && indices[j + 1] == indices[j] + 1) ++j;
    if (i > 0) out << ',';
    out << indices[i];
    if (j > i) out << '-' << indices[j];
    i = j + 1;
  }
  if (max_parallel > 0) out << '%' << max_parallel;
  return out.str();
}

std::vector<ArrayJob> SplitArrayJobs(const std::vector<int>& input, std::optional<int> max_array_size) {
  std::vector<int> indices = input;
  std::sort(indices.begin(), indices.end());
  indices.erase(std::unique(indices.begin(), indices.end()), indices.end());
  RB_CHECK(!indices.empty(), "no tasks to submit");
  RB_CHECK(!max_array_size || *max_array_size > 0, "MaxArraySize must be positive, got ", *max_array_size);
  if (!max_array_size || indices.back() < *max_array_size) return {ArrayJob{0, indices, ""}};
  std::vector<ArrayJob> jobs;
  for (const int index : indices) {
    const int offset = index / *max_array_size * *max_array_size;
    if (jobs.empty() || jobs.back().offset != offset) jobs.push_back(ArrayJob{offset, {}, ""});
    jobs.back().indices.push_back(index);
  }
  return jobs;
}

std::vector<std::string> SbatchCommand(const BatchLayout& layout, const ArrayJob& job,
                                       const BatchSubmitOptions& options, const std::string& job_script) {
  std::vector<int> array_indices;
  for (const int index : job.indices) array_indices.push_back(index - job.offset);
  std::vector<std::string> command = {options.sbatch,
                                      "--parsable",
                                      "--job-name=rangebayes-batch",
                                      "--array=" + ArraySpec(array_indices, options.max_parallel),
                                      "--requeue",
                                      "--open-mode=append",
                                      "--output=" + layout.slurm_dir() + "/%A_%a.out",
                                      "--chdir=" + layout.dir};
  if (!options.partition.empty()) command.push_back("--partition=" + options.partition);
  if (options.task_timeout_s > 0) {
    command.push_back("--time=" + std::to_string(SlurmTimeMinutes(options.task_timeout_s)));
  }
  if (!job.after_job.empty()) command.push_back("--dependency=afterany:" + job.after_job);
  command.insert(command.end(), options.slurm_args.begin(), options.slurm_args.end());
  command.push_back(job_script);
  if (job.offset != 0) command.push_back(std::to_string(job.offset));
  return command;
}

std::optional<int> ParseMaxArraySize(const std::string& output) {
  std::istringstream in(output);
  for (std::string line; std::getline(in, line);) {
    std::istringstream words(line);
    std::string key, equals;
    long long value = 0;
    if (words >> key >> equals >> value && key == "MaxArraySize" && equals == "=" && value > 0 && value <= 1 << 30) {
      return static_cast<int>(value);
    }
  }
  return std::nullopt;
}

std::string ParseSbatchJobId(const std::string& output) {
  std::string line = LastLine(output);
  const size_t semicolon = line.find(';');
  if (semicolon != std::string::npos) line = line.substr(0, semicolon);
  RB_CHECK(!line.empty() && line.find_first_not_of("0123456789") == std::string::npos,
           "sbatch printed no job id (output: '", LastLine(output), "')");
  return line;
}

BatchSubmitSummary SubmitBatch(const std::string& manifest_path, const std::string& dir,
                               const BatchSubmitOptions& options) {
  options.Check();
  const std::vector<ManifestTask> tasks = ReadManifest(manifest_path);
  if (!options.subcommands.empty()) {
    for (const ManifestTask& t : tasks) {
      const std::string& name = t.arguments[0];
      if (std::find(options.subcommands.begin(), options.subcommands.end(), name) != options.subcommands.end())
        continue;
      std::string known;
      for (const std::string& s : options.subcommands) known += (known.empty() ? "" : ", ") + s;
      RB_FAIL(manifest_path, ":", t.line_number, ": '", name, "' is not a rangebayes subcommand (", known, ")");
    }
  }
  for (const ManifestTask& t : tasks) CheckTaskOutputs(t, options.syntaxes, manifest_path);
  CheckTaskLines(tasks, fs::absolute(manifest_path).lexically_normal().parent_path().string(), options, manifest_path);
  const BatchLayout layout(dir);
  const auto check_no_batch = [&] {
    // A folder whose earlier submit was refused (no submission recorded) may be used again.
    RB_CHECK(!fs::exists(layout.record()) || ReadBatchRecord(layout).submissions.empty(), layout.dir,
             ": already holds a batch (batch.json); use batch resubmit DIR, or another --out");
  };
  check_no_batch();
  CreateFolder(layout.dir);
  const BatchLock lock(layout);
  check_no_batch();  // again under the lock: another submit may have recorded its batch meanwhile
  fs::copy_file(manifest_path, layout.manifest(), fs::copy_options::overwrite_existing);
  BatchRecord record;
  record.manifest_source = fs::absolute(manifest_path).lexically_normal().string();
  record.manifest_dir = fs::path(record.manifest_source).parent_path().string();
  record.binary = options.binary.empty() ? SelfExecutable() : options.binary;
  record.num_tasks = static_cast<int>(tasks.size());
  std::vector<int> indices;
  for (const ManifestTask& t : tasks) indices.push_back(t.index);
  WriteBatchRecord(layout, record);
  return Submit(layout, record, indices, options);
}

BatchSubmitSummary ResubmitBatch(const std::string& dir, const BatchSubmitOptions& options) {
  options.Check();
  const BatchLayout layout(dir);
  ReadBatchRecord(layout);  // a folder that holds no batch is refused before a lock file is made in it
  const BatchLock lock(layout);
  BatchRecord record = ReadBatchRecord(layout);
  const BatchReport report = CollectBatchReport(layout.dir);
  for (const ManifestTask& t : report.tasks) CheckTaskOutputs(t, options.syntaxes, layout.manifest());
  CheckTaskLines(report.tasks, record.manifest_dir, options, layout.manifest());
  const std::vector<std::string> jobs = SlurmJobsOf(record);
  const std::set<std::string> ours(jobs.begin(), jobs.end());
  bool queue_listed = false;
  if (!ours.empty()) {
    for (const std::string& id : QueuedArrayJobs(options.squeue, &queue_listed)) {
      RB_CHECK(ours.count(id) == 0, "Slurm job ", id, " of this batch is still queued or running; wait for it (squeue -j ",
               id, ") or cancel it (scancel ", id, ") before batch resubmit");
    }
  }
  // Missing, failed and interrupted (a run-task process on this host gone before it recorded an end).
  std::vector<int> indices = report.UnfinishedIndices();
  // A task still marked running: with no job of the batch left in the queue, it was killed (on another node, where
  // its process cannot be checked) before it could write its final status; with include_running, the user says it
  // was (a --local run on a host that died). Never one whose run-task is alive here.
  if (queue_listed || options.include_running) {
    for (size_t i = 0; i < report.states.size(); ++i) {
      if (report.states[i] != "running") continue;
      const BatchTaskStatus& s = *report.statuses[i];
      RB_CHECK(!RunTaskRunsHere(s), "task ", i, " still runs on this host (run-task pid ", s.pid,
               "); wait for it to end, or stop it, before batch resubmit");
      indices.push_back(static_cast<int>(i));
    }
  }
  std::sort(indices.begin(), indices.end());
  RB_CHECK(!indices.empty(), layout.dir, ": nothing to resubmit (", report.succeeded, " succeeded, ", report.running,
           " running",
           report.running > 0 && !options.include_running
               ? "; a task that reads running on a host that is down is taken by resubmit --include-running"
               : "",
           ")");
  if (!options.binary.empty()) record.binary = options.binary;
  return Submit(layout, record, indices, options);
}

std::vector<std::string> CancelBatch(const std::string& dir, const BatchSubmitOptions& options) {
  const BatchLayout layout(dir);
  const std::vector<std::string> jobs = SlurmJobsOf(ReadBatchRecord(layout));
  RB_CHECK(!jobs.empty(), layout.dir,
           ": has no Slurm job to cancel (a --local run ends with Ctrl-C of its submit or "
           "resubmit, or kill of the pid named in ",
           layout.dir, "/batch.lock)");
  bool listed = false;
  const std::set<std::string> queued = QueuedArrayJobs(options.squeue, &listed);
  RB_CHECK(listed, options.squeue,
           ": cannot run squeue, which says which jobs of the batch are still queued or "
           "running; cancel them with scancel (their ids are in ",
           layout.record(), ")");
  std::vector<std::string> cancel;
  for (const std::string& job : jobs) {
    if (queued.count(job) != 0) cancel.push_back(job);
  }
  RB_CHECK(!cancel.empty(), layout.dir, ": no Slurm job of this batch is queued or running (jobs ", QuoteForShell(jobs),
           "); see rangebayes batch status ", layout.dir);
  std::vector<std::string> command = {options.scancel};
  command.insert(command.end(), cancel.begin(), cancel.end());
  const CapturedRun run = RunAndCapture(command);
  RB_CHECK(run.started, options.scancel, ": cannot run scancel (", run.error, ")");
  RB_CHECK(run.exit.exit_code == 0, "scancel failed (exit ", run.exit.exit_code, "): ", LastLine(run.err));
  return cancel;
}

void RunBatchLocally(const BatchLayout& layout, const std::vector<int>& indices, const BatchSubmitOptions& options) {
  RB_CHECK(options.local_workers > 0, "RunBatchLocally needs local_workers > 0");
  const std::string binary = options.binary.empty() ? SelfExecutable() : options.binary;
  fs::create_directories(layout.dir + "/local");
  const std::string output = layout.dir + "/local/run-task.out";
  std::map<pid_t, int> running;
  size_t next = 0;
  auto finish = [&](pid_t pid, const ProcessExit& exit) {
    const int index = running.at(pid);
    running.erase(pid);
    std::optional<BatchTaskStatus> status;
    try {
      status = ReadBatchTaskStatus(layout, index);
    } catch (const Error&) {
      // Unreadable: as if run-task had written none (the other workers are still to be waited for).
    }
    if (!status || status->state == "running") {
      // run-task died before writing its final status.
      BatchTaskStatus failed = status.value_or(BatchTaskStatus{});
      failed.index = index;
      failed.state = "failed";
      failed.exit_code = exit.exit_code;
      failed.end_utc = NowUtc();
      failed.error_line = "batch run-task ended with exit " + std::to_string(exit.exit_code) +
                          " without a final status (see " + output + ")";
      WriteBatchTaskStatus(layout, failed);
      status = failed;
    }
    if (options.on_task_end) options.on_task_end(*status);
  };
  while (next < indices.size() || !running.empty()) {
    while (next < indices.size() && static_cast<int>(running.size()) < options.local_workers) {
      ProcessSpec spec;
      spec.argv = {binary, "batch", "run-task", layout.dir, std::to_string(indices[next])};
      for (const std::string& word : RunTaskOptionWords(options)) spec.argv.push_back(word);
      spec.output_path = output;
      running[StartProcess(spec)] = indices[next];
      ++next;
    }
    int status = 0;
    const pid_t pid = waitpid(-1, &status, 0);
    if (pid < 0) {
      RB_CHECK(errno == EINTR, "waitpid: ", std::strerror(errno));
      continue;
    }
    if (running.count(pid) != 0) finish(pid, DecodeWaitStatus(status));
  }
}

}  // namespace rangebayes
