#include "batch/task.h"

#include <signal.h>
#include <sys/time.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "batch/process.h"
#include "core/error.h"
#include "core/files.h"
#include "core/json_int.h"
#include "core/json_text.h"

namespace rangebayes {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

// A JSON value that must be an int (`what` names it). A value that is no integer or does not fit an int (a damaged
// file; get<int>() would wrap it) is a json::type_error, which the callers report as a malformed file.
int IntOf(const json& v, const std::string& what) {
  const std::optional<int> i = JsonInt(v);
  if (!i) throw json::type_error::create(302, what + " is not an int", &v);
  return *i;
}

// The int at `key` of a JSON object; `fallback` when the key is absent (nullopt: the key is required).
int IntAt(const json& j, const char* key, std::optional<int> fallback = std::nullopt) {
  if (fallback && !j.contains(key)) return *fallback;
  return IntOf(j.at(key), std::string("\"") + key + "\"");
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  RB_CHECK(in.good(), path, ": cannot read");
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::string Env(const char* name) {
  const char* value = std::getenv(name);
  return value == nullptr ? "" : value;
}

std::string HostName() {
  char name[256] = {};
  if (gethostname(name, sizeof(name) - 1) != 0) return "";
  return name;
}

// The kernel's id of this boot ("" where /proc does not say).
std::string BootId() {
  std::ifstream in("/proc/sys/kernel/random/boot_id");
  std::string id;
  std::getline(in, id);
  return id;
}

// True when `line` names a frame that failed or was skipped ("frame 12 skipped: ...", "frame 3: sinks: ...: write
// failed: ..."), or a system error that explains a failure by itself (a full disk).
bool NamesACause(const std::string& line) {
  for (const int e : {ENOSPC, EDQUOT, EROFS, EIO}) {
    if (line.find(std::strerror(e)) != std::string::npos) return true;
  }
  for (size_t at = line.find("frame "); at != std::string::npos; at = line.find("frame ", at + 1)) {
    const bool numbered = at + 6 < line.size() && std::isdigit(static_cast<unsigned char>(line[at + 6]));
    if (numbered && (line.find("failed", at) != std::string::npos || line.find("skipped", at) != std::string::npos ||
                     line.find("error", at) != std::string::npos)) {
      return true;
    }
  }
  return false;
}

// Whether `state` is one whose result folder is published.
bool Published(const std::string& state) { return state == "succeeded" || state == "partial"; }

// Whether process `pid` exists on this host and has not ended (a zombie, not yet reaped by its parent, has).
bool ProcessRunsHere(int pid) {
  if (pid <= 0) return false;
  if (kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) return false;
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(in, line)) return true;  // /proc does not say: kill(2) found it
  const size_t name_end = line.rfind(')');
  return name_end == std::string::npos || name_end + 2 >= line.size() || line[name_end + 2] != 'Z';
}

// Where signals for the command go while it runs: its pid, or minus its process group; 0 when none runs.
volatile sig_atomic_t g_command_target = 0;
volatile sig_atomic_t g_signal = 0;
volatile sig_atomic_t g_time_limit_alarms = 0;

void ForwardSignal(int sig) {
  g_signal = sig;
  if (g_command_target != 0) kill(static_cast<pid_t>(g_command_target), sig);
}

// The first alarm is the task's time limit (SIGTERM); every later one, a grace period apart, sends SIGKILL.
void TimeLimitAlarm(int) {
  const bool first = g_time_limit_alarms == 0;
  g_time_limit_alarms = 1;
  if (g_command_target != 0) kill(static_cast<pid_t>(g_command_target), first ? SIGTERM : SIGKILL);
}

timeval Timeval(double seconds) {
  timeval t{};
  t.tv_sec = static_cast<time_t>(seconds);
  t.tv_usec = static_cast<suseconds_t>((seconds - static_cast<double>(t.tv_sec)) * 1e6);
  if (t.tv_sec == 0 && t.tv_usec == 0) t.tv_usec = 1;  // a zero it_value would disarm the timer
  return t;
}

// The command's time limit while it lives: SIGALRM (ITIMER_REAL) after `limit_s`, then every `grace_s`. The old
// SIGALRM action comes back, and the timer is disarmed, at Disarm or at the end of its scope. Armed() is false
// when sigaction or setitimer failed (they fail only for invalid arguments).
class TimeLimit {
 public:
  TimeLimit(double limit_s, double grace_s) {
    g_time_limit_alarms = 0;
    if (limit_s <= 0) return;
    struct sigaction sa {};
    sa.sa_handler = TimeLimitAlarm;
    sigemptyset(&sa.sa_mask);
    if (sigaction(SIGALRM, &sa, &old_) != 0) return;
    itimerval timer{};
    timer.it_value = Timeval(limit_s);
    timer.it_interval = Timeval(grace_s);
    armed_ = setitimer(ITIMER_REAL, &timer, nullptr) == 0;
    if (!armed_) sigaction(SIGALRM, &old_, nullptr);
  }
  bool Armed() const { return armed_; }
  ~TimeLimit() { Disarm(); }
  TimeLimit(const TimeLimit&) = delete;
  TimeLimit& operator=(const TimeLimit&) = delete;
  void Disarm() {
    if (!armed_) return;
    const itimerval off{};
    setitimer(ITIMER_REAL, &off, nullptr);
    sigaction(SIGALRM, &old_, nullptr);
    armed_ = false;
  }
  bool Reached() const { return g_time_limit_alarms != 0; }

 private:
  bool armed_ = false;
  struct sigaction old_ {};
};

// Forwards SIGTERM, SIGINT and SIGHUP to the command while it lives. A signal that is ignored (nohup, a background
// job of a non-interactive shell) keeps its SIG_IGN, which the command inherits: whoever ignored it meant the
// work to go on.
struct SignalForwarding {
  static constexpr int kSignals[3] = {SIGTERM, SIGINT, SIGHUP};
  bool installed[3] = {false, false, false};
  struct sigaction old[3]{};
  explicit SignalForwarding(bool on) {
    g_signal = 0;
    if (!on) return;
    struct sigaction sa{};
    sa.sa_handler = ForwardSignal;
    sigemptyset(&sa.sa_mask);
    for (int k = 0; k < 3; ++k) {
      if (sigaction(kSignals[k], nullptr, &old[k]) != 0 || old[k].sa_handler == SIG_IGN) continue;
      installed[k] = sigaction(kSignals[k], &sa, &old[k]) == 0;
    }
  }
  ~SignalForwarding() {
    g_command_target = 0;
    for (int k = 0; k < 3; ++k) {
      if (installed[k]) sigaction(kSignals[k], &old[k], nullptr);
    }
  }
  SignalForwarding(const SignalForwarding&) = delete;
  SignalForwarding& operator=(const SignalForwarding&) = delete;
};

// Moves `from` to `to`; an existing `to` (an older result) is moved aside first and removed after.
void Publish(const fs::path& from, const fs::path& to) {
  std::error_code ec;
  fs::path old;
  if (fs::exists(to)) {
    old = to.parent_path() / (".old-" + to.filename().string() + "-" + std::to_string(getpid()));
    fs::rename(to, old, ec);
    RB_CHECK(!ec, to.string(), ": cannot move the older result aside (", ec.message(), ")");
  }
  fs::rename(from, to, ec);
  RB_CHECK(!ec, from.string(), ": cannot rename to ", to.string(), " (", ec.message(), ")");
  if (!old.empty()) fs::remove_all(old, ec);
}

}  // namespace

std::int64_t ProcessStartTicks(int pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(in, line)) return -1;
  const size_t name_end = line.rfind(')');  // the command name, field 2, may hold spaces and parentheses
  if (name_end == std::string::npos) return -1;
  std::istringstream fields(line.substr(name_end + 1));
  std::string field;
  for (int k = 3; k <= 22; ++k) {
    if (!(fields >> field)) return -1;
  }
  char* end = nullptr;
  const long long ticks = std::strtoll(field.c_str(), &end, 10);
  return end != field.c_str() && *end == '\0' && ticks >= 0 ? ticks : -1;
}

BatchLayout::BatchLayout(const std::string& folder)
    : dir(fs::absolute(fs::path(folder)).lexically_normal().string()) {
  while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
}
std::string BatchLayout::manifest() const { return dir + "/manifest.txt"; }
std::string BatchLayout::record() const { return dir + "/batch.json"; }
std::string BatchLayout::tasks_dir() const { return dir + "/tasks"; }
std::string BatchLayout::task_dir(int index) const { return tasks_dir() + "/" + std::to_string(index); }
std::string BatchLayout::status_file(int index) const { return dir + "/status/" + std::to_string(index) + ".json"; }
std::string BatchLayout::log_file(int index) const { return dir + "/logs/" + std::to_string(index) + ".log"; }
std::string BatchLayout::slurm_dir() const { return dir + "/slurm"; }

std::string NowUtc() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900, tm.tm_mon + 1,
                tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, static_cast<int>(ms));
  return buffer;
}

void WriteBatchRecord(const BatchLayout& layout, const BatchRecord& record) {
  json j;
  j["manifest_source"] = record.manifest_source;
  j["manifest_dir"] = record.manifest_dir;
  j["binary"] = record.binary;
  j["num_tasks"] = record.num_tasks;
  j["submissions"] = json::array();
  for (const BatchSubmission& s : record.submissions) {
    json js;
    js["kind"] = s.kind;
    js["time_utc"] = s.time_utc;
    js["indices"] = s.indices;
    if (s.kind == "slurm") {
      js["job_id"] = s.job_id;
      if (s.array_offset != 0) js["array_offset"] = s.array_offset;
      js["command"] = s.command;
    } else {
      js["workers"] = s.workers;
    }
    if (s.task_timeout_s > 0) js["task_timeout_s"] = s.task_timeout_s;
    j["submissions"].push_back(js);
  }
  std::string text;
  try {
    text = j.dump(2) + "\n";
  } catch (const json::type_error& e) {
    // Not JsonText's U+FFFD: these paths are read back to run the tasks, and a changed one names another file.
    RB_FAIL(layout.record(), ": cannot record the batch: a path (manifest ", record.manifest_source, ", binary ",
            record.binary, ") is not UTF-8 text, which JSON cannot hold; rename it (", e.what(), ")");
  }
  WriteFileAtomically(layout.record(), text, /*sync=*/true);
}

BatchRecord ReadBatchRecord(const BatchLayout& layout) {
  RB_CHECK(fs::exists(layout.record()), layout.dir, ": not a batch folder (no batch.json; run batch submit first)");
  BatchRecord record;
  try {
    const json j = json::parse(ReadText(layout.record()));
    record.manifest_source = j.at("manifest_source").get<std::string>();
    record.manifest_dir = j.at("manifest_dir").get<std::string>();
    record.binary = j.at("binary").get<std::string>();
    record.num_tasks = IntAt(j, "num_tasks");
    for (const json& js : j.at("submissions")) {
      BatchSubmission s;
      s.kind = js.at("kind").get<std::string>();
      s.time_utc = js.value("time_utc", "");
      for (const json& i : js.at("indices")) s.indices.push_back(IntOf(i, "an element of \"indices\""));
      s.job_id = js.value("job_id", "");
      s.array_offset = IntAt(js, "array_offset", 0);
      if (js.contains("command")) s.command = js.at("command").get<std::vector<std::string>>();
      s.workers = IntAt(js, "workers", 0);
      s.task_timeout_s = js.value("task_timeout_s", 0.0);
      record.submissions.push_back(s);
    }
  } catch (const json::exception& e) {
    RB_FAIL(layout.record(), ": malformed (", e.what(), ")");
  }
  return record;
}

std::string BatchTaskStatusJson(const BatchTaskStatus& s) {
  json j;
  j["index"] = s.index;
  j["state"] = s.state;
  j["exit_code"] = s.exit_code;
  j["attempt"] = s.attempt;
  j["run"] = s.run;
  j["job_id"] = s.job_id;
  j["host"] = s.host;
  j["pid"] = s.pid;
  j["pid_start_ticks"] = s.pid_start_ticks;
  j["boot_id"] = s.boot_id;
  j["node"] = s.node;
  j["start_utc"] = s.start_utc;
  j["end_utc"] = s.end_utc;
  j["duration_s"] = s.duration_s;
  j["error_line"] = s.error_line;
  j["line"] = s.line;
  j["command"] = s.command;
  return JsonText(j, 2) + "\n";
}

BatchTaskStatus ParseBatchTaskStatus(const std::string& text, const std::string& source) {
  BatchTaskStatus s;
  try {
    const json j = json::parse(text);
    s.index = IntAt(j, "index");
    s.state = j.at("state").get<std::string>();
    s.exit_code = IntAt(j, "exit_code");
    s.attempt = IntAt(j, "attempt", 0);
    s.run = IntAt(j, "run", 1);
    s.job_id = j.value("job_id", "");
    s.host = j.value("host", "");
    s.pid = IntAt(j, "pid", 0);
    s.pid_start_ticks = j.value("pid_start_ticks", std::int64_t{-1});
    s.boot_id = j.value("boot_id", "");
    s.node = j.value("node", "");
    s.start_utc = j.value("start_utc", "");
    s.end_utc = j.value("end_utc", "");
    s.duration_s = j.value("duration_s", 0.0);
    s.error_line = j.value("error_line", "");
    s.line = j.value("line", "");
    s.command = j.value("command", "");
  } catch (const json::exception& e) {
    RB_FAIL(source, ": malformed task status (", e.what(), ")");
  }
  RB_CHECK(s.state == "running" || s.state == "succeeded" || s.state == "partial" || s.state == "failed" ||
               s.state == "timeout",
           source, ": unknown state '", s.state, "'");
  return s;
}

void WriteBatchTaskStatus(const BatchLayout& layout, const BatchTaskStatus& status) {
  fs::create_directories(fs::path(layout.status_file(status.index)).parent_path());
  WriteFileAtomically(layout.status_file(status.index), BatchTaskStatusJson(status), /*sync=*/true);
}

std::optional<BatchTaskStatus> ReadBatchTaskStatus(const BatchLayout& layout, int index) {
  const std::string path = layout.status_file(index);
  if (!fs::exists(path)) return std::nullopt;
  return ParseBatchTaskStatus(ReadText(path), path);
}

void RunTaskOptions::Check() const {
  RB_CHECK(binary.empty() || fs::path(binary).is_absolute(), "RunTaskOptions::binary must be absolute: ", binary);
  if (task_timeout_s != 0) CheckTaskTimeout(task_timeout_s);
  RB_CHECK(std::isfinite(timeout_grace_s) && timeout_grace_s > 0 && timeout_grace_s <= kMaxTaskTimeoutS,
           "RunTaskOptions::timeout_grace_s must be a positive number of seconds, got ", timeout_grace_s);
}

void CheckTaskTimeout(double seconds) {
  RB_CHECK(std::isfinite(seconds) && seconds > 0 && seconds <= kMaxTaskTimeoutS,
           "--task-timeout must be a number of seconds above 0 and at most ", FormatSeconds(kMaxTaskTimeoutS),
           " (a year), got ", FormatSeconds(seconds));
}

std::string FormatSeconds(double seconds) {
  std::ostringstream out;
  out.precision(15);
  out << seconds;
  return out.str();
}

bool JobReachedTimeLimit(const std::string& output, const std::string& job_id, std::string* limit) {
  std::istringstream lines(output);
  for (std::string line; std::getline(lines, line);) {
    std::istringstream words(line);
    std::string word;
    if (!(words >> word) || word != "JobId=" + job_id) continue;
    bool reached = false;
    while (words >> word) {
      if (word == "JobState=TIMEOUT" || word == "Reason=TimeLimit") reached = true;
      if (word.rfind("TimeLimit=", 0) == 0 && limit != nullptr) *limit = word.substr(10);
    }
    return reached;
  }
  return false;
}

namespace {

// The temporary folders of earlier runs of task `index` that never finished (their run-task was killed with
// SIGKILL or lost its node): a published result supersedes them. A folder whose run-task (the pid that ends its
// name) still runs on this host belongs to a run in progress and stays.
void RemoveAbandonedWork(const BatchLayout& layout, int index) {
  const std::string prefix = ".tmp-" + std::to_string(index) + "-";
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(layout.tasks_dir(), ec)) {
    const std::string name = entry.path().filename().string();
    if (name.rfind(prefix, 0) != 0) continue;
    const int pid = std::atoi(name.substr(name.find_last_of('-') + 1).c_str());
    if (pid != static_cast<int>(getpid()) && ProcessRunsHere(pid)) continue;
    fs::remove_all(entry.path(), ec);
  }
}

// The status of a task that starts now: attempt and job from Slurm's environment, run from its previous status.
BatchTaskStatus StartingStatus(const BatchLayout& layout, const ManifestTask& task,
                               const std::vector<std::string>& arguments) {
  const int index = task.index;
  BatchTaskStatus status;
  status.index = index;
  status.line = task.line;
  status.state = "running";
  const std::string restarts = Env("SLURM_RESTART_COUNT");
  status.attempt = restarts.empty() ? 0 : std::atoi(restarts.c_str());
  try {
    if (const auto previous = ReadBatchTaskStatus(layout, index)) status.run = previous->run + 1;
  } catch (const Error&) {
    // A damaged status (a machine that crashed while writing it) is replaced by this run's; its count is lost.
  }
  status.job_id = Env("SLURM_ARRAY_JOB_ID");
  status.host = HostName();
  status.pid = static_cast<int>(getpid());
  status.pid_start_ticks = ProcessStartTicks(status.pid);
  status.boot_id = BootId();
  status.node = Env("SLURMD_NODENAME");
  status.start_utc = NowUtc();
  status.command = QuoteForShell(arguments);
  return status;
}

// How the command ended, besides its exit: a stop signal run-task received (forwarded to it), or its time limit.
struct CommandEnd {
  ProcessExit exit;
  std::string start_error;  // not empty: the command could not start
  int stop_signal = 0;      // SIGTERM, SIGINT or SIGHUP that run-task received and forwarded
  bool time_limit = false;  // its --task-timeout expired (SIGTERM, then SIGKILL after the grace)
};

// Runs the task's command with the signals forwarded to it and its time limit, if any. With a time limit the
// command leads a process group of its own, and both go to the whole group (whatever it started too).
CommandEnd RunCommand(ProcessSpec spec, const RunTaskOptions& options) {
  CommandEnd end;
  SignalForwarding forwarding(options.forward_signals);
  spec.own_process_group = options.task_timeout_s > 0;
  pid_t pid = -1;
  try {
    pid = StartProcess(spec);
  } catch (const Error& e) {
    end.start_error = e.what();
    return end;
  }
  g_command_target = spec.own_process_group ? -pid : pid;
  if (g_signal != 0) kill(static_cast<pid_t>(g_command_target), g_signal);
  TimeLimit limit(options.task_timeout_s, options.timeout_grace_s);
  if (options.task_timeout_s > 0 && !limit.Armed()) {
    end.start_error = "cannot arm the task's time limit (setitimer: " + std::string(std::strerror(errno)) + ")";
    kill(static_cast<pid_t>(g_command_target), SIGKILL);
  }
  // Until it is reaped, the command's pid and process group stay its own, so a late alarm or forwarded signal
  // reaches no other process.
  WaitUntilEnded(pid);
  limit.Disarm();
  g_command_target = 0;
  end.time_limit = limit.Reached();
  end.exit = WaitProcess(pid);
  end.stop_signal = g_signal;
  return end;
}

// Why Slurm stopped the job run-task runs in (it forwarded SIGTERM): its time limit, when `scontrol show job` says
// so (the controller sets Reason=TimeLimit before slurmd sends the signal); else cancelled, preempted or requeued.
std::string SlurmStopReason(const RunTaskOptions& options, bool* time_limit) {
  const std::string job = Env("SLURM_JOB_ID");
  const CapturedRun run = RunAndCapture({options.scontrol, "show", "job", "-o", job});
  if (!run.started || run.exit.exit_code != 0) {
    return "Slurm stopped the job: cancelled, preempted, requeued or its time limit reached (scontrol show job " + job +
           " could not say which: " + (run.started ? LastLine(run.err) : run.error) + ")";
  }
  std::string limit;
  *time_limit = JobReachedTimeLimit(run.out, job, &limit);
  if (*time_limit) return "Slurm job " + job + " reached its time limit" + (limit.empty() ? "" : " of " + limit);
  return "the job was cancelled, preempted or requeued";
}

std::string ReadFrom(const std::string& path, std::uintmax_t offset) {
  std::ifstream in(path, std::ios::binary);
  in.seekg(static_cast<std::streamoff>(offset));
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

// The exit code and error line of a command that ended (or never started), from its output in the log; a command
// stopped at its time limit (ours or Slurm's) is recorded as "timeout".
void RecordExit(const CommandEnd& end, const RunTaskOptions& options, const std::string& output, const std::string& log,
                BatchTaskStatus* status) {
  if (!end.start_error.empty()) {
    status->exit_code = 127;
    status->error_line = end.start_error;
    return;
  }
  const ProcessExit& exit = end.exit;
  status->exit_code = exit.exit_code;
  const std::string last = exit.exit_code != 0 ? TaskErrorLine(output) : "";
  status->error_line = last;
  if (end.time_limit) {
    status->state = "timeout";
    status->error_line =
        "time limit of " + FormatSeconds(options.task_timeout_s) + " s reached (--task-timeout): " +
        (exit.signal == SIGKILL ? "killed (SIGKILL) " + FormatSeconds(options.timeout_grace_s) + " s after SIGTERM"
                                : "stopped with SIGTERM (exit " + std::to_string(exit.exit_code) + ")") +
        (last.empty() ? "" : "; last line: " + last);
    return;
  }
  if (end.stop_signal != 0) {
    std::string reason;
    if (!Env("SLURM_JOB_ID").empty()) {
      bool time_limit = false;
      reason = " (" + SlurmStopReason(options, &time_limit) + ")";
      if (time_limit) status->state = "timeout";
    }
    status->error_line = "stopped by signal " + std::to_string(end.stop_signal) + reason + ", exit " +
                         std::to_string(exit.exit_code) + (last.empty() ? "" : "; last line: " + last);
  } else if (exit.signal != 0) {
    status->error_line =
        "ended by signal " + std::to_string(exit.signal) + (last.empty() ? "" : "; last line: " + last);
  } else if (exit.exit_code != 0 && status->error_line.empty()) {
    // A command whose error line could not reach the log (a full disk) still fails with a line saying so.
    status->error_line = "exit " + std::to_string(exit.exit_code) + " with no output in " + log;
  }
}

// Publishes the work folder of a command that succeeded (exit 0) or partly succeeded (exit 3: replay with frames
// that failed or were skipped) and was neither stopped nor timed out; else the task failed (or timed out).
void PublishOrFail(const BatchLayout& layout, int index, const fs::path& work, const CommandEnd& end,
                   BatchTaskStatus* status) {
  const bool stopped = end.stop_signal != 0 || end.time_limit;
  if ((status->exit_code == 0 || status->exit_code == 3) && !stopped) {
    try {
      Publish(work, layout.task_dir(index));
      status->state = status->exit_code == 0 ? "succeeded" : "partial";
      RemoveAbandonedWork(layout, index);
    } catch (const Error& e) {
      status->state = "failed";
      status->exit_code = 1;
      status->error_line = e.what();
    }
    return;
  }
  if (status->state != "timeout") status->state = "failed";
  if (status->exit_code == 0) status->exit_code = 128 + (end.time_limit ? SIGTERM : end.stop_signal);
}

// Task i's status and result belong to line i of the manifest, so the manifest may be edited but keep its tasks.
void CheckTaskCount(const BatchLayout& layout, const BatchRecord& record, const std::vector<ManifestTask>& tasks) {
  RB_CHECK(static_cast<int>(tasks.size()) == record.num_tasks, layout.manifest(), ": has ", tasks.size(),
           " tasks, but the batch was submitted with ", record.num_tasks,
           "; results are matched to tasks by their position, so edit lines there but keep their number "
           "(submit a new batch for other tasks)");
}

}  // namespace

std::string TaskErrorLine(const std::string& output) {
  std::istringstream in(output);
  std::string line, last, last_error, last_cause;
  while (std::getline(in, line)) {
    while (!line.empty() && (line.back() == '\r' || line.back() == ' ')) line.pop_back();
    // Progress output rewrites its line with carriage returns; keep what was printed last.
    const size_t cr = line.find_last_of('\r');
    if (cr != std::string::npos) line = line.substr(cr + 1);
    if (line.empty()) continue;
    last = line;
    if (line.find("error:") != std::string::npos) {
      last_error = line;
    } else if (NamesACause(line)) {
      last_cause = line;
    }
  }
  const bool summing_up = last_error.find("more above)") != std::string::npos;
  if (!last_cause.empty() && (last_error.empty() || summing_up)) {
    return last_error.empty() ? last_cause : last_error + " (last: " + last_cause + ")";
  }
  return last_error.empty() ? last : last_error;
}

BatchTaskStatus RunBatchTask(const std::string& dir, int index, const RunTaskOptions& options) {
  options.Check();
  const BatchLayout layout(dir);
  const BatchRecord record = ReadBatchRecord(layout);
  const std::vector<ManifestTask> tasks = ReadManifest(layout.manifest());
  CheckTaskCount(layout, record, tasks);
  RB_CHECK(index >= 0 && index < static_cast<int>(tasks.size()), layout.dir, ": task ", index,
           " out of range (the manifest has ", tasks.size(), " tasks, 0-", tasks.size() - 1, ")");
  const ManifestTask& task = tasks[index];
  const std::vector<std::string> arguments =
      ResolveTaskArguments(task.arguments, record.manifest_dir, options.syntaxes);
  BatchTaskStatus status = StartingStatus(layout, task, arguments);
  try {
    CheckTaskOutputs(task, options.syntaxes, layout.manifest());
  } catch (const Error& e) {
    // A line edited in DIR/manifest.txt after submit's check: refused here, before anything is written.
    status.state = "failed";
    status.exit_code = 2;
    status.end_utc = status.start_utc;
    status.error_line = e.what();
    WriteBatchTaskStatus(layout, status);
    return status;
  }

  fs::create_directories(layout.tasks_dir());
  fs::create_directories(fs::path(layout.log_file(index)).parent_path());
  const fs::path work = fs::path(layout.tasks_dir()) / (".tmp-" + std::to_string(index) + "-" +
                                                        std::to_string(status.attempt) + "-" +
                                                        std::to_string(getpid()));
  // The running status first: when it cannot be written (a full disk), no temporary folder is left either.
  WriteBatchTaskStatus(layout, status);
  std::error_code ec;
  fs::remove_all(work, ec);
  fs::create_directories(work);

  const std::string log = layout.log_file(index);
  {
    std::ofstream header(log, std::ios::app);
    header << "==> task " << index << " (manifest line " << task.line_number << "), run " << status.run
           << ", attempt " << status.attempt << ", host " << status.host << ", " << status.start_utc << "\n"
           << "==> " << status.command << "\n";
  }
  const std::uintmax_t log_start = fs::file_size(log);

  ProcessSpec spec;
  spec.argv.push_back(options.binary.empty() ? SelfExecutable() : options.binary);
  spec.argv.insert(spec.argv.end(), arguments.begin(), arguments.end());
  spec.working_dir = work.string();
  spec.output_path = log;
  const auto start = std::chrono::steady_clock::now();
  const CommandEnd end = RunCommand(spec, options);
  status.duration_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  status.end_utc = NowUtc();

  RecordExit(end, options, ReadFrom(log, log_start), log, &status);
  PublishOrFail(layout, index, work, end, &status);
  fs::remove_all(work, ec);
  {
    std::ofstream footer(log, std::ios::app);
    footer << "==> " << status.state << ", exit " << status.exit_code << ", " << status.duration_s << " s\n";
  }
  WriteBatchTaskStatus(layout, status);
  return status;
}

bool RunTaskIsGone(const BatchTaskStatus& status) {
  if (status.state != "running" || status.pid <= 0 || status.host != HostName()) return false;
  if (!status.boot_id.empty() && status.boot_id != BootId()) return true;  // the machine restarted since
  if (!ProcessRunsHere(status.pid)) return true;
  // A process with that pid runs, but it may be another that reused the pid.
  return status.pid_start_ticks >= 0 && ProcessStartTicks(status.pid) != status.pid_start_ticks;
}

bool RunTaskRunsHere(const BatchTaskStatus& status) {
  return status.state == "running" && status.pid > 0 && status.host == HostName() && !RunTaskIsGone(status);
}

BatchReport CollectBatchReport(const std::string& dir) {
  const BatchLayout layout(dir);
  const BatchRecord record = ReadBatchRecord(layout);
  BatchReport report;
  report.dir = layout.dir;
  report.tasks = ReadManifest(layout.manifest());
  CheckTaskCount(layout, record, report.tasks);
  for (const ManifestTask& task : report.tasks) {
    std::optional<BatchTaskStatus> status;
    try {
      status = ReadBatchTaskStatus(layout, task.index);
    } catch (const Error& e) {
      // A status that cannot be read counts as failed, with why, so that resubmit runs the task again (and its
      // new status replaces the damaged one) instead of every command on the batch failing on it.
      status = BatchTaskStatus{};
      status->index = task.index;
      status->state = "failed";
      status->error_line = e.what();
    }
    std::string state = "missing";
    if (status) {
      if (status->state != "running" && !status->line.empty() && status->line != task.line) {
        state = "changed";  // its status and result are of the line that was there before DIR/manifest.txt was edited
      } else if (Published(status->state)) {
        state = fs::is_directory(layout.task_dir(task.index)) ? status->state : "missing";
      } else if (RunTaskIsGone(*status)) {
        state = "interrupted";
      } else {
        state = status->state;
      }
    }
    if (state == "succeeded") ++report.succeeded;
    if (state == "partial") ++report.partial;
    if (state == "changed") ++report.changed;
    if (state == "failed") ++report.failed;
    if (state == "timeout") ++report.timeout;
    if (state == "running") ++report.running;
    if (state == "interrupted") ++report.interrupted;
    if (state == "missing") ++report.missing;
    report.states.push_back(state);
    report.statuses.push_back(std::move(status));
  }
  return report;
}

std::vector<int> BatchReport::UnfinishedIndices() const {
  std::vector<int> indices;
  for (size_t i = 0; i < states.size(); ++i) {
    if (states[i] != "succeeded" && states[i] != "running") {
      indices.push_back(static_cast<int>(i));
    }
  }
  return indices;
}

std::string BatchReport::BriefReport() const {
  std::ostringstream out;
  out << dir << ": " << tasks.size() << " tasks: " << succeeded << " succeeded, ";
  if (partial > 0) out << partial << " partial, ";
  if (changed > 0) out << changed << " changed, ";
  out << failed << " failed, ";
  if (timeout > 0) out << timeout << " timeout, ";
  out << running << " running, ";
  if (interrupted > 0) out << interrupted << " interrupted, ";
  out << missing << " missing\n";
  const std::string here = HostName();
  for (size_t i = 0; i < tasks.size(); ++i) {
    if (states[i] == "running" && statuses[i]->job_id.empty() && !statuses[i]->host.empty() &&
        statuses[i]->host != here) {
      const BatchTaskStatus& s = *statuses[i];
      out << "running: task " << i << " (manifest line " << tasks[i].line_number << ", started " << s.start_utc
          << ") on " << s.host << " (not this host, " << here << ": cannot check whether its run-task process " << s.pid
          << " still runs); if " << s.host << " is down, 'rangebayes batch resubmit " << dir
          << " --include-running' runs it again\n";
    }
    if (states[i] == "interrupted") {
      const BatchTaskStatus& s = *statuses[i];
      out << "interrupted: task " << i << " (manifest line " << tasks[i].line_number << ", attempt " << s.attempt
          << ", started " << s.start_utc << "): its run-task process " << s.pid << " on this host is gone (killed, "
          << "or the machine restarted) before it recorded an end; unless Slurm requeues its job, 'rangebayes batch "
          << "resubmit " << dir << "' runs it again\n";
    }
    if (states[i] == "changed") {
      out << "changed: task " << i << " (manifest line " << tasks[i].line_number << "): its " << statuses[i]->state
          << " run was of the line '" << statuses[i]->line
          << "', which DIR/manifest.txt no longer has; 'rangebayes batch resubmit " << dir << "' runs the new one\n";
    }
    if (states[i] != "failed" && states[i] != "partial" && states[i] != "timeout") continue;
    const BatchTaskStatus& s = *statuses[i];
    out << states[i] << ": task " << i << " (manifest line " << tasks[i].line_number << ", exit " << s.exit_code
        << ", attempt " << s.attempt << ", host " << (s.node.empty() ? s.host : s.node) << "): " << s.error_line
        << " (log: " << dir << "/logs/" << i << ".log)\n";
  }
  return out.str();
}

std::string BatchReport::Json() const {
  json j;
  j["dir"] = dir;
  j["tasks"] = tasks.size();
  j["succeeded"] = succeeded;
  j["partial"] = partial;
  j["changed"] = changed;
  j["failed"] = failed;
  j["timeout"] = timeout;
  j["running"] = running;
  j["interrupted"] = interrupted;
  j["missing"] = missing;
  j["task"] = json::array();
  for (size_t i = 0; i < tasks.size(); ++i) {
    json t;
    t["index"] = i;
    t["line_number"] = tasks[i].line_number;
    t["line"] = tasks[i].line;
    t["state"] = states[i];
    if (statuses[i]) t["status"] = json::parse(BatchTaskStatusJson(*statuses[i]));
    j["task"].push_back(t);
  }
  return JsonText(j, 2) + "\n";
}

}  // namespace rangebayes
