// `rangebayes replay` as a user runs it: the bundled recording end to end, and bad input.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <string>
#include <thread>
#include <utility>

#include "tests/apps/run_binary.h"
#include "tests/capture/test_util.h"

namespace rangebayes {
namespace {
namespace fs = std::filesystem;

constexpr const char* kBundled = "recordings/synth_planes_320x240";

// Copies the first `frames` entries of the bundled recording into `folder` (index lines and images).
void CopyBundled(const std::string& folder, int frames) {
  fs::create_directories(folder + "/left");
  fs::create_directories(folder + "/right");
  const std::string src = std::string(RB_SOURCE_DIR) + "/" + kBundled;
  fs::copy_file(src + "/rig.yaml", folder + "/rig.yaml");
  std::ifstream in(src + "/frames.csv");
  std::ofstream out(folder + "/frames.csv");
  std::string line;
  for (int i = 0; i <= frames && std::getline(in, line); ++i) out << line << "\n";
  for (int i = 0; i < frames; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", i);
    fs::copy_file(src + "/left/" + name, folder + "/left/" + name);
    fs::copy_file(src + "/right/" + name, folder + "/right/" + name);
  }
}

// The whole of a text file ("" when it does not exist).
std::string ReadAll(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Replaces the first `from` in FOLDER/frames.csv by `to`.
void EditIndex(const std::string& folder, const std::string& from, const std::string& to) {
  std::string text = ReadAll(folder + "/frames.csv");
  const size_t at = text.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  text.replace(at, from.size(), to);
  std::ofstream(folder + "/frames.csv", std::ios::binary) << text;
}

int CountLines(const std::string& path) {
  std::ifstream in(path);
  int lines = 0;
  for (std::string line; std::getline(in, line);) ++lines;
  return lines;
}

TEST(ReplayCli, BundledRecordingEndToEnd) {
  const TempDir dir("cli_replay");
  const RunResult r = RunRangebayes(std::string("replay ") + kBundled + " --count 2 --downsample 4 --tolerance fast --out " +
                                    dir.path() + "/out");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* f : {"raw/000000.ply", "smoothed/000001.ply", "decimated/000001.obj", "depth/000000.png",
                        "shaded/000001.png", "results.csv", "summary.json"}) {
    EXPECT_TRUE(fs::exists(dir.path() + "/out/" + f)) << f;
  }
  EXPECT_NE(r.output.find("frames/s end to end"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("triangulate"), std::string::npos);
  EXPECT_NE(r.output.find("shaded/ (raw | smoothed | decimated renderings), depth/, raw/ (PLY), smoothed/ (PLY), "
                          "decimated/ (OBJ), results.csv"),
            std::string::npos)
      << r.output;
}

// The model `calibrate noise` writes by default (the block matcher) is the one replay's space-time matcher takes:
// it runs that configuration over the window's frames. It was refused ("fitted for matcher 'block', not
// 'spacetime'"), and a model of `rangebayes spacetime`'s static-scene preset was taken instead.
TEST(ReplayCli, TheSpaceTimeMatcherTakesTheBlockMatchersNoiseModel) {
  const TempDir dir("cli_replay_noise");
  const auto model = [&](const std::string& matcher) {
    const std::string path = dir.path() + "/" + matcher + ".yaml";
    std::ofstream(path) << "%YAML:1.0\n---\nform: constant\nsigma_px: 0.3\nmatcher: " << matcher << "\n";
    return path;
  };
  const std::string replay = std::string("replay ") + kBundled +
                             " --matcher spacetime --count 1 --downsample 4 --tolerance fast --no-decimate --out " +
                             dir.path();
  RunResult r = RunRangebayes(replay + "/block --noise-model " + model("block"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = RunRangebayes(replay + "/spacetime --noise-model " + model("spacetime"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("fitted for matcher 'spacetime', not 'block'"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("fit one with `calibrate noise --matcher block`"), std::string::npos) << r.output;
}

// --prior takes what `smooth --prior` takes, names too (`replay --prior cauchy` was refused as an unreadable file).
TEST(ReplayCli, ThePriorIsNamedAsInSmooth) {
  const TempDir dir("cli_replay_prior");
  const std::string replay = std::string("replay ") + kBundled +
                             " --count 1 --downsample 4 --tolerance fast --no-decimate --out " + dir.path();
  RunResult r = RunRangebayes(replay + "/cauchy --prior cauchy");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = RunRangebayes(replay + "/other --prior huber");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("expected sqrt, quadratic, cauchy or a .yaml learned prior"), std::string::npos) << r.output;
}

// A space-time window longer than the recording matches nothing: the error points at the note that says why (it
// pointed at "the errors above", of which there were none).
TEST(ReplayCli, AWindowLongerThanTheRecordingPointsAtTheNote) {
  const TempDir dir("cli_replay_window");
  const RunResult r = RunRangebayes(std::string("replay ") + kBundled +
                                    " --matcher spacetime --window-frames 9 --out " + dir.path() + "/out");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("note: the last 8 frame(s) did not fill a 9-frame space-time window"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("error: no frame went through the pipeline: the last 8 frame(s) did not fill a 9-frame "
                          "space-time window"),
            std::string::npos)
      << r.output;
  // With --quiet the note is not printed: the error line alone says why (it pointed at "the notes above").
  const RunResult quiet = RunRangebayes(std::string("replay ") + kBundled +
                                        " --matcher spacetime --window-frames 9 -q --out " + dir.path() + "/quiet");
  EXPECT_EQ(quiet.exit_code, 1) << quiet.output;
  EXPECT_EQ(quiet.output.find("note:"), std::string::npos) << quiet.output;
  EXPECT_NE(quiet.output.find("the last 8 frame(s) did not fill a 9-frame space-time window"), std::string::npos)
      << quiet.output;
}

// With outputs off, their folders are not made and the closing line lists only what was written (it named five
// folders, three of them empty).
TEST(ReplayCli, OutputsThatAreOffLeaveNoFolder) {
  const TempDir dir("cli_replay_off");
  const RunResult r =
      RunRangebayes(std::string("replay ") + kBundled +
                    " --count 1 --downsample 4 --no-smooth --no-decimate --no-previews --out " + dir.path() + "/out");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir.path() + "/out/raw/000000.ply"));
  for (const char* folder : {"smoothed", "decimated", "shaded"}) {
    EXPECT_FALSE(fs::exists(dir.path() + "/out/" + folder)) << folder;
  }
  EXPECT_NE(r.output.find("/out: "), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("smoothed/"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("shaded/"), std::string::npos) << r.output;
  // Decimation off: the pictures have two panels and the closing line says so (it named three); the stage that is
  // off has no rate (it printed millions of items/s).
  const RunResult two =
      RunRangebayes(std::string("replay ") + kBundled +
                    " --count 1 --downsample 4 --tolerance fast --no-decimate --out " + dir.path() + "/two");
  ASSERT_EQ(two.exit_code, 0) << two.output;
  EXPECT_NE(two.output.find("shaded/ (raw | smoothed renderings)"), std::string::npos) << two.output;
  const size_t row = two.output.find("  decimate ");
  ASSERT_NE(row, std::string::npos) << two.output;
  EXPECT_EQ(two.output.substr(row, two.output.find('\n', row) - row).back(), '-') << two.output;
}

// A second run into the folder of a first is refused (its frames would mix with the first run's, which it would
// partly replace); with --overwrite the first run's results are removed first, so only the new frames are there.
TEST(ReplayCli, AFolderWithEarlierResultsIsRefusedUnlessOverwrite) {
  const TempDir dir("cli_replay_again");
  const std::string out = dir.path() + "/out";
  const std::string args =
      std::string("replay ") + kBundled + " --downsample 4 --tolerance fast --no-previews --out " + out;
  ASSERT_EQ(RunRangebayes(args + " --count 2").exit_code, 0);
  ASSERT_TRUE(fs::exists(out + "/raw/000001.ply"));
  RunResult r = RunRangebayes(args + " --count 1");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find(out + ": holds the results of an earlier run (results.csv)"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(out + "/raw/000001.ply"));  // the first run's results untouched
  r = RunRangebayes(args + " --count 1 --overwrite");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out + "/raw/000000.ply"));
  EXPECT_FALSE(fs::exists(out + "/raw/000001.ply"));  // not left over from the first run
  std::ifstream index(out + "/results.csv");
  int lines = 0;
  for (std::string line; std::getline(index, line);) ++lines;
  EXPECT_EQ(lines, 2);  // header and the one new frame
}

// A frame whose last file cannot be written (here a folder stands where its shaded PNG goes) leaves none of its
// files: its raw mesh and depth picture were left on disk, listed nowhere in results.csv.
TEST(ReplayCli, AFrameThatFailsToWriteLeavesNoFilesUnlisted) {
  const TempDir dir("cli_replay_partial");
  const std::string out = dir.path() + "/out";
  fs::create_directories(out + "/shaded/000000.png");
  const RunResult r = RunRangebayes(std::string("replay ") + kBundled +
                                    " --count 1 --downsample 4 --no-smooth --no-decimate -q --out " + out);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_FALSE(fs::exists(out + "/raw/000000.ply"));
  EXPECT_FALSE(fs::exists(out + "/depth/000000.png"));
  std::ifstream index(out + "/results.csv");
  int lines = 0;
  for (std::string line; std::getline(index, line);) ++lines;
  EXPECT_EQ(lines, 1);  // the header alone
}

// A results.csv of its header alone holds no result: the folder of a run that stopped before its first result
// takes the next run without --overwrite (it was refused as holding "the results of an earlier run").
TEST(ReplayCli, AFolderWithoutResultsTakesTheNextRun) {
  const TempDir dir("cli_replay_no_results");
  const std::string out = dir.path() + "/out";
  fs::create_directories(out + "/shaded/000000.png");
  const std::string args =
      std::string("replay ") + kBundled + " --count 1 --downsample 4 --no-smooth --no-decimate -q --out " + out;
  ASSERT_EQ(RunRangebayes(args).exit_code, 1);
  ASSERT_TRUE(fs::exists(out + "/results.csv"));
  const RunResult r = RunRangebayes(args);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(out + "/raw/000000.ply"));
  EXPECT_TRUE(fs::is_regular_file(out + "/shaded/000000.png"));
}

TEST(ReplayCli, MissingRecordingIsOneLineExitOne) {
  const RunResult r = RunRangebayes("replay /nonexistent/rec --out /tmp/never");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("rangebayes replay: error: /nonexistent/rec: recording folder not found"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find('\n'), r.output.size() - 1) << r.output;
}

TEST(ReplayCli, MissingFileAndTruncatedIndexAreReportedPerFrame) {
  const TempDir dir("cli_bad");
  const std::string rec = dir.path() + "/rec";
  CopyBundled(rec, 3);
  fs::remove(rec + "/right/000001.png");
  { std::ofstream(rec + "/frames.csv", std::ios::app) << "3,5,5,left/000003.png,right/00"; }
  const RunResult r = RunRangebayes("replay " + rec + " --no-smooth --no-decimate --out " + dir.path() + "/out");
  EXPECT_EQ(r.exit_code, 3) << r.output;  // partial success
  EXPECT_NE(r.output.find("frame 1: right/000001.png is missing"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("line 5 is truncated"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(dir.path() + "/out/raw/000002.ply"));
}

// The bundled synthetic recording's disparities run from 20 to 34 px: searched from 20 px up, its far plane sits at
// the range's lower end and the summary says the range looks short; with the defaults it says nothing.
TEST(ReplayCli, SearchRangeThatMissesTheSceneIsReported) {
  const TempDir dir("cli_range");
  const std::string rec = dir.path() + "/rec";
  CopyBundled(rec, 2);
  const std::string note = "many pixels matched best at an end of the disparities searched";
  RunResult r = RunRangebayes("replay " + rec + " --no-smooth --no-decimate --min-disparity 20 --out " + dir.path() +
                              "/short");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("in 2 of 2 results " + note), std::string::npos) << r.output;
  r = RunRangebayes("replay " + rec + " --no-smooth --no-decimate --out " + dir.path() + "/default");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find(note), std::string::npos) << r.output;
}

TEST(ReplayCli, WrongRigAndMismatchedSizesAreClear) {
  const TempDir dir("cli_rig");
  const std::string rec = dir.path() + "/rec";
  CopyBundled(rec, 2);
  { std::ofstream(rec + "/rig.yaml") << "%YAML:1.0\nimage_width: 320\n"; }
  RunResult r = RunRangebayes("replay " + rec + " --out " + dir.path() + "/out");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("rig.yaml"), std::string::npos) << r.output;

  fs::copy_file(std::string(RB_SOURCE_DIR) + "/" + kBundled + "/rig.yaml", rec + "/rig.yaml",
                fs::copy_options::overwrite_existing);
  cv::Mat small(10, 10, CV_8UC1, cv::Scalar(0));
  std::vector<uchar> png;
  cv::imencode(".png", small, png);
  std::ofstream(rec + "/right/000001.png", std::ios::binary).write(reinterpret_cast<char*>(png.data()),
                                                                    static_cast<std::streamsize>(png.size()));
  r = RunRangebayes("replay " + rec + " --no-smooth --no-decimate --out " + dir.path() + "/out2");
  EXPECT_EQ(r.exit_code, 3) << r.output;
  EXPECT_NE(r.output.find("frame 1: left is 320x240 but right is 10x10"), std::string::npos) << r.output;
}

// The end of the selection in 64 bits: --first 1 --count 2147483647 played no frame and exited 0.
TEST(ReplayCli, CountUpToIntMaxPlaysTheRest) {
  const TempDir dir("cli_count_max");
  const std::string rec = dir.path() + "/rec";
  CopyBundled(rec, 3);
  const RunResult r = RunRangebayes("replay " + rec + " --first 1 --count 2147483647 --downsample 4 --no-smooth " +
                                    "--no-decimate --no-previews --out " + dir.path() + "/out");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(CountLines(dir.path() + "/out/results.csv"), 3);  // header and frames 1 and 2
}

// A frames.csv line may name any Linux file name, UTF-8 or not. Its frame is skipped (missing file) and
// summary.json holds the error with U+FFFD for the byte: json::dump threw there after the file was truncated,
// leaving it empty and the run at exit 1 instead of 3 (frames skipped).
TEST(ReplayCli, FileNameThatIsNotUtf8GivesAValidSummaryAndExitThree) {
  const TempDir dir("cli_utf8");
  const std::string rec = dir.path() + "/rec";
  CopyBundled(rec, 2);
  EditIndex(rec, "left/000001.png", "left/\xff.png");
  const RunResult r = RunRangebayes("replay " + rec + " --downsample 4 --no-smooth --no-decimate --no-previews --out " +
                                    dir.path() + "/out");
  EXPECT_EQ(r.exit_code, 3) << r.output;
  const nlohmann::json j = nlohmann::json::parse(ReadAll(dir.path() + "/out/summary.json"));
  EXPECT_EQ(j["results"], 1);
  EXPECT_EQ(j["frames_skipped"], 1);
  ASSERT_EQ(j["errors"].size(), 1u);
  EXPECT_NE(j["errors"][0].get<std::string>().find("frame 1: left/\xEF\xBF\xBD.png is missing"), std::string::npos)
      << j["errors"][0];
}

// --queue is kept with --live-path (whose preset sets queues of one item), and left out it is the preset's.
TEST(ReplayCli, QueueGivenIsKeptWithLivePath) {
  const TempDir dir("cli_queue");
  const std::pair<std::string, int> cases[] = {
      {"", 4}, {"--queue 2", 2}, {"--live-path", 1}, {"--live-path --queue 8", 8}};
  int run = 0;
  for (const auto& [flags, capacity] : cases) {
    const std::string out = dir.path() + "/out" + std::to_string(run++);
    const RunResult r = RunRangebayes(std::string("replay ") + kBundled + " --count 1 --no-smooth --no-decimate " +
                                      "--no-previews " + flags + " --out " + out);
    ASSERT_EQ(r.exit_code, 0) << flags << "\n" << r.output;
    EXPECT_EQ(nlohmann::json::parse(ReadAll(out + "/summary.json"))["queue_capacity"], capacity) << flags;
  }
}

// --repeat that would number frames past 2^53 - 1 ends the run with one error line and exit 1 (a last index of
// 9223372036854775807 wrapped to negative indices and exited 0).
TEST(ReplayCli, RepeatsPastTheLargestIndexAreOneErrorLine) {
  const TempDir dir("cli_repeat_max");
  const std::string rec = dir.path() + "/rec";
  CopyBundled(rec, 2);
  EditIndex(rec, "\n1,", "\n9007199254740991,");
  const RunResult r = RunRangebayes("replay " + rec + " --repeat 2 --downsample 4 --no-smooth --no-decimate " +
                                    "--no-previews --quiet --out " + dir.path() + "/out");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(r.output, "rangebayes replay: error: " + rec +
                          ": playing it again would number frames past 9007199254740991 (its last index is "
                          "9007199254740991); play it fewer times\n");
}

// Kills and reaps a child process that a failed assertion left running.
class ChildGuard {
 public:
  explicit ChildGuard(pid_t pid) : pid_(pid) {}
  ~ChildGuard() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  // Waits up to `seconds` for the child to end; its waitpid status, or nullopt if it still runs.
  std::optional<int> WaitFor(double seconds) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    do {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return status;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    } while (std::chrono::steady_clock::now() < end);
    return std::nullopt;
  }

 private:
  pid_t pid_;
};

// `replay --speed step` waits for Enter on the capture thread. SIGTERM while it waits ends the run with the
// results so far: the wait polls stdin and the stop flag. A blocking getchar() kept the process there until Enter
// or the end of stdin (25 s after SIGTERM in the review, for ever here, where stdin stays open).
TEST(ReplayCli, SigtermEndsAStepReplayWaitingForEnter) {
  const TempDir dir("cli_step");
  const std::string out = dir.path() + "/out", log = dir.path() + "/log.txt";
  int input[2];
  ASSERT_EQ(::pipe(input), 0);
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::dup2(input[0], STDIN_FILENO);
    ::close(input[0]);
    ::close(input[1]);
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, STDOUT_FILENO);
    ::dup2(fd, STDERR_FILENO);
    ::close(fd);
    if (::chdir(RB_SOURCE_DIR) != 0) ::_exit(127);
    ::execl(RB_BINARY, RB_BINARY, "replay", kBundled, "--speed", "step", "--count", "3", "--downsample", "4",
            "--no-smooth", "--no-decimate", "--no-previews", "--out", out.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  ChildGuard child(pid);
  ::close(input[0]);
  ASSERT_EQ(::write(input[1], "\n", 1), 1);  // frame 0; frame 1 then waits for the next Enter
  const auto prompts = [&] {
    const std::string text = ReadAll(log);
    int n = 0;
    for (size_t at = text.find("Enter for the next frame"); at != std::string::npos;
         at = text.find("Enter for the next frame", at + 1)) {
      ++n;
    }
    return n;
  };
  // Generous bounds (not timings): a wait that runs out means the run is stuck.
  const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while ((prompts() < 2 || CountLines(out + "/results.csv") < 2) && std::chrono::steady_clock::now() < end) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  ASSERT_EQ(prompts(), 2) << ReadAll(log);
  ASSERT_EQ(CountLines(out + "/results.csv"), 2) << ReadAll(log);  // frame 0 is through
  ASSERT_EQ(::kill(pid, SIGTERM), 0);
  const std::optional<int> status = child.WaitFor(60.0);
  ::close(input[1]);
  ASSERT_TRUE(status.has_value()) << "still waiting for Enter 60 s after SIGTERM\n" << ReadAll(log);
  ASSERT_TRUE(WIFEXITED(*status)) << ReadAll(log);
  EXPECT_EQ(WEXITSTATUS(*status), 0) << ReadAll(log);
  EXPECT_NE(ReadAll(log).find("stopped by request"), std::string::npos) << ReadAll(log);
  EXPECT_EQ(CountLines(out + "/results.csv"), 2);
}

// Options that had no effect in the combination given were read and ignored (exit 0): now usage errors, or (a
// window cut at the recording's end) a note.
TEST(ReplayCli, OptionsWithoutEffectAreRefusedOrNoted) {
  const TempDir dir("cli_ignored");
  const std::string replay = std::string("replay ") + kBundled + " --downsample 4 --no-smooth --no-decimate --out ";
  for (const auto& [options, message] :
       {std::pair{"--speed-factor 2", "--speed-factor applies to --speed recorded"},
        {"--no-previews --preview-width 100", "--preview-width excludes --no-previews"},
        {"--ui-record-dir rec", "--ui-record-dir requires --ui"}}) {
    const RunResult r = RunRangebayes(replay + dir.path() + "/x " + options);
    EXPECT_EQ(r.exit_code, 2) << options << "\n" << r.output;
    EXPECT_NE(r.output.find(message), std::string::npos) << r.output;
  }
  const RunResult r = RunRangebayes(replay + dir.path() + "/cut --first 7 --count 5 --no-previews");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("--count 5 from --first 7: the recording has 8 entries, so 1 are played"), std::string::npos)
      << r.output;
}

// q, or the end of stdin, in `replay --speed step` is a stop: it ended the run as if the recording had ended (exit
// 0, summary "stopped": false, also with no frame through).
TEST(ReplayCli, QOrTheEndOfInputStopsAStepReplay) {
  const TempDir dir("cli_step_q");
  const std::string keys = dir.path() + "/keys.txt";
  std::ofstream(keys) << "\nq\n";
  const std::string replay = std::string("replay ") + kBundled +
                             " --speed step --count 3 --downsample 4 --no-smooth --no-decimate --no-previews --out ";
  RunResult r = RunRangebayes(replay + dir.path() + "/q < " + keys);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("stopped by request"), std::string::npos) << r.output;
  EXPECT_EQ(CountLines(dir.path() + "/q/results.csv"), 2) << r.output;  // frame 0, then q
  EXPECT_NE(ReadAll(dir.path() + "/q/summary.json").find("\"stopped\": true"), std::string::npos);
  r = RunRangebayes(replay + dir.path() + "/eof < /dev/null");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("stopped by request before the first result"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace rangebayes
