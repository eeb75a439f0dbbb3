// batch/: manifest parsing and the path rule, status files, atomic publishing of a task's folder, the local
// runner, and the sbatch command line (with stand-in sbatch/squeue scripts; the real cluster is tested by
// slurm_cluster_test.sh).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <thread>

#include "batch/manifest.h"
#include "batch/submit.h"
#include "batch/task.h"
#include "core/error.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {
namespace fs = std::filesystem;

void WriteText(const std::string& path, const std::string& text) {
  fs::create_directories(fs::path(path).parent_path());
  std::ofstream(path, std::ios::binary) << text;
}

std::string ReadText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// Names in `folder` that start with `prefix`.
std::vector<std::string> Entries(const std::string& folder, const std::string& prefix) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(folder)) {
    if (e.path().filename().string().rfind(prefix, 0) == 0) names.push_back(e.path().filename().string());
  }
  return names;
}

// A manifest folder with a small mesh input (a tetrahedron).
std::string MakeManifest(const std::string& root, const std::string& lines) {
  WriteText(root + "/in/tet.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
  WriteText(root + "/tasks.txt", lines);
  return root + "/tasks.txt";
}

// An executable shell script standing in for sbatch or squeue.
// run-task as the tests call it in-process: this build's binary, signals left alone.
RunTaskOptions TestRunOptions() {
  RunTaskOptions run;
  run.binary = RB_BINARY;
  run.forward_signals = false;
  return run;
}

std::string FakeProgram(const std::string& path, const std::string& body) {
  WriteText(path, "#!/bin/sh\n" + body + "\n");
  fs::permissions(path, fs::perms::owner_all);
  return path;
}

TEST(Manifest, SplitsLikeAShellWithoutExpansions) {
  EXPECT_EQ(SplitCommandLine("smooth a.ply  b.ply --noise 0.3"),
            (std::vector<std::string>{"smooth", "a.ply", "b.ply", "--noise", "0.3"}));
  EXPECT_EQ(SplitCommandLine("smooth 'my scan.ply' \"out \\\"1\\\".ply\" x\\ y $HOME"),
            (std::vector<std::string>{"smooth", "my scan.ply", "out \"1\".ply", "x y", "$HOME"}));
  EXPECT_EQ(SplitCommandLine("info a#b.ply # a comment"), (std::vector<std::string>{"info", "a#b.ply"}));
  EXPECT_EQ(SplitCommandLine("info ''"), (std::vector<std::string>{"info", ""}));
  EXPECT_TRUE(SplitCommandLine("   # only a comment").empty());
  EXPECT_THROW(SplitCommandLine("smooth 'a.ply"), Error);
  EXPECT_THROW(SplitCommandLine("smooth \"a.ply"), Error);
  EXPECT_THROW(SplitCommandLine("smooth a.ply\\"), Error);
}

TEST(Manifest, SkipsBlankAndCommentLinesAndNumbersTasks) {
  const auto tasks = ParseManifest("# scans of monday\n\nsmooth a.ply b.ply\n   \n  replay rec --out r  \n", "m.txt");
  ASSERT_EQ(tasks.size(), 2u);
  EXPECT_EQ(tasks[0].index, 0);
  EXPECT_EQ(tasks[0].line_number, 3);
  EXPECT_EQ(tasks[1].index, 1);
  EXPECT_EQ(tasks[1].line_number, 5);
  EXPECT_EQ(tasks[1].line, "replay rec --out r");
  EXPECT_EQ(tasks[1].arguments.front(), "replay");
}

TEST(Manifest, BadLinesNameFileAndLine) {
  auto message = [](const std::string& text) {
    try {
      ParseManifest(text, "m.txt");
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(message("smooth a b\nsmooth 'x\n"), "m.txt:2: unterminated ' quote");
  EXPECT_NE(message("--noise 3\n").find("m.txt:1: a task starts with a subcommand"), std::string::npos);
  EXPECT_NE(message("rangebayes smooth a b\n").find("leave out the binary's name"), std::string::npos);
  EXPECT_NE(message("batch status d\n").find("cannot be a batch command"), std::string::npos);
  // Found by fuzz_manifest: an empty first word was taken for a subcommand.
  EXPECT_EQ(message("smooth a b\n'' x.ply\n"), "m.txt:2: a task starts with a subcommand, not an empty word");
  EXPECT_EQ(message("\"\" x.ply\n"), "m.txt:1: a task starts with a subcommand, not an empty word");
  EXPECT_NE(message("# nothing\n\n").find("m.txt: the manifest has no tasks"), std::string::npos);
}

TEST(Manifest, ExistingPathsBesideTheManifestAreInputsEverythingElseStays) {
  const TempDir dir("resolve");
  WriteText(dir.path() + "/scans/a.ply", "x");
  fs::create_directories(dir.path() + "/recordings/r1");
  const auto resolved = ResolveTaskArguments({"smooth", "scans/a.ply", "a_out.ply", "--prior=scans/a.ply", "--noise",
                                              "0.3", "/abs/x.ply", "recordings/r1", "--out", "r1"},
                                             dir.path(), {});
  EXPECT_EQ(resolved, (std::vector<std::string>{"smooth", dir.path() + "/scans/a.ply", "a_out.ply",
                                                "--prior=" + dir.path() + "/scans/a.ply", "--noise", "0.3",
                                                "/abs/x.ply", dir.path() + "/recordings/r1", "--out", "r1"}));
  EXPECT_THROW(ResolveTaskArguments({"smooth"}, "relative/dir", {}), Error);
}

TEST(Manifest, QuotesForShell) {
  EXPECT_EQ(QuoteForShell({"smooth", "/a/b.ply", "--noise=0.3"}), "smooth /a/b.ply --noise=0.3");
  EXPECT_EQ(QuoteForShell({"a b", "it's", ""}), "'a b' 'it'\\''s' ''");
}

TEST(Status, JsonRoundTripAndAtomicReplace) {
  const TempDir dir("status");
  const BatchLayout layout(dir.path());
  BatchTaskStatus s;
  s.index = 3;
  s.state = "failed";
  s.exit_code = 1;
  s.attempt = 2;
  s.run = 4;
  s.job_id = "17";
  s.host = "h";
  s.node = "node1";
  s.start_utc = "2026-12-01T20:00:00.000Z";
  s.end_utc = "2026-12-01T20:00:01.500Z";
  s.duration_s = 1.5;
  s.error_line = "rangebayes smooth: error: x.ply: cannot open";
  s.command = "smooth x.ply y.ply";
  WriteBatchTaskStatus(layout, s);
  s.exit_code = 2;
  WriteBatchTaskStatus(layout, s);
  const auto read = ReadBatchTaskStatus(layout, 3);
  ASSERT_TRUE(read.has_value());
  EXPECT_EQ(BatchTaskStatusJson(*read), BatchTaskStatusJson(s));
  EXPECT_EQ(Entries(dir.path() + "/status", "."), std::vector<std::string>{});  // no temporary left
  EXPECT_FALSE(ReadBatchTaskStatus(layout, 4).has_value());
  EXPECT_THROW(ParseBatchTaskStatus("{\"index\": 1}", "s.json"), Error);
  EXPECT_THROW(ParseBatchTaskStatus("{\"index\":1,\"state\":\"odd\",\"exit_code\":0}", "s.json"), Error);
  // A damaged number is refused, not wrapped into another int (4294967298 would read as 2).
  EXPECT_THROW(ParseBatchTaskStatus("{\"index\":4294967298,\"state\":\"failed\",\"exit_code\":0}", "s.json"), Error);
  EXPECT_THROW(ParseBatchTaskStatus("{\"index\":1,\"state\":\"failed\",\"exit_code\":0,\"run\":-4294967295}", "s.json"),
               Error);
  EXPECT_THROW(ParseBatchTaskStatus("{\"index\":1.5,\"state\":\"failed\",\"exit_code\":0}", "s.json"), Error);
}

// A batch.json whose task count or indices do not fit an int is malformed, not read as another batch.
TEST(BatchRecord, NumbersThatDoNotFitAnIntAreMalformed) {
  const TempDir dir("record-int");
  const BatchLayout layout(dir.path());
  const auto record = [&](const std::string& num_tasks, const std::string& index) {
    std::ofstream(layout.record()) << "{\"manifest_source\":\"m.txt\",\"manifest_dir\":\".\",\"binary\":\"rb\","
                                   << "\"num_tasks\":" << num_tasks << ",\"submissions\":[{\"kind\":\"local\","
                                   << "\"indices\":[" << index << "],\"workers\":1}]}";
  };
  record("2", "1");
  EXPECT_EQ(ReadBatchRecord(layout).num_tasks, 2);
  EXPECT_EQ(ReadBatchRecord(layout).submissions.at(0).indices, std::vector<int>{1});
  record("4294967298", "1");
  EXPECT_THROW(ReadBatchRecord(layout), Error);
  record("2", "4294967297");
  EXPECT_THROW(ReadBatchRecord(layout), Error);
}

// A task that failed on a file whose name is not UTF-8 (any byte but '/' and NUL is a Linux file name) has that
// name in its error line: its status is written with U+FFFD in place of the byte; json::dump threw before, and the
// task kept no status.
TEST(Status, ErrorLineThatIsNotUtf8IsWrittenWithAReplacementCharacter) {
  const TempDir dir("status-utf8");
  const BatchLayout layout(dir.path());
  BatchTaskStatus s;
  s.index = 0;
  s.state = "failed";
  s.exit_code = 1;
  s.error_line = "rangebayes replay: error: rec: frame 1: left/\xff.png is missing";
  s.command = "replay rec/\xff";
  ASSERT_NO_THROW(WriteBatchTaskStatus(layout, s));
  const auto read = ReadBatchTaskStatus(layout, 0);
  ASSERT_TRUE(read.has_value());
  EXPECT_EQ(read->error_line, "rangebayes replay: error: rec: frame 1: left/\xEF\xBF\xBD.png is missing");
  EXPECT_EQ(read->command, "replay rec/\xEF\xBF\xBD");
}

// batch.json's paths are read back to run the tasks, so one that is not UTF-8 is refused with one clear error (it
// was json's own type_error) instead of being recorded changed.
TEST(BatchRecord, PathThatIsNotUtf8IsOneClearError) {
  const TempDir dir("record-utf8");
  const BatchLayout layout(dir.path());
  BatchRecord record;
  record.manifest_source = dir.path() + "/\xff/m.txt";
  record.manifest_dir = dir.path() + "/\xff";
  record.binary = "/usr/bin/rangebayes";
  record.num_tasks = 1;
  std::string message;
  try {
    WriteBatchRecord(layout, record);
  } catch (const Error& e) {
    message = e.what();
  }
  EXPECT_NE(message.find("batch.json: cannot record the batch: a path (manifest " + record.manifest_source),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("is not UTF-8 text"), std::string::npos) << message;
  EXPECT_FALSE(fs::exists(layout.record()));
}

// A line that names no subcommand of the binary is refused at submit, with its line, before anything is written.
TEST(SubmitBatch, UnknownSubcommandIsRefusedBeforeAnythingRuns) {
  const TempDir dir("unknown");
  const std::string manifest = MakeManifest(dir.path(), "convert in/tet.obj tet.ply\nnotacommand foo\n");
  BatchSubmitOptions options;
  options.binary = RB_BINARY;
  options.local_workers = 1;
  options.subcommands = {"convert", "smooth"};
  const std::string out = dir.path() + "/out";
  try {
    SubmitBatch(manifest, out, options);
    ADD_FAILURE() << "a manifest with an unknown subcommand was submitted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(":2: 'notacommand' is not a rangebayes subcommand (convert, smooth)"),
              std::string::npos)
        << e.what();
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST(RunTask, PublishesOnlyOnSuccessAndReplacesAnOlderResult) {
  const TempDir dir("runtask");
  const std::string manifest =
      MakeManifest(dir.path(), "convert in/tet.obj tet.ply\nconvert in/missing.obj m.ply\n");
  BatchSubmitOptions options;
  options.binary = RB_BINARY;
  options.local_workers = 1;
  const std::string out = dir.path() + "/out";
  SubmitBatch(manifest, out, options);
  const BatchLayout layout(out);
  EXPECT_TRUE(fs::exists(out + "/tasks/0/tet.ply"));
  EXPECT_FALSE(fs::exists(out + "/tasks/1"));
  EXPECT_EQ(Entries(out + "/tasks", "."), std::vector<std::string>{});  // no temporary folder left behind

  const auto failed = ReadBatchTaskStatus(layout, 1);
  ASSERT_TRUE(failed.has_value());
  EXPECT_EQ(failed->state, "failed");
  EXPECT_EQ(failed->exit_code, 1);
  EXPECT_EQ(failed->attempt, 0);
  EXPECT_NE(failed->error_line.find("rangebayes convert: error:"), std::string::npos) << failed->error_line;
  EXPECT_NE(failed->error_line.find("missing.obj"), std::string::npos) << failed->error_line;
  EXPECT_FALSE(failed->host.empty());
  EXPECT_FALSE(failed->end_utc.empty());

  const BatchReport report = CollectBatchReport(out);
  EXPECT_EQ(report.succeeded, 1);
  EXPECT_EQ(report.failed, 1);
  EXPECT_EQ(report.UnfinishedIndices(), std::vector<int>{1});
  EXPECT_NE(report.BriefReport().find("failed: task 1 (manifest line 2, exit 1"), std::string::npos)
      << report.BriefReport();

  // The fix: the input appears beside the manifest; the path rule finds it on the next run.
  fs::copy_file(dir.path() + "/in/tet.obj", dir.path() + "/in/missing.obj");
  const RunTaskOptions run = TestRunOptions();
  const BatchTaskStatus fixed = RunBatchTask(out, 1, run);
  EXPECT_EQ(fixed.state, "succeeded") << fixed.error_line;
  EXPECT_EQ(fixed.run, 2);
  EXPECT_TRUE(fs::exists(out + "/tasks/1/m.ply"));

  // Running a finished task again replaces its folder as a whole.
  WriteText(out + "/tasks/0/stale.txt", "from an older run");
  EXPECT_EQ(RunBatchTask(out, 0, run).state, "succeeded");
  EXPECT_TRUE(fs::exists(out + "/tasks/0/tet.ply"));
  EXPECT_FALSE(fs::exists(out + "/tasks/0/stale.txt"));
  EXPECT_EQ(Entries(out + "/tasks", "."), std::vector<std::string>{});
  EXPECT_EQ(CollectBatchReport(out).succeeded, 2);
  EXPECT_THROW(RunBatchTask(out, 2, run), Error);
  // The log keeps every run.
  EXPECT_NE(ReadText(out + "/logs/1.log").find("run 2"), std::string::npos);
}

// `rangebayes batch run-task OUT 0` in a process group of its own (so that a test can signal it and its command
// together), with SIGHUP ignored from the start when `ignore_hangup` (as under nohup). Its pid, or -1.
pid_t StartRunTaskInItsOwnGroup(const std::string& out, bool ignore_hangup) {
  const pid_t child = fork();
  if (child == 0) {
    setpgid(0, 0);
    if (ignore_hangup) signal(SIGHUP, SIG_IGN);
    execl(RB_BINARY, RB_BINARY, "batch", "run-task", out.c_str(), "0", static_cast<char*>(nullptr));
    _exit(127);
  }
  if (child > 0) setpgid(child, child);
  return child;
}

// A node dies mid-task: run-task and its command are killed with SIGKILL together (one process group) while
// the command is writing its outputs. No result is published, the status still says running, and once the
// job has left the queue a resubmit takes the task again and its run completes (removing the dead run's
// temporary folder).
TEST(RunTask, KilledMidTaskLeavesNoResultAndAResubmitCompletes) {
  const TempDir dir("sigkill");
  // A live-path replay at a twentieth of the recorded speed: seconds, writing one frame's outputs after another.
  const std::string recording = std::string(RB_SOURCE_DIR) + "/recordings/synth_planes_320x240";
  const std::string manifest = MakeManifest(
      dir.path(), "replay " + recording + " --out frames --live-path --speed recorded --speed-factor 0.05\n");
  BatchSubmitOptions options;
  options.binary = RB_BINARY;
  options.sbatch = FakeProgram(dir.path() + "/sbatch", "echo '41;c'");
  options.squeue = FakeProgram(dir.path() + "/squeue", "echo 41");
  const std::string out = dir.path() + "/out";
  SubmitBatch(manifest, out, options);

  const pid_t child = StartRunTaskInItsOwnGroup(out, false);
  ASSERT_GE(child, 0);
  // Wait until the command has written some of its outputs in its temporary folder.
  bool writing = false;
  for (int i = 0; i < 1200 && !writing; ++i) {
    usleep(50 * 1000);
    if (!fs::is_directory(out + "/tasks")) continue;
    for (const std::string& tmp : Entries(out + "/tasks", ".tmp-0-")) {
      const fs::path frames = fs::path(out) / "tasks" / tmp / "frames";
      std::error_code ec;
      writing = writing || (fs::is_directory(frames, ec) && !fs::is_empty(frames, ec));
    }
  }
  kill(-child, SIGKILL);
  int wait_status = 0;
  waitpid(child, &wait_status, 0);
  ASSERT_TRUE(writing) << "the task never started writing; log:\n" << ReadText(out + "/logs/0.log");
  ASSERT_TRUE(WIFSIGNALED(wait_status));

  EXPECT_FALSE(fs::exists(out + "/tasks/0"));  // nothing half-done is published
  EXPECT_EQ(Entries(out + "/tasks", ".tmp-0-").size(), 1u);
  // Its status still says running, but the run-task process that wrote it, on this host, is gone.
  const BatchReport killed = CollectBatchReport(out);
  EXPECT_EQ(killed.states.at(0), "interrupted");
  EXPECT_EQ(killed.succeeded, 0);
  EXPECT_EQ(killed.interrupted, 1);
  EXPECT_EQ(killed.running, 0);
  EXPECT_NE(killed.BriefReport().find("1 tasks: 0 succeeded, 0 failed, 0 running, 1 interrupted, 0 missing"),
            std::string::npos)
      << killed.BriefReport();
  EXPECT_NE(killed.BriefReport().find("interrupted: task 0 (manifest line 1"), std::string::npos);
  EXPECT_EQ(nlohmann::json::parse(killed.Json())["interrupted"], 1);

  EXPECT_THROW(ResubmitBatch(out, options), Error);  // the job is still listed by squeue
  options.squeue = FakeProgram(dir.path() + "/squeue", "echo 7");
  EXPECT_EQ(ResubmitBatch(out, options).indices, std::vector<int>{0});
  // What the resubmitted array task runs.
  const RunTaskOptions run = TestRunOptions();
  const BatchTaskStatus done = RunBatchTask(out, 0, run);
  EXPECT_EQ(done.state, "succeeded") << done.error_line;
  EXPECT_EQ(done.run, 2);
  EXPECT_TRUE(fs::is_directory(out + "/tasks/0/frames"));
  EXPECT_EQ(Entries(out + "/tasks", "."), std::vector<std::string>{});
  EXPECT_EQ(CollectBatchReport(out).succeeded, 1);
}

// Options of a local batch with one worker, and the batch of two converts it has run in DIR/out.
BatchSubmitOptions OneLocalWorker() {
  BatchSubmitOptions options;
  options.binary = RB_BINARY;
  options.local_workers = 1;
  return options;
}
std::string RunTwoConverts(const TempDir& dir) {
  const std::string manifest = MakeManifest(dir.path(), "convert in/tet.obj a.ply\nconvert in/tet.obj b.ply\n");
  const std::string out = dir.path() + "/out";
  SubmitBatch(manifest, out, OneLocalWorker());
  return out;
}

// A local batch whose run-task was killed (SIGKILL: its status still says running, with the pid of a
// process that is gone): resubmit takes the task again and completes it.
TEST(LocalRunner, ResubmitTakesATaskWhoseRunTaskIsGone) {
  const TempDir dir("local_killed");
  const BatchSubmitOptions options = OneLocalWorker();
  const std::string out = RunTwoConverts(dir);
  fs::remove_all(out + "/tasks/1");
  BatchTaskStatus killed = *ReadBatchTaskStatus(BatchLayout(out), 1);
  killed.state = "running";
  const pid_t gone = fork();
  if (gone == 0) _exit(0);
  waitpid(gone, nullptr, 0);
  killed.pid = static_cast<int>(gone);
  WriteBatchTaskStatus(BatchLayout(out), killed);
  EXPECT_TRUE(RunTaskIsGone(killed));
  BatchTaskStatus alive = killed;
  alive.pid = static_cast<int>(getpid());
  alive.pid_start_ticks = ProcessStartTicks(static_cast<int>(getpid()));
  ASSERT_GT(alive.pid_start_ticks, 0);
  EXPECT_FALSE(RunTaskIsGone(alive));
  // A live process that reused the pid: another start time, or a status from before the machine restarted.
  BatchTaskStatus reused = alive;
  reused.pid_start_ticks = alive.pid_start_ticks + 1;
  EXPECT_TRUE(RunTaskIsGone(reused));
  reused = alive;
  reused.boot_id = "a-boot-before";
  EXPECT_TRUE(RunTaskIsGone(reused));
  alive.host = "another-host";
  alive.pid = static_cast<int>(gone);
  EXPECT_FALSE(RunTaskIsGone(alive));  // another machine's process cannot be checked from here
  EXPECT_EQ(CollectBatchReport(out).states, (std::vector<std::string>{"succeeded", "interrupted"}));
  WriteBatchTaskStatus(BatchLayout(out), alive);
  EXPECT_EQ(CollectBatchReport(out).states, (std::vector<std::string>{"succeeded", "running"}));
  EXPECT_THROW(ResubmitBatch(out, options), Error);  // nothing to resubmit: task 1 may still run elsewhere
  WriteBatchTaskStatus(BatchLayout(out), killed);

  EXPECT_EQ(ResubmitBatch(out, options).indices, std::vector<int>{1});
  EXPECT_TRUE(fs::exists(out + "/tasks/1/b.ply"));
  EXPECT_EQ(CollectBatchReport(out).succeeded, 2);
}

// A task of a --local run on another host that died still reads running, as its process cannot be checked from
// here: status names it and its host, saying so; resubmit leaves it unless told --include-running, which is
// still refused for a task whose run-task is alive on this host.
TEST(LocalRunner, ARunningTaskOfAnotherHostIsNamedAndTakenOnlyWithIncludeRunning) {
  const TempDir dir("other_host");
  BatchSubmitOptions options = OneLocalWorker();
  const std::string out = RunTwoConverts(dir);
  fs::remove_all(out + "/tasks/1");
  BatchTaskStatus elsewhere = *ReadBatchTaskStatus(BatchLayout(out), 1);
  elsewhere.state = "running";
  elsewhere.host = "lab-node-7";
  elsewhere.pid = 4242;
  elsewhere.start_utc = "2026-12-07T10:00:00.000Z";
  WriteBatchTaskStatus(BatchLayout(out), elsewhere);
  const BatchReport report = CollectBatchReport(out);
  EXPECT_EQ(report.states, (std::vector<std::string>{"succeeded", "running"}));
  EXPECT_NE(report.BriefReport().find("running: task 1 (manifest line 2, started 2026-12-07T10:00:00.000Z) on "
                                      "lab-node-7 (not this host, "),
            std::string::npos)
      << report.BriefReport();
  EXPECT_NE(report.BriefReport().find("cannot check whether its run-task process 4242 still runs); if lab-node-7 is "
                                      "down, 'rangebayes batch resubmit " +
                                      BatchLayout(out).dir + " --include-running' runs it again"),
            std::string::npos)
      << report.BriefReport();
  try {
    ResubmitBatch(out, options);
    ADD_FAILURE() << "a task that may still run on lab-node-7 was resubmitted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("nothing to resubmit (1 succeeded, 1 running; a task that reads running on a "
                                         "host that is down is taken by resubmit --include-running)"),
              std::string::npos)
        << e.what();
  }
  // A Slurm task reads running on its node while its job runs: no line for it.
  BatchTaskStatus in_job = elsewhere;
  in_job.job_id = "41";
  WriteBatchTaskStatus(BatchLayout(out), in_job);
  EXPECT_EQ(CollectBatchReport(out).BriefReport().find("running: task"), std::string::npos);
  // Alive here: refused even when told.
  BatchTaskStatus here = elsewhere;
  const BatchTaskStatus mine = RunBatchTask(out, 0, TestRunOptions());
  here.host = mine.host;
  here.pid = static_cast<int>(getpid());
  here.pid_start_ticks = ProcessStartTicks(here.pid);
  here.boot_id = mine.boot_id;
  WriteBatchTaskStatus(BatchLayout(out), here);
  options.include_running = true;
  try {
    ResubmitBatch(out, options);
    ADD_FAILURE() << "a task whose run-task runs here was resubmitted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("task 1 still runs on this host (run-task pid " + std::to_string(getpid())),
              std::string::npos)
        << e.what();
  }
  WriteBatchTaskStatus(BatchLayout(out), elsewhere);
  EXPECT_EQ(ResubmitBatch(out, options).indices, std::vector<int>{1});
  EXPECT_EQ(CollectBatchReport(out).succeeded, 2);
}

// A status file that cannot be read (cut to nothing when a machine crashed) made every command on the batch fail
// on it (status, resubmit, run-task of that very task): it counts as failed, saying why, and a resubmit runs
// that task again, whose new status replaces it.
TEST(LocalRunner, ADamagedStatusCountsAsFailedAndIsRunAgain) {
  const TempDir dir("damaged_status");
  const BatchSubmitOptions options = OneLocalWorker();
  const std::string out = RunTwoConverts(dir);
  const std::string status_file = BatchLayout(out).status_file(1);
  std::ofstream(status_file, std::ios::trunc) << "{\"index\": 1, \"sta";
  const BatchReport damaged = CollectBatchReport(out);
  EXPECT_EQ(damaged.states, (std::vector<std::string>{"succeeded", "failed"}));
  EXPECT_NE(damaged.BriefReport().find("failed: task 1 (manifest line 2"), std::string::npos) << damaged.BriefReport();
  EXPECT_NE(damaged.BriefReport().find("malformed task status"), std::string::npos) << damaged.BriefReport();
  EXPECT_EQ(ResubmitBatch(out, options).indices, std::vector<int>{1});
  const BatchReport again = CollectBatchReport(out);
  EXPECT_EQ(again.succeeded, 2);
  EXPECT_EQ(again.statuses.at(1)->run, 1);  // the damaged status's count of runs is lost
}

// A flat grid of n×n vertices as OBJ text: an input whose converted output is large (about 1.7 MB as OBJ for
// n = 150).
std::string GridObj(int n) {
  std::ostringstream s;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) s << "v " << x * 0.001 << ' ' << y * 0.001 << " 0.125\n";
  }
  for (int y = 0; y + 1 < n; ++y) {
    for (int x = 0; x + 1 < n; ++x) {
      const int v = y * n + x + 1;
      s << "f " << v << ' ' << v + 1 << ' ' << v + n << "\nf " << v + 1 << ' ' << v + n + 1 << ' ' << v + n << "\n";
    }
  }
  return s.str();
}

// The lines of a batch report that name a failed task.
int FailedLines(const std::string& report) {
  int lines = 0;
  std::istringstream in(report);
  for (std::string line; std::getline(in, line);) lines += line.rfind("failed: task ", 0) == 0 ? 1 : 0;
  return lines;
}

// The disk fills up while a task writes its output: the batch folder lies on a 4 MiB tmpfs that a filler file
// has filled but for about half a MiB, and the middle task's output (1.7 MB) does not fit. That task fails
// with the command's own error line (ENOSPC), nothing of it is published or left behind, and the tasks before
// and after it succeed; once the filler is removed, a resubmit runs exactly that task and it completes.
// Needs mount(2) (root in a container that allows it); skips otherwise.
TEST(RunTask, FullDiskDuringOutputLosesOnlyTheTaskInFlightAndSaysSo) {
  if (geteuid() != 0) GTEST_SKIP() << "mounting a small tmpfs needs root";
  const TempDir dir("full_disk");
  const std::string disk = dir.path() + "/disk";
  fs::create_directories(disk);
  if (mount("tmpfs", disk.c_str(), "tmpfs", MS_NOSUID | MS_NODEV, "size=4m,mode=0700") != 0) {
    GTEST_SKIP() << "mount -t tmpfs is not permitted here (" << std::strerror(errno) << ")";
  }
  struct Unmount {
    std::string path;
    ~Unmount() { umount2(path.c_str(), MNT_DETACH); }
  } unmount{disk};

  const std::string manifest = MakeManifest(
      dir.path(), "convert in/tet.obj a.ply\nconvert in/grid.obj grid.obj\nconvert in/tet.obj c.ply\n");
  WriteText(dir.path() + "/in/grid.obj", GridObj(150));
  const std::string filler = disk + "/filler";
  {
    std::ofstream out(filler, std::ios::binary);
    const std::string chunk(64 * 1024, 'x');
    for (int i = 0; i < 56; ++i) out << chunk;  // 3.5 MiB of the 4
    ASSERT_TRUE(out.good());
  }
  BatchSubmitOptions options;
  options.binary = RB_BINARY;
  options.local_workers = 1;  // one task in flight at a time
  const std::string out = disk + "/out";
  std::vector<BatchTaskStatus> ended;
  options.on_task_end = [&](const BatchTaskStatus& s) { ended.push_back(s); };
  SubmitBatch(manifest, out, options);

  ASSERT_EQ(ended.size(), 3u);
  EXPECT_EQ(ended[0].state, "succeeded") << ended[0].error_line;
  EXPECT_EQ(ended[2].state, "succeeded") << ended[2].error_line;
  const BatchTaskStatus& full = ended[1];
  EXPECT_EQ(full.state, "failed");
  EXPECT_EQ(full.exit_code, 1);
  EXPECT_NE(full.error_line.find("rangebayes convert: error:"), std::string::npos) << full.error_line;
  EXPECT_NE(full.error_line.find(std::strerror(ENOSPC)), std::string::npos) << full.error_line;
  EXPECT_FALSE(fs::exists(out + "/tasks/1"));
  EXPECT_EQ(Entries(out + "/tasks", "."), std::vector<std::string>{});  // no half output left on the disk
  EXPECT_EQ(ReadText(out + "/tasks/0/a.ply"), ReadText(out + "/tasks/2/c.ply"));
  EXPECT_GT(fs::file_size(out + "/tasks/0/a.ply"), 0u);
  const BatchReport report = CollectBatchReport(out);
  EXPECT_EQ(report.succeeded, 2);
  EXPECT_EQ(report.failed, 1);
  EXPECT_EQ(FailedLines(report.BriefReport()), 1) << report.BriefReport();
  const auto recorded = ReadBatchTaskStatus(BatchLayout(out), 1);
  ASSERT_TRUE(recorded.has_value());
  EXPECT_EQ(recorded->error_line, full.error_line);

  // No room left at all: run-task cannot even record that the task runs. It says so, and leaves no temporary
  // status file or task folder behind; the task's last status stays as it was.
  {
    std::ofstream rest(disk + "/rest", std::ios::binary);
    const std::string chunk(64 * 1024, 'x');
    for (int i = 0; i < 64 && rest.good(); ++i) rest << chunk << std::flush;
    EXPECT_FALSE(rest.good());  // the disk is full
  }
  try {
    RunBatchTask(out, 1, TestRunOptions());
    ADD_FAILURE() << "no error on a full disk";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("status/1.json"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(std::strerror(ENOSPC)), std::string::npos) << e.what();
  }
  EXPECT_EQ(Entries(out + "/tasks", "."), std::vector<std::string>{});
  EXPECT_EQ(Entries(out + "/status", "."), std::vector<std::string>{});
  EXPECT_EQ(ReadBatchTaskStatus(BatchLayout(out), 1)->error_line, full.error_line);

  fs::remove(disk + "/rest");
  fs::remove(filler);
  ended.clear();
  EXPECT_EQ(ResubmitBatch(out, options).indices, std::vector<int>{1});
  ASSERT_EQ(ended.size(), 1u);
  EXPECT_EQ(ended[0].state, "succeeded") << ended[0].error_line;
  // The premise: the output is larger than the half MiB the filler had left.
  EXPECT_GT(fs::file_size(out + "/tasks/1/grid.obj"), 1024u * 1024u);
  EXPECT_EQ(CollectBatchReport(out).succeeded, 3);
  EXPECT_EQ(Entries(out + "/tasks", "."), std::vector<std::string>{});
}

// An output named like a path beside the manifest, here a link to /dev/full (where every write fails with
// ENOSPC): it was taken for an input and the task wrote through the link (the only way this test once had to
// fill a disk without mounting one). The output is the task's own file now; the run-task of the binary knows
// convert's OUT from convert's own options.
TEST(RunTask, AnOutputNamedLikeAFileBesideTheManifestIsTheTasksOwn) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full on this machine";
  const TempDir dir("dev_full");
  const std::string manifest = MakeManifest(dir.path(), "convert in/tet.obj full.ply\nconvert in/tet.obj b.ply\n");
  fs::create_symlink("/dev/full", dir.path() + "/full.ply");
  BatchSubmitOptions options;
  options.binary = RB_BINARY;
  options.local_workers = 1;
  const std::string out = dir.path() + "/out";
  SubmitBatch(manifest, out, options);
  const BatchReport report = CollectBatchReport(out);
  EXPECT_EQ(report.states, (std::vector<std::string>{"succeeded", "succeeded"})) << report.BriefReport();
  EXPECT_GT(fs::file_size(out + "/tasks/0/full.ply"), 0u);
  EXPECT_EQ(ReadText(out + "/tasks/0/full.ply"), ReadText(out + "/tasks/1/b.ply"));
  EXPECT_TRUE(fs::is_symlink(dir.path() + "/full.ply"));
  EXPECT_EQ(Entries(out + "/tasks", "."), std::vector<std::string>{});
}

TEST(LocalRunner, RunsEveryTaskOnWorkersAndReportsEach) {
  const TempDir dir("local");
  std::string lines;
  for (int i = 0; i < 5; ++i) lines += "convert in/tet.obj t" + std::to_string(i) + ".off\n";
  const std::string manifest = MakeManifest(dir.path(), "# five conversions\n" + lines);
  BatchSubmitOptions options;
  options.binary = RB_BINARY;
  options.local_workers = 2;
  std::set<int> ended;
  options.on_task_end = [&](const BatchTaskStatus& s) {
    EXPECT_EQ(s.state, "succeeded") << s.error_line;
    ended.insert(s.index);
  };
  const BatchSubmitSummary summary = SubmitBatch(manifest, dir.path() + "/out", options);
  EXPECT_EQ(summary.submissions.at(0).kind, "local");
  EXPECT_EQ(ended, (std::set<int>{0, 1, 2, 3, 4}));
  const BatchReport report = CollectBatchReport(dir.path() + "/out");
  EXPECT_EQ(report.succeeded, 5);
  for (int i = 0; i < 5; ++i) EXPECT_TRUE(fs::exists(dir.path() + "/out/tasks/" + std::to_string(i) + "/t" +
                                                     std::to_string(i) + ".off"));
  EXPECT_EQ(ReadText(dir.path() + "/out/manifest.txt"), ReadText(manifest));
  EXPECT_THROW(ResubmitBatch(dir.path() + "/out", options), Error);  // nothing left to do
  EXPECT_THROW(SubmitBatch(manifest, dir.path() + "/out", options), Error);  // already a batch
}

// What apps/cmd_batch.cpp derives from convert's, smooth's and replay's own options (IN OUT positionals; --out).
SubcommandSyntaxes TestSyntaxes() {
  SubcommandSyntaxes syntaxes;
  syntaxes["convert"].positionals = {{1, false, false}, {1, true, false}};
  syntaxes["smooth"].value_options = {"--noise", "--png", "--tolerance", "--threads"};
  syntaxes["smooth"].output_options = {"--png"};
  syntaxes["smooth"].positionals = {{1, false, false}, {1, true, false}};
  syntaxes["replay"].value_options = {"--out", "-o", "--count"};
  syntaxes["replay"].output_options = {"--out", "-o"};
  syntaxes["replay"].positionals = {{1, false, false}};
  syntaxes["decimate"].value_options = {"--out", "-o", "--target-faces"};
  syntaxes["decimate"].output_options = {"--out", "-o"};
  syntaxes["decimate"].positionals = {{-1, false, true}};
  return syntaxes;
}

// Runs a shell command line; its exit code, and what it printed (stdout and stderr) in *output.
int RunShell(const std::string& command, std::string* output) {
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  if (pipe == nullptr) return -1;
  char buffer[4096];
  output->clear();
  for (size_t n; (n = fread(buffer, 1, sizeof(buffer), pipe)) > 0;) output->append(buffer, n);
  const int status = pclose(pipe);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(Manifest, OutputWordsFollowEachSubcommandsSyntax) {
  const SubcommandSyntaxes syntaxes = TestSyntaxes();
  EXPECT_EQ(OutputWordIndices({"convert", "a.obj", "b.ply"}, syntaxes), (std::vector<size_t>{2}));
  EXPECT_EQ(OutputWordIndices({"smooth", "--noise", "0.3", "a.obj", "--png", "p.png", "b.ply"}, syntaxes),
            (std::vector<size_t>{5, 6}));
  EXPECT_EQ(OutputWordIndices({"replay", "rec", "--count", "2", "--out", "r"}, syntaxes), (std::vector<size_t>{5}));
  EXPECT_EQ(OutputWordIndices({"replay", "rec", "--out=r"}, syntaxes), (std::vector<size_t>{2}));
  EXPECT_EQ(OutputWordIndices({"replay", "rec", "-or"}, syntaxes), (std::vector<size_t>{2}));
  EXPECT_EQ(OutputWordIndices({"decimate", "a.obj", "b.obj", "--target-faces", "9"}, syntaxes),
            (std::vector<size_t>{2}));
  EXPECT_EQ(OutputWordIndices({"decimate", "p0.obj", "p1.obj", "--out", "anim"}, syntaxes), (std::vector<size_t>{4}));
  // Without a syntax: --out and -o.
  EXPECT_EQ(OutputWordIndices({"other", "x", "-o", "y"}, syntaxes), (std::vector<size_t>{3}));
}

// The reviewer's case: result.ply exists beside the manifest, and was made absolute as if it were an input, so two
// tasks wrote the lab's own file. An output word is never resolved.
TEST(Manifest, AnOutputThatExistsBesideTheManifestStaysInTheTaskFolder) {
  const TempDir dir("resolve_out");
  WriteText(dir.path() + "/tet.obj", "x");
  WriteText(dir.path() + "/result.ply", "the lab's own file");
  EXPECT_EQ(ResolveTaskArguments({"convert", "tet.obj", "result.ply"}, dir.path(), TestSyntaxes()),
            (std::vector<std::string>{"convert", dir.path() + "/tet.obj", "result.ply"}));
}

TEST(SubmitBatch, OutputsOutsideTheTaskFolderAreRefusedNamingLineAndWord) {
  const TempDir dir("outputs");
  BatchSubmitOptions options = OneLocalWorker();
  options.syntaxes = TestSyntaxes();
  auto refusal = [&](const std::string& lines) {
    const std::string manifest = MakeManifest(dir.path(), lines);
    try {
      SubmitBatch(manifest, dir.path() + "/out", options);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string shared = dir.path() + "/same.ply";
  std::string message = refusal("convert in/tet.obj a.ply\nconvert in/tet.obj " + shared + "\n");
  EXPECT_NE(message.find("tasks.txt:2: the output '" + shared + "' is an absolute path"), std::string::npos) << message;
  message = refusal("replay rec --out=../../elsewhere\n");
  EXPECT_NE(message.find("tasks.txt:1: the output '../../elsewhere' leaves the task's folder"), std::string::npos)
      << message;
  message = refusal("smooth in/tet.obj s.ply --png /tmp/p.png\n");
  EXPECT_NE(message.find("tasks.txt:1: the output '/tmp/p.png' is an absolute path"), std::string::npos) << message;
  EXPECT_FALSE(fs::exists(dir.path() + "/out"));
  EXPECT_FALSE(fs::exists(shared));

  // Both tasks name result.ply, which exists beside the manifest: each writes its own, the lab's file stays.
  WriteText(dir.path() + "/in/block.obj", "v 0 0 0\nv 2 0 0\nv 0 2 0\nf 1 2 3\n");
  WriteText(dir.path() + "/result.ply", "the lab's own file");
  const std::string manifest =
      MakeManifest(dir.path(), "convert in/tet.obj result.ply\nconvert in/block.obj result.ply\n");
  SubmitBatch(manifest, dir.path() + "/out", options);
  EXPECT_EQ(ReadText(dir.path() + "/result.ply"), "the lab's own file");
  EXPECT_EQ(CollectBatchReport(dir.path() + "/out").succeeded, 2);
  EXPECT_NE(ReadText(dir.path() + "/out/tasks/0/result.ply"), ReadText(dir.path() + "/out/tasks/1/result.ply"));
}

// The binary derives each subcommand's outputs from its own options: `batch submit` refuses the reviewer's line.
TEST(SubmitBatch, TheCliRefusesAnAbsoluteOutput) {
  const TempDir dir("outputs_cli");
  const std::string manifest =
      MakeManifest(dir.path(), "convert in/tet.obj a.ply\ndecimate in/tet.obj " + dir.path() + "/d.obj\n");
  std::string output;
  EXPECT_EQ(RunShell(std::string(RB_BINARY) + " batch submit " + manifest + " --out " + dir.path() + "/out --local 1",
                     &output),
            1);
  EXPECT_NE(output.find("tasks.txt:2: the output '" + dir.path() + "/d.obj' is an absolute path"), std::string::npos)
      << output;
  EXPECT_FALSE(fs::exists(dir.path() + "/out"));
  // Every option that writes is an output, --plot too (it was resolved beside the manifest like an input).
  const std::string plot =
      MakeManifest(dir.path(), "learn-prior --pairs in/tet.obj --out p.yaml --plot " + dir.path() + "/p.png\n");
  EXPECT_EQ(
      RunShell(std::string(RB_BINARY) + " batch submit " + plot + " --out " + dir.path() + "/out --local 1", &output),
      1);
  EXPECT_NE(output.find("tasks.txt:1: the output '" + dir.path() + "/p.png' is an absolute path"), std::string::npos)
      << output;
}

// A line of DIR/manifest.txt edited after its task ran: the old result is not counted for the new line.
TEST(LocalRunner, AnEditedLineIsChangedAndRerunAndAnotherTaskCountIsRefused) {
  const TempDir dir("edited");
  const BatchSubmitOptions options = OneLocalWorker();
  const std::string out = RunTwoConverts(dir);
  WriteText(out + "/manifest.txt", "convert in/tet.obj a.ply\nconvert in/tet.obj b2.off\n");
  const BatchReport edited = CollectBatchReport(out);
  EXPECT_EQ(edited.states, (std::vector<std::string>{"succeeded", "changed"}));
  EXPECT_EQ(edited.changed, 1);
  EXPECT_NE(edited.BriefReport().find("changed: task 1 (manifest line 2): its succeeded run was of the line "
                                      "'convert in/tet.obj b.ply'"),
            std::string::npos)
      << edited.BriefReport();
  EXPECT_EQ(ResubmitBatch(out, options).indices, std::vector<int>{1});
  EXPECT_TRUE(fs::exists(out + "/tasks/1/b2.off"));
  EXPECT_EQ(CollectBatchReport(out).succeeded, 2);

  WriteText(out + "/manifest.txt", "convert in/tet.obj a.ply\nconvert in/tet.obj b2.off\ninfo in/tet.obj\n");
  for (const auto& call :
       std::vector<std::function<void()>>{[&] { CollectBatchReport(out); }, [&] { ResubmitBatch(out, options); },
                                          [&] { RunBatchTask(out, 0, TestRunOptions()); }}) {
    try {
      call();
      ADD_FAILURE() << "a manifest with another number of tasks was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("manifest.txt: has 3 tasks, but the batch was submitted with 2"),
                std::string::npos)
          << e.what();
    }
  }
}

// A second local run of one batch while the first runs its task: refused, naming the first (here, this test's
// own pid: the first runs on a thread). The task is a stand-in that waits on a FIFO.
TEST(LocalRunner, ASecondRunOfTheBatchIsRefusedWhileOneRuns) {
  const TempDir dir("lock");
  const std::string started = dir.path() + "/started.fifo", go = dir.path() + "/go.fifo";
  ASSERT_EQ(mkfifo(started.c_str(), 0600), 0);
  ASSERT_EQ(mkfifo(go.c_str(), 0600), 0);
  // Read-write: opening never blocks, and each end has a peer for the stand-in's opens.
  const int started_fd = open(started.c_str(), O_RDWR);
  const int go_fd = open(go.c_str(), O_RDWR);
  BatchSubmitOptions options = OneLocalWorker();
  // Only its first run waits, so that a second run let through ends (and the test fails) instead of waiting too.
  options.binary = FakeProgram(
      dir.path() + "/task", "mkdir " + dir.path() + "/first || exit 0\necho started > " + started + "\nread x < " + go);
  const std::string manifest = MakeManifest(dir.path(), "convert in/tet.obj a.ply\n");
  const std::string out = dir.path() + "/out";
  std::thread first([&] { SubmitBatch(manifest, out, options); });
  struct Release {
    int fd;
    std::thread* thread;
    ~Release() {
      EXPECT_EQ(write(fd, "go\n", 3), 3);
      thread->join();
    }
  } release{go_fd, &first};
  char line[16];
  ASSERT_GT(read(started_fd, line, sizeof(line)), 0);  // the first run's task runs
  try {
    ResubmitBatch(out, options);
    ADD_FAILURE() << "a second run of the batch was let through";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("another batch submit or resubmit of this batch is running (pid " +
                                         std::to_string(getpid()) + " on "),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(SubmitBatch(manifest, out, options), Error);
}

// A published result removes the temporary folders of earlier runs that were killed, but not one whose run-task
// still runs on this host (another run of the same task, started meanwhile).
TEST(RunTask, AbandonedWorkOfALiveRunStays) {
  const TempDir dir("abandoned");
  const std::string out = RunTwoConverts(dir);
  const pid_t alive = fork();
  if (alive == 0) {
    pause();
    _exit(0);
  }
  const pid_t gone = fork();
  if (gone == 0) _exit(0);
  waitpid(gone, nullptr, 0);
  const std::string live_work = out + "/tasks/.tmp-1-0-" + std::to_string(alive);
  const std::string dead_work = out + "/tasks/.tmp-1-0-" + std::to_string(gone);
  WriteText(live_work + "/b.ply", "being written");
  WriteText(dead_work + "/b.ply", "left by a killed run");
  const BatchTaskStatus done = RunBatchTask(out, 1, TestRunOptions());
  kill(alive, SIGKILL);
  waitpid(alive, nullptr, 0);
  EXPECT_EQ(done.state, "succeeded") << done.error_line;
  EXPECT_TRUE(fs::exists(live_work + "/b.ply"));
  EXPECT_FALSE(fs::exists(dead_work));
}

// A run-task whose process has ended but is not reaped yet (a zombie) is gone, as kill(pid, 0) does not say.
TEST(RunTask, AZombieRunTaskIsGone) {
  const TempDir dir("zombie");
  const std::string out = RunTwoConverts(dir);
  const pid_t zombie = fork();
  if (zombie == 0) _exit(0);
  siginfo_t info{};
  ASSERT_EQ(waitid(P_PID, zombie, &info, WEXITED | WNOWAIT), 0);  // ended, left unreaped
  BatchTaskStatus status = *ReadBatchTaskStatus(BatchLayout(out), 1);
  status.state = "running";
  status.pid = static_cast<int>(zombie);
  status.pid_start_ticks = -1;
  EXPECT_TRUE(RunTaskIsGone(status));
  waitpid(zombie, nullptr, 0);
}

// Under nohup (SIGHUP ignored) a hangup of the whole process group does not end the task: run-task keeps the
// signal ignored and so does its command. The command is `info` of a FIFO, which waits for the mesh to arrive.
TEST(RunTask, AnIgnoredHangupStaysIgnored) {
  const TempDir dir("nohup");
  const std::string manifest = MakeManifest(dir.path(), "info in/stuck.obj\n");
  ASSERT_EQ(mkfifo((dir.path() + "/in/stuck.obj").c_str(), 0600), 0);
  BatchSubmitOptions options;
  options.binary = RB_BINARY;
  options.sbatch = FakeProgram(dir.path() + "/sbatch", "echo 3");
  const std::string out = dir.path() + "/out";
  SubmitBatch(manifest, out, options);
  const pid_t child = StartRunTaskInItsOwnGroup(out, true);
  ASSERT_GE(child, 0);
  struct sigaction ignore_pipe {
  }, old_pipe{};
  ignore_pipe.sa_handler = SIG_IGN;
  sigaction(SIGPIPE, &ignore_pipe, &old_pipe);
  {
    // Opening blocks until `info` opens the FIFO: the task runs.
    std::ofstream mesh(dir.path() + "/in/stuck.obj", std::ios::binary);
    kill(-child, SIGHUP);
    mesh << ReadText(dir.path() + "/in/tet.obj");
  }
  sigaction(SIGPIPE, &old_pipe, nullptr);
  int wait_status = 0;
  waitpid(child, &wait_status, 0);
  const auto status = ReadBatchTaskStatus(BatchLayout(out), 0);
  ASSERT_TRUE(status.has_value());
  EXPECT_EQ(status->state, "succeeded") << status->error_line;
  EXPECT_TRUE(WIFEXITED(wait_status) && WEXITSTATUS(wait_status) == 0);
}

// replay exits 3 when some frames failed or were skipped and the others went through: the task is "partial",
// its results are published, its error line names the skipped frame, and resubmit runs it again.
TEST(RunTask, APartialReplayKeepsItsResultsAndIsRerun) {
  const TempDir dir("partial");
  std::string output;
  ASSERT_EQ(RunShell(std::string(RB_BINARY) + " synth --width 64 --height 48 --frames 2 --seed 1 --out " + dir.path() +
                         "/rec",
                     &output),
            0)
      << output;
  WriteText(dir.path() + "/rec/left/000001.png", "garbage");
  const std::string manifest =
      MakeManifest(dir.path(), "replay rec --out r --num-disparities 16 --tolerance fast --no-decimate\n");
  BatchSubmitOptions options = OneLocalWorker();
  options.syntaxes = TestSyntaxes();
  const std::string out = dir.path() + "/out";
  SubmitBatch(manifest, out, options);
  const auto status = ReadBatchTaskStatus(BatchLayout(out), 0);
  ASSERT_TRUE(status.has_value());
  EXPECT_EQ(status->state, "partial") << status->error_line;
  EXPECT_EQ(status->exit_code, 3);
  EXPECT_NE(status->error_line.find("frame 1 skipped"), std::string::npos) << status->error_line;
  EXPECT_TRUE(fs::exists(out + "/tasks/0/r/summary.json"));
  const BatchReport report = CollectBatchReport(out);
  EXPECT_EQ(report.states, std::vector<std::string>{"partial"});
  EXPECT_EQ(report.partial, 1);
  EXPECT_NE(report.BriefReport().find("1 tasks: 0 succeeded, 1 partial, 0 failed"), std::string::npos)
      << report.BriefReport();
  EXPECT_NE(report.BriefReport().find("partial: task 0 (manifest line 1, exit 3"), std::string::npos)
      << report.BriefReport();
  EXPECT_NE(report.BriefReport().find("/logs/0.log"), std::string::npos) << report.BriefReport();
  EXPECT_EQ(ResubmitBatch(out, options).indices, std::vector<int>{0});
  EXPECT_EQ(CollectBatchReport(out).partial, 1);
  EXPECT_TRUE(fs::exists(out + "/tasks/0/r/summary.json"));
}

TEST(RunTask, TheErrorLineNamesTheRealCause) {
  // A full disk under replay: only the frame's line says why; the final error line merely sums up.
  const std::string full = std::string("frame 1: sinks: rec_0/raw/000001.ply: write failed: ") + std::strerror(ENOSPC);
  EXPECT_EQ(TaskErrorLine("recording r (2 frames)\n" + full +
                          "\n1 frames in, 0 results, 1 failed, 0 skipped\n"
                          "results in rec_0: shaded/\n"),
            full);
  const std::string first = "frame 0: sinks: rec_0/raw/000000.ply: write failed: " + std::string(std::strerror(ENOSPC));
  EXPECT_EQ(TaskErrorLine(first + "\n" + full + "\nrangebayes replay: error: no frame went through the pipeline: " +
                          first + " (and 1 more above)\n"),
            "rangebayes replay: error: no frame went through the pipeline: " + first +
                " (and 1 more above) (last: " + full + ")");
  // A partial replay: the skipped frame, not the summary or the last line.
  EXPECT_EQ(TaskErrorLine("1 frames in, 1 results, 0 failed, 1 skipped, 0 dropped\nframe 1 skipped: rp: frame 1: "
                          "left/000001.png is corrupt\nresults in rec: shaded/\n"),
            "frame 1 skipped: rp: frame 1: left/000001.png is corrupt");
  // An "error:" line that says why wins; else the last line.
  EXPECT_EQ(TaskErrorLine("frame 2 skipped: x\nrangebayes smooth: error: a.ply: cannot open\n"),
            "rangebayes smooth: error: a.ply: cannot open");
  EXPECT_EQ(TaskErrorLine("one\ntwo\r\n"), "two");
}

// batch status: 0 when every task succeeded, 3 when one needs a rerun, 4 while one is missing (not started).
TEST(LocalRunner, StatusExitCodeSaysWhetherEveryTaskSucceeded) {
  const TempDir dir("status_rc");
  const std::string out = RunTwoConverts(dir);
  const std::string status = std::string(RB_BINARY) + " batch status " + out;
  std::string output;
  EXPECT_EQ(RunShell(status, &output), 0) << output;
  fs::remove(BatchLayout(out).status_file(1));
  EXPECT_EQ(RunShell(status, &output), 4) << output;
  BatchTaskStatus failed;
  failed.index = 1;
  failed.state = "failed";
  failed.exit_code = 1;
  WriteBatchTaskStatus(BatchLayout(out), failed);
  EXPECT_EQ(RunShell(status, &output), 3) << output;
  EXPECT_EQ(RunShell(status + " --json", &output), 3) << output;
}

// A task that hangs (`info` of a FIFO nobody writes) past --task-timeout on a local worker: its command is stopped,
// the task is recorded as timeout (not failed), nothing of it is published, the next task still runs, status
// lists it, and resubmit runs it again like a failed task.
TEST(LocalRunner, ATaskPastItsTimeLimitIsStoppedAsTimeoutAndTheBatchGoesOn) {
  const TempDir dir("timeout");
  const std::string manifest = MakeManifest(dir.path(), "info in/stuck.obj\nconvert in/tet.obj b.ply\n");
  ASSERT_EQ(mkfifo((dir.path() + "/in/stuck.obj").c_str(), 0600), 0);
  BatchSubmitOptions options = OneLocalWorker();
  options.task_timeout_s = 0.5;
  std::vector<std::string> ended;
  options.on_task_end = [&](const BatchTaskStatus& s) { ended.push_back(s.state); };
  const std::string out = dir.path() + "/out";
  SubmitBatch(manifest, out, options);
  EXPECT_EQ(ended, (std::vector<std::string>{"timeout", "succeeded"}));
  const auto status = ReadBatchTaskStatus(BatchLayout(out), 0);
  ASSERT_TRUE(status.has_value());
  EXPECT_EQ(status->state, "timeout");
  EXPECT_EQ(status->exit_code, 128 + SIGTERM);
  EXPECT_NE(status->error_line.find("time limit of 0.5 s reached (--task-timeout): stopped with SIGTERM"),
            std::string::npos)
      << status->error_line;
  EXPECT_FALSE(fs::exists(out + "/tasks/0"));
  EXPECT_EQ(Entries(out + "/tasks", "."), std::vector<std::string>{});
  EXPECT_EQ(ReadBatchRecord(BatchLayout(out)).submissions.at(0).task_timeout_s, 0.5);

  const BatchReport report = CollectBatchReport(out);
  EXPECT_EQ(report.states, (std::vector<std::string>{"timeout", "succeeded"}));
  EXPECT_EQ(report.timeout, 1);
  EXPECT_EQ(report.failed, 0);
  EXPECT_NE(report.BriefReport().find("2 tasks: 1 succeeded, 0 failed, 1 timeout, 0 running, 0 missing"),
            std::string::npos)
      << report.BriefReport();
  EXPECT_NE(report.BriefReport().find("timeout: task 0 (manifest line 1, exit 143"), std::string::npos)
      << report.BriefReport();
  EXPECT_EQ(nlohmann::json::parse(report.Json())["timeout"], 1);
  std::string output;
  EXPECT_EQ(RunShell(std::string(RB_BINARY) + " batch status " + out, &output), 3) << output;

  // Retried like a failed task: the input is there now, and the resubmit (with no time limit) completes it.
  fs::remove(dir.path() + "/in/stuck.obj");
  fs::copy_file(dir.path() + "/in/tet.obj", dir.path() + "/in/stuck.obj");
  EXPECT_EQ(ResubmitBatch(out, OneLocalWorker()).indices, std::vector<int>{0});
  EXPECT_EQ(CollectBatchReport(out).succeeded, 2);
}

// A command that ignores SIGTERM at its time limit is killed with SIGKILL after the grace, with whatever it started
// (its process group).
TEST(RunTask, ACommandThatIgnoresSigtermIsKilledWithItsChildrenAfterTheGrace) {
  const TempDir dir("timeout_kill");
  const std::string out = RunTwoConverts(dir);
  RunTaskOptions run = TestRunOptions();
  const std::string child_pid = dir.path() + "/child.pid";
  run.binary = FakeProgram(dir.path() + "/stubborn", "trap '' TERM\nsleep 1000 &\necho $! > " + child_pid +
                                                         ".tmp\nmv " + child_pid + ".tmp " + child_pid + "\nwait");
  run.task_timeout_s = 0.2;
  run.timeout_grace_s = 0.2;
  const BatchTaskStatus status = RunBatchTask(out, 1, run);
  EXPECT_EQ(status.state, "timeout");
  EXPECT_EQ(status.exit_code, 128 + SIGKILL);
  EXPECT_NE(status.error_line.find("time limit of 0.2 s reached (--task-timeout): killed (SIGKILL) 0.2 s after "
                                   "SIGTERM"),
            std::string::npos)
      << status.error_line;
  // The command's child got SIGKILL too: wait until it has ended (it was orphaned, so init reaps it).
  const int pid = std::stoi(ReadText(child_pid));
  bool ended = false;
  for (int i = 0; i < 200 && !ended; ++i) {
    ended = ProcessStartTicks(pid) < 0 ||
            ReadText("/proc/" + std::to_string(pid) + "/stat").find(") Z ") != std::string::npos;
    if (!ended) usleep(10 * 1000);
  }
  EXPECT_TRUE(ended) << "the command's child " << pid << " outlived its time limit";
  if (!ended) kill(pid, SIGKILL);
}

TEST(RunTask, TimeLimitIsPositiveAndFinite) {
  const TempDir dir("timeout_check");
  const std::string manifest = MakeManifest(dir.path(), "convert in/tet.obj a.ply\n");
  for (const double bad : {-1.0, std::nan(""), HUGE_VAL, kMaxTaskTimeoutS * 2}) {
    BatchSubmitOptions options;
    options.task_timeout_s = bad;
    EXPECT_THROW(options.Check(), Error) << bad;
  }
  BatchSubmitOptions options;
  options.task_timeout_s = 90;
  options.Check();
  EXPECT_EQ(SlurmTimeMinutes(90), 3);  // 90 s and the 10 s grace: 2 minutes, and one for run-task
  EXPECT_EQ(SbatchCommand(BatchLayout("/b"), ArrayJob{0, {0}, ""}, options, "/b/job.sh").at(8), "--time=3");
  // Slurm's own time limit is then ours.
  options.slurm_args = {"--cpus-per-task=2", "--time=1:00:00"};
  try {
    options.Check();
    ADD_FAILURE() << "--task-timeout and --slurm-arg=--time were both taken";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--task-timeout sets sbatch's --time (3 min for 90 s); give it without "
                                         "--slurm-arg=--time=1:00:00"),
              std::string::npos)
        << e.what();
  }
  options.slurm_args = {"--time-min=10"};
  options.Check();
  std::string output;
  EXPECT_EQ(RunShell(std::string(RB_BINARY) + " batch submit " + manifest + " --out " + dir.path() +
                         "/out --local 1 --task-timeout nan",
                     &output),
            2)
      << output;
  EXPECT_FALSE(fs::exists(dir.path() + "/out"));
  EXPECT_NE(output.find("--task-timeout"), std::string::npos) << output;
}

// `rangebayes batch run-task OUT 0` as a Slurm job's script runs it (SLURM_JOB_ID=77, scontrol as `scontrol_body`
// on PATH), stopped by SIGTERM to its process group while its command (`info` of the FIFO in/stuck.obj) waits, as
// slurmstepd stops a job. The task's status after.
BatchTaskStatus StopRunTaskAsSlurmDoes(const TempDir& dir, const std::string& out, const std::string& scontrol_body) {
  const std::string bin = dir.path() + "/bin";
  fs::remove_all(bin);
  fs::create_directories(bin);
  FakeProgram(bin + "/scontrol", scontrol_body);
  const pid_t child = fork();
  if (child == 0) {
    setpgid(0, 0);
    setenv("SLURM_JOB_ID", "77", 1);
    setenv("PATH", (bin + ":/usr/bin:/bin").c_str(), 1);
    execl(RB_BINARY, RB_BINARY, "batch", "run-task", out.c_str(), "0", static_cast<char*>(nullptr));
    _exit(127);
  }
  if (child > 0) setpgid(child, child);
  struct sigaction ignore_pipe {
  }, old_pipe{};
  ignore_pipe.sa_handler = SIG_IGN;
  sigaction(SIGPIPE, &ignore_pipe, &old_pipe);
  {
    // Opening blocks until `info` opens the FIFO: the task runs. It waits for a mesh until it is stopped.
    std::ofstream mesh(dir.path() + "/in/stuck.obj", std::ios::binary);
    kill(-child, SIGTERM);
    waitpid(child, nullptr, 0);
  }
  sigaction(SIGPIPE, &old_pipe, nullptr);
  return ReadBatchTaskStatus(BatchLayout(out), 0).value_or(BatchTaskStatus{});
}

// Slurm stops a job at its time limit as it stops a cancelled one (SIGTERM, SIGKILL after KillWait); run-task asks
// scontrol, whose line of the job says Reason=TimeLimit by then, and records "timeout", not a cancellation.
TEST(RunTask, SlurmsTimeLimitIsATimeoutNotACancellation) {
  const TempDir dir("slurm_time_limit");
  const std::string manifest = MakeManifest(dir.path(), "info in/stuck.obj\n");
  ASSERT_EQ(mkfifo((dir.path() + "/in/stuck.obj").c_str(), 0600), 0);
  BatchSubmitOptions options;
  options.binary = RB_BINARY;
  options.sbatch = FakeProgram(dir.path() + "/sbatch", "echo 76");
  const std::string out = dir.path() + "/out";
  SubmitBatch(manifest, out, options);
  // What Slurm 22.05's scontrol printed for a job at its time limit, while its processes had SIGTERM (abridged);
  // 76 is the array's own id, also listed.
  const std::string job_line =
      "JobId=77 ArrayJobId=76 ArrayTaskId=0 JobName=job.sh JobState=COMPLETING "
      "Reason=TimeLimit Dependency=(null) RunTime=00:01:27 TimeLimit=00:01:00";
  EXPECT_TRUE(JobReachedTimeLimit(job_line + "\n", "77", nullptr));
  EXPECT_FALSE(JobReachedTimeLimit(job_line + "\n", "7", nullptr));
  EXPECT_FALSE(JobReachedTimeLimit("JobId=76 JobState=RUNNING Reason=None\n" + job_line + "\n", "76", nullptr));
  EXPECT_TRUE(JobReachedTimeLimit("JobId=5 JobState=TIMEOUT Reason=None\n", "5", nullptr));

  BatchTaskStatus status = StopRunTaskAsSlurmDoes(dir, out, "echo '" + job_line + "'");
  EXPECT_EQ(status.state, "timeout");
  EXPECT_EQ(status.exit_code, 128 + SIGTERM);
  EXPECT_NE(status.error_line.find("stopped by signal 15 (Slurm job 77 reached its time limit of 00:01:00)"),
            std::string::npos)
      << status.error_line;
  EXPECT_EQ(CollectBatchReport(out).timeout, 1);

  // Cancelled (scancel), and scontrol failing: each says so, the latter naming every possibility.
  status = StopRunTaskAsSlurmDoes(dir, out, "echo 'JobId=77 JobState=CANCELLED Reason=None TimeLimit=00:01:00'");
  EXPECT_EQ(status.state, "failed");
  EXPECT_NE(status.error_line.find("stopped by signal 15 (the job was cancelled, preempted or requeued)"),
            std::string::npos)
      << status.error_line;
  status =
      StopRunTaskAsSlurmDoes(dir, out, "echo 'slurm_load_jobs error: Unable to contact slurm controller' >&2\nexit 1");
  EXPECT_EQ(status.state, "failed");
  EXPECT_NE(status.error_line.find("cancelled, preempted, requeued or its time limit reached (scontrol show job 77 "
                                   "could not say which"),
            std::string::npos)
      << status.error_line;
  EXPECT_EQ(status.run, 3);
}

// A mistyped option, a value an option refuses, or a missing argument in a manifest line: `batch submit` parses
// every line with the binary's own parser first and refuses the batch with one line naming the manifest line, before
// anything is written; so does resubmit after DIR/manifest.txt was edited. An input that does not exist yet is not
// the parser's business (smooth's input is read when the task runs).
TEST(SubmitBatch, AMistypedOptionIsRefusedNamingItsLineBeforeAnythingIsWritten) {
  const TempDir dir("mistyped");
  const std::string submit = std::string(RB_BINARY) + " batch submit " + dir.path() + "/tasks.txt --local 1 --out ";
  const auto refused = [&](const std::string& lines, const std::string& expected) {
    MakeManifest(dir.path(), lines);
    std::string output;
    EXPECT_EQ(RunShell(submit + dir.path() + "/refused", &output), 1) << output;
    EXPECT_NE(output.find("rangebayes batch submit: error: " + dir.path() + "/tasks.txt:" + expected),
              std::string::npos)
        << output;
    EXPECT_EQ(std::count(output.begin(), output.end(), '\n'), 1) << output;
    EXPECT_FALSE(fs::exists(dir.path() + "/refused"));
  };
  refused("convert in/tet.obj a.ply\n# smooth\n\nsmooth in/tet.obj b.ply --tolerence fast\n",
          "4: smooth: The following arguments were not expected: fast --tolerence (see rangebayes smooth --help)");
  refused("smooth in/tet.obj b.ply --noise -1\n", "1: smooth: --noise: ");
  refused("convert in/tet.obj\n", "1: convert: OUT is required");
  refused(
      "calibrate noise --target plane in/tet.obj --out n.yaml --bogus\n",
      "1: calibrate noise: The following argument was not expected: --bogus (see rangebayes calibrate noise --help)");
  refused("info in/tet.obj --help\n", "1: info: --help shows help instead of running the task");

  MakeManifest(dir.path(), "convert in/tet.obj a.ply\nsmooth later/missing.obj b.ply --tolerance fast\n");
  std::string output;
  EXPECT_EQ(RunShell(submit + dir.path() + "/out", &output), 3) << output;
  EXPECT_NE(output.find("2 tasks: 1 succeeded, 1 failed"), std::string::npos) << output;
  WriteText(dir.path() + "/out/manifest.txt",
            "convert in/tet.obj a.ply\nsmooth in/tet.obj b.ply --tolerance fastest\n");
  EXPECT_EQ(RunShell(std::string(RB_BINARY) + " batch resubmit " + dir.path() + "/out --local 1", &output), 1)
      << output;
  EXPECT_NE(output.find(dir.path() + "/out/manifest.txt:2: smooth: --tolerance: "), std::string::npos) << output;
  EXPECT_EQ(ReadBatchRecord(BatchLayout(dir.path() + "/out")).submissions.size(), 1u);
}

// A manifest saved with a UTF-8 byte order mark (and CRLF line ends) by a Windows editor.
TEST(Manifest, AByteOrderMarkIsSkipped) {
  const auto tasks = ParseManifest("\xEF\xBB\xBFinfo a.obj\r\nconvert a.obj b.ply\r\n", "m.txt");
  ASSERT_EQ(tasks.size(), 2u);
  EXPECT_EQ(tasks[0].arguments, (std::vector<std::string>{"info", "a.obj"}));
  EXPECT_EQ(tasks[0].line, "info a.obj");
}

// More tasks than the cluster's MaxArraySize allows as array indices: split into one array per MaxArraySize task
// indices, each job's script given its offset (array index + offset = task index), each recorded; with
// --max-parallel each waits for the one before. Resubmit checks every job of the batch in the queue and splits
// likewise; cancel cancels those still queued; a refusal after the first job names what Slurm has accepted.
TEST(Slurm, ABatchAboveMaxArraySizeIsSplitIntoArrayJobs) {
  const TempDir dir("max_array");
  std::string lines;
  for (int i = 0; i < 5; ++i) lines += "convert in/tet.obj t" + std::to_string(i) + ".ply\n";
  const std::string manifest = MakeManifest(dir.path(), lines);
  BatchSubmitOptions options;
  options.binary = RB_BINARY;
  options.max_parallel = 1;
  // Records its arguments and accepts each job as 41, 42, ...
  options.sbatch = FakeProgram(dir.path() + "/sbatch", "echo \"$@\" >> " + dir.path() + "/sbatch.args\nn=$(wc -l < " +
                                                           dir.path() + "/sbatch.args)\necho $((40 + n))");
  options.scontrol = FakeProgram(dir.path() + "/scontrol",
                                 "echo 'Configuration data as of 2026-12-07T14:00:00'\n"
                                 "echo 'MaxArraySize            = 2'\necho 'MaxJobCount             = 10000'");
  const std::string out = dir.path() + "/out";
  const BatchSubmitSummary summary = SubmitBatch(manifest, out, options);
  EXPECT_EQ(summary.JobIds(), "41 42 43");
  EXPECT_EQ(summary.BriefReport(),
            "submitted 5 tasks as 3 Slurm jobs (MaxArraySize 2): 41 (tasks 0-1), 42 (tasks "
            "2-3), 43 (task 4) in " +
                BatchLayout(out).dir);
  const std::string job_script = BatchLayout(out).slurm_dir() + "/job.sh";
  std::istringstream args(ReadText(dir.path() + "/sbatch.args"));
  std::string line;
  std::getline(args, line);
  EXPECT_NE(line.find("--array=0-1%1 "), std::string::npos) << line;
  EXPECT_EQ(line.find("--dependency"), std::string::npos) << line;
  EXPECT_EQ(line.substr(line.size() - job_script.size()), job_script) << line;
  std::getline(args, line);
  EXPECT_NE(line.find("--array=0-1%1 "), std::string::npos) << line;
  EXPECT_NE(line.find("--dependency=afterany:41 "), std::string::npos) << line;
  EXPECT_EQ(line.substr(line.size() - job_script.size() - 2), job_script + " 2") << line;
  std::getline(args, line);
  EXPECT_NE(line.find("--array=0%1 --requeue"), std::string::npos) << line;
  EXPECT_NE(line.find("--dependency=afterany:42 "), std::string::npos) << line;
  EXPECT_EQ(line.substr(line.size() - job_script.size() - 2), job_script + " 4") << line;
  const BatchRecord record = ReadBatchRecord(BatchLayout(out));
  ASSERT_EQ(record.submissions.size(), 3u);
  EXPECT_EQ(record.submissions[1].job_id, "42");
  EXPECT_EQ(record.submissions[1].array_offset, 2);
  EXPECT_EQ(record.submissions[1].indices, (std::vector<int>{2, 3}));

  // What Slurm runs for array index 1 of job 42: task 3.
  std::string output;
  ASSERT_EQ(RunShell("SLURM_ARRAY_TASK_ID=1 sh " + job_script + " 2", &output), 0) << output;
  EXPECT_TRUE(fs::exists(out + "/tasks/3/t3.ply")) << output;

  // Resubmit: refused while any of the jobs is queued; then tasks 0-2 and 4, split likewise.
  options.squeue = FakeProgram(dir.path() + "/squeue", "echo 7\necho 43");
  try {
    ResubmitBatch(out, options);
    ADD_FAILURE() << "resubmit went ahead while job 43 of the batch was queued";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("Slurm job 43 of this batch is still queued or running"), std::string::npos)
        << e.what();
  }
  options.squeue = FakeProgram(dir.path() + "/squeue", "echo 7");
  const BatchSubmitSummary again = ResubmitBatch(out, options);
  EXPECT_EQ(again.indices, (std::vector<int>{0, 1, 2, 4}));
  EXPECT_EQ(again.BriefReport(),
            "submitted 4 tasks as 3 Slurm jobs (MaxArraySize 2): 44 (tasks 0-1), 45 (task 2), "
            "46 (task 4) in " +
                BatchLayout(out).dir);

  // Cancel: the batch's jobs that squeue still lists, in one scancel.
  options.scancel = FakeProgram(dir.path() + "/scancel", "echo \"$@\" > " + dir.path() + "/scancel.args");
  options.squeue = FakeProgram(dir.path() + "/squeue", "echo 7\necho 45\necho 46\necho 41");
  EXPECT_EQ(CancelBatch(out, options), (std::vector<std::string>{"41", "45", "46"}));
  EXPECT_EQ(ReadText(dir.path() + "/scancel.args"), "41 45 46\n");
  options.squeue = FakeProgram(dir.path() + "/squeue", "echo 7");
  EXPECT_THROW(CancelBatch(out, options), Error);

  // sbatch refusing the second job: the first is recorded, and the message says so.
  options.sbatch = FakeProgram(dir.path() + "/sbatch2", "[ -e " + dir.path() +
                                                            "/once ] && { echo 'sbatch: error: "
                                                            "QOSMaxSubmitJobPerUserLimit' >&2; exit 1; }\ntouch " +
                                                            dir.path() + "/once\necho 50");
  try {
    SubmitBatch(manifest, dir.path() + "/out2", options);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("sbatch refused the job for tasks 2-3 (exit 1): sbatch: error: "
                                         "QOSMaxSubmitJobPerUserLimit; Slurm accepted the jobs before it, 50 (tasks "
                                         "0-1), recorded in "),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(ReadBatchRecord(BatchLayout(dir.path() + "/out2")).submissions.size(), 1u);

  EXPECT_EQ(ParseMaxArraySize("MaxArraySize            = 1001\n"), 1001);
  EXPECT_FALSE(ParseMaxArraySize("MaxJobCount = 5\n").has_value());
  // Within the limit, or with the limit unknown: one array, array index = task index.
  EXPECT_EQ(SplitArrayJobs({3, 1}, 4).size(), 1u);
  EXPECT_EQ(SplitArrayJobs({5, 1}, std::nullopt).at(0).indices, (std::vector<int>{1, 5}));
  const std::vector<ArrayJob> jobs = SplitArrayJobs({250, 3, 120, 199}, 100);
  ASSERT_EQ(jobs.size(), 3u);
  EXPECT_EQ(jobs[1].offset, 100);
  EXPECT_EQ(jobs[1].indices, (std::vector<int>{120, 199}));
  EXPECT_EQ(jobs[2].offset, 200);
}

TEST(Slurm, ArraySpecAndSbatchCommandLine) {
  EXPECT_EQ(ArraySpec({0, 1, 2, 3}, 0), "0-3");
  EXPECT_EQ(ArraySpec({9, 1, 3, 4, 5}, 2), "1,3-5,9%2");
  EXPECT_EQ(ArraySpec({7}, 0), "7");
  EXPECT_THROW(ArraySpec({}, 0), Error);
  BatchSubmitOptions options;
  options.partition = "gpu";
  options.max_parallel = 4;
  options.slurm_args = {"--time=10", "--cpus-per-task=2"};
  const BatchLayout layout("/data/b");
  EXPECT_EQ(
      SbatchCommand(layout, ArrayJob{0, {0, 1, 2}, ""}, options, "/data/b/slurm/job.sh"),
      (std::vector<std::string>{"sbatch", "--parsable", "--job-name=rangebayes-batch", "--array=0-2%4", "--requeue",
                                "--open-mode=append", "--output=/data/b/slurm/%A_%a.out", "--chdir=/data/b",
                                "--partition=gpu", "--time=10", "--cpus-per-task=2", "/data/b/slurm/job.sh"}));
  EXPECT_EQ(ParseSbatchJobId("12\n"), "12");
  EXPECT_EQ(ParseSbatchJobId("Submitted\n345;cluster\n"), "345");
  EXPECT_THROW(ParseSbatchJobId(""), Error);
  EXPECT_THROW(ParseSbatchJobId("Submitted batch job 12\n"), Error);
}

TEST(Slurm, MissingOrRefusingSbatchIsOneClearError) {
  const TempDir dir("sbatch");
  const std::string manifest = MakeManifest(dir.path(), "convert in/tet.obj a.ply\n");
  BatchSubmitOptions options;
  options.binary = RB_BINARY;
  options.sbatch = dir.path() + "/no/sbatch";
  try {
    SubmitBatch(manifest, dir.path() + "/out1", options);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cannot run sbatch"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--local N"), std::string::npos) << e.what();
  }
  options.sbatch = FakeProgram(dir.path() + "/refuse",
                               "echo 'sbatch: error: invalid partition specified: nope' >&2\n"
                               "echo 'sbatch: error: Batch job submission failed: Invalid partition name' >&2\n"
                               "exit 1");
  try {
    SubmitBatch(manifest, dir.path() + "/out2", options);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "sbatch refused the job (exit 1): sbatch: error: Batch job submission failed: Invalid partition name");
  }
  // After the refusal the same folder can be submitted again.
  options.sbatch = FakeProgram(dir.path() + "/accept", "echo 5");
  EXPECT_EQ(SubmitBatch(manifest, dir.path() + "/out2", options).JobIds(), "5");
}

TEST(Slurm, SubmitRecordsTheJobAndResubmitTakesExactlyTheUnfinished) {
  const TempDir dir("resubmit");
  const std::string manifest =
      MakeManifest(dir.path(), "convert in/tet.obj a.ply\nconvert in/tet.obj b.ply\nconvert in/tet.obj c.ply\n"
                               "convert in/tet.obj d.ply\n");
  BatchSubmitOptions options;
  options.binary = RB_BINARY;
  // Records its arguments and accepts the job.
  options.sbatch = FakeProgram(dir.path() + "/sbatch", "echo \"$@\" >> " + dir.path() + "/sbatch.args\necho '41;c'");
  options.squeue = FakeProgram(dir.path() + "/squeue", "echo 41");
  const std::string out = dir.path() + "/out";
  const BatchSubmitSummary first = SubmitBatch(manifest, out, options);
  EXPECT_EQ(first.JobIds(), "41");
  EXPECT_NE(ReadText(out + "/slurm/job.sh")
                .find("batch run-task " + BatchLayout(out).dir + " \"$((${1:-0} + SLURM_ARRAY_TASK_ID))\""),
            std::string::npos)
      << ReadText(out + "/slurm/job.sh");
  EXPECT_EQ(ReadBatchRecord(BatchLayout(out)).submissions.at(0).job_id, "41");

  // Task 1 ran and succeeded; 0 failed; 2 was killed while running (its status says running); 3 never started.
  const RunTaskOptions run = TestRunOptions();
  ASSERT_EQ(RunBatchTask(out, 1, run).state, "succeeded");
  BatchTaskStatus failed;
  failed.index = 0;
  failed.state = "failed";
  failed.exit_code = 1;
  WriteBatchTaskStatus(BatchLayout(out), failed);
  BatchTaskStatus killed;
  killed.index = 2;
  killed.state = "running";
  WriteBatchTaskStatus(BatchLayout(out), killed);
  EXPECT_EQ(CollectBatchReport(out).UnfinishedIndices(), (std::vector<int>{0, 3}));

  EXPECT_THROW(ResubmitBatch(out, options), Error);  // squeue still lists job 41
  options.squeue = FakeProgram(dir.path() + "/squeue", "echo 7");
  options.max_parallel = 1;
  const BatchSubmitSummary second = ResubmitBatch(out, options);
  EXPECT_EQ(second.indices, (std::vector<int>{0, 2, 3}));
  EXPECT_NE(ReadText(dir.path() + "/sbatch.args").find("--array=0,2-3%1"), std::string::npos)
      << ReadText(dir.path() + "/sbatch.args");
  EXPECT_EQ(ReadBatchRecord(BatchLayout(out)).submissions.size(), 2u);
}

}  // namespace
}  // namespace rangebayes
