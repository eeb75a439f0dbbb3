// PlaybackSource (speeds, random access, skipping bad frames) and Recorder (limits, stop, device loss,
// SIGINT and SIGKILL of a recording process, a full disk through the file system-call seam).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <thread>

#include "capture/file_syscalls.h"
#include "capture/playback_source.h"
#include "capture/recorder.h"
#include "capture/stop_signal.h"
#include "core/error.h"
#include "tests/capture/test_util.h"

namespace rangebayes {
namespace {
namespace fs = std::filesystem;

std::string MakeRecording(const TempDir& dir, int frames) {
  const std::string folder = dir.path() + "/rec";
  RecordingWriter writer(folder, TestRig(32, 16), {{"source", "test"}});
  for (int i = 0; i < frames; ++i) writer.Write(TestFrame(i, 32, 16, CV_8UC1));
  writer.Finish();
  return folder;
}

TEST(Playback, FastestDeliversEveryFrameInOrder) {
  const TempDir dir("play");
  PlaybackSource source(OpenRecording(MakeRecording(dir, 5)));
  EXPECT_EQ(source.frames_total().value_or(-1), 5);
  for (int i = 0; i < 5; ++i) {
    const FrameResult r = source.Next();
    ASSERT_EQ(r.status, FrameStatus::kFrame);
    EXPECT_EQ(r.frame.index, i);
    EXPECT_EQ(r.frame.pattern_id, i % 4);
  }
  EXPECT_EQ(source.Next().status, FrameStatus::kEndOfStream);
  EXPECT_EQ(source.stats().frames_delivered, 5);
}

// A recording made from a playback (the console's record button during replay) describes itself: the source's
// state and counts are not copied into its meta.yaml.
TEST(Playback, MetaLeavesOutTheSourcesStateAndCounts) {
  const TempDir dir("play_meta");
  Recording rec = OpenRecording(MakeRecording(dir, 2));
  rec.meta["frames"] = "8";  // as synth writes it
  rec.meta["error"] = "frame 3 not recorded";
  const RecordingMeta meta = PlaybackSource(rec).Meta();
  for (const char* key : {"complete", "error", "frame_count", "frames"}) EXPECT_EQ(meta.count(key), 0u) << key;
  EXPECT_NE(meta.at("source").find("(2 frames)"), std::string::npos) << meta.at("source");
}

TEST(Playback, MissingAndCorruptFramesAreSkippedWithTheirIndex) {
  const TempDir dir("skip");
  const std::string folder = MakeRecording(dir, 4);
  fs::remove(folder + "/right/000001.png");
  { std::ofstream(folder + "/left/000002.png") << "garbage"; }
  PlaybackSource source(OpenRecording(folder));
  std::vector<FrameStatus> statuses;
  std::vector<std::string> reasons;
  for (FrameResult r = source.Next(); r.status != FrameStatus::kEndOfStream; r = source.Next()) {
    statuses.push_back(r.status);
    reasons.push_back(r.reason);
  }
  ASSERT_EQ(statuses.size(), 4u);
  EXPECT_EQ(statuses[0], FrameStatus::kFrame);
  EXPECT_EQ(statuses[1], FrameStatus::kSkipped);
  EXPECT_NE(reasons[1].find("frame 1"), std::string::npos) << reasons[1];
  EXPECT_EQ(statuses[2], FrameStatus::kSkipped);
  EXPECT_NE(reasons[2].find("frame 2"), std::string::npos) << reasons[2];
  EXPECT_EQ(statuses[3], FrameStatus::kFrame);
  EXPECT_EQ(source.stats().frames_skipped, 2);
}

TEST(Playback, RandomAccessStepAndRecordedSpeed) {
  const TempDir dir("access");
  const Recording rec = OpenRecording(MakeRecording(dir, 6));
  PlaybackOptions step;
  step.speed = PlaybackSpeed::kStep;
  int gate_calls = 0;
  step.step_gate = [&] { return ++gate_calls <= 2; };
  PlaybackSource source(rec, step);
  EXPECT_EQ(source.FrameWithIndex(4).index, 4);
  EXPECT_THROW(source.FrameWithIndex(40), Error);
  EXPECT_EQ(source.Next().frame.index, 0);
  EXPECT_EQ(source.Next().frame.index, 1);
  EXPECT_EQ(source.Next().status, FrameStatus::kEndOfStream);  // the gate said stop

  PlaybackOptions recorded;
  recorded.speed = PlaybackSpeed::kRecorded;
  recorded.speed_factor = 1000.0;  // 33 ms gaps become 33 µs: exercises the clock without slowing the test
  recorded.first_position = 2;
  recorded.count = 3;
  PlaybackSource timed(rec, recorded);
  EXPECT_EQ(timed.frames_total().value_or(-1), 3);
  std::vector<std::int64_t> got;
  for (FrameResult r = timed.Next(); r.status == FrameStatus::kFrame; r = timed.Next()) got.push_back(r.frame.index);
  EXPECT_EQ(got, (std::vector<std::int64_t>{2, 3, 4}));

  PlaybackOptions bad;
  bad.speed = PlaybackSpeed::kStep;  // without a gate
  EXPECT_THROW(PlaybackSource(rec, bad), Error);
  // Playing nothing is an error, not a run of zero frames that exits as if all went well.
  PlaybackOptions past;
  past.first_position = rec.num_frames();
  EXPECT_NE(ErrorOf([&] { PlaybackSource s(rec, past); }).find("past the recording's"), std::string::npos);
  PlaybackOptions none;
  none.count = 0;
  EXPECT_NE(ErrorOf([&] { PlaybackSource s(rec, none); }).find("plays no frame"), std::string::npos);
}

// Plays `rec` at the recorded speed: its first frame comes, and the wait for its second ends with the end of the
// stream when a stop is requested 100 ms in.
void ExpectAStopEndsTheWaitForTheSecondFrame(const Recording& rec) {
  std::atomic<bool> stop{false};
  PlaybackOptions o;
  o.speed = PlaybackSpeed::kRecorded;
  o.stop = &stop;
  PlaybackSource source(rec, o);
  EXPECT_EQ(source.Next().status, FrameStatus::kFrame);
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    stop = true;
  });
  EXPECT_EQ(source.Next().status, FrameStatus::kEndOfStream);
  stopper.join();
}

// At the recorded speed, a stop request ends the wait for the next frame: a damaged timestamp (or a gap of hours)
// kept the process asleep, deaf to Ctrl-C and SIGTERM.
TEST(Playback, StopEndsTheWaitForAFarTimestamp) {
  const TempDir dir("far");
  Recording rec = OpenRecording(MakeRecording(dir, 3));
  rec.frames[1].timestamp_left_ns = rec.frames[1].timestamp_right_ns = 9'000'000'000'000'000'000;
  ExpectAStopEndsTheWaitForTheSecondFrame(rec);
}

// A gap between recorded timestamps longer than max_gap_s is played as max_gap_s and counted; the frames after it
// keep their own gaps. A timestamp 4e18 ns ahead made `replay --speed recorded` sleep without end. (The stop
// request is only the guard that ends the test if the wait is not cut.)
TEST(Playback, AGapLongerThanTheLongestWaitIsPlayedShorter) {
  const TempDir dir("gap");
  Recording rec = OpenRecording(MakeRecording(dir, 3));
  rec.frames[1].timestamp_left_ns = rec.frames[1].timestamp_right_ns = 4'000'000'000'000'000'000;
  rec.frames[2].timestamp_left_ns = rec.frames[2].timestamp_right_ns = 4'000'000'000'001'000'000;  // 1 ms later
  std::atomic<bool> stop{false};
  PlaybackOptions o;
  o.speed = PlaybackSpeed::kRecorded;
  o.max_gap_s = 0.01;
  o.stop = &stop;
  PlaybackSource source(rec, o);
  std::thread guard([&] {
    for (int i = 0; i < 600 && !stop; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(100));
    stop = true;
  });
  std::vector<FrameStatus> got;
  for (int i = 0; i < 3; ++i) got.push_back(source.Next().status);
  stop = true;
  guard.join();
  EXPECT_EQ(got, std::vector<FrameStatus>(3, FrameStatus::kFrame));
  EXPECT_EQ(source.stats().gaps_shortened, 1);
  o.max_gap_s = 0.0;
  EXPECT_THROW(PlaybackSource(rec, o), Error);
}

TEST(Playback, RepeatsPlayTheSelectionAgainWithIncreasingIndices) {
  const TempDir dir("repeat");
  const Recording rec = OpenRecording(MakeRecording(dir, 4));
  PlaybackOptions o;
  o.first_position = 1;
  o.count = 2;
  o.repeats = 3;
  PlaybackSource source(rec, o);
  EXPECT_EQ(source.frames_total().value_or(-1), 6);
  std::vector<std::int64_t> got;
  for (FrameResult r = source.Next(); r.status == FrameStatus::kFrame; r = source.Next()) got.push_back(r.frame.index);
  EXPECT_EQ(got, (std::vector<std::int64_t>{1, 2, 4, 5, 7, 8}));  // each pass adds the last index + 1 = 3
  EXPECT_EQ(source.Next().status, FrameStatus::kEndOfStream);
  PlaybackOptions bad;
  bad.repeats = 0;
  EXPECT_THROW(PlaybackSource(rec, bad), Error);
}

// The end of the selection in 64 bits: first 1 + count 2147483647 passed INT_MAX and played no frame at all.
TEST(Playback, CountUpToIntMaxPlaysTheRestOfTheRecording) {
  const TempDir dir("count_max");
  PlaybackOptions o;
  o.first_position = 1;
  o.count = std::numeric_limits<int>::max();
  PlaybackSource source(OpenRecording(MakeRecording(dir, 4)), o);
  EXPECT_EQ(source.frames_total().value_or(-1), 3);
  std::vector<std::int64_t> got;
  for (FrameResult r = source.Next(); r.status == FrameStatus::kFrame; r = source.Next()) got.push_back(r.frame.index);
  EXPECT_EQ(got, (std::vector<std::int64_t>{1, 2, 3}));
}

// A pass that would number frames past kMaxRecordingIndex is an error, not an index that wraps to a negative
// one (a last index of 9223372036854775807 played twice numbered the second pass from -9223372036854775808).
TEST(Playback, RepeatsThatWouldPassTheLargestIndexThrow) {
  const TempDir dir("repeat_max");
  Recording rec = OpenRecording(MakeRecording(dir, 2));
  for (const std::int64_t last : {kMaxRecordingIndex, std::numeric_limits<std::int64_t>::max()}) {
    SCOPED_TRACE(last);
    rec.frames[1].index = last;
    PlaybackOptions o;
    o.repeats = 2;
    PlaybackSource source(rec, o);
    EXPECT_EQ(source.Next().frame.index, 0);
    EXPECT_EQ(source.Next().frame.index, last);
    EXPECT_NE(ErrorOf([&] { source.Next(); }).find("playing it again would number frames past 9007199254740991"),
              std::string::npos);
  }
  // The largest pass that fits: indices 0 and 2^52 - 1, played twice, end at 2^53 - 1.
  rec.frames[1].index = (std::int64_t{1} << 52) - 1;
  PlaybackOptions o;
  o.repeats = 2;
  PlaybackSource source(rec, o);
  std::vector<std::int64_t> got;
  for (FrameResult r = source.Next(); r.status == FrameStatus::kFrame; r = source.Next()) got.push_back(r.frame.index);
  EXPECT_EQ(got,
            (std::vector<std::int64_t>{0, (std::int64_t{1} << 52) - 1, std::int64_t{1} << 52, kMaxRecordingIndex}));
}

// Timestamps of opposite sign far apart: their difference overflowed int64 (to -1 ns here) and the frame came at
// once; in double it is a gap of about 584 years, capped and waited for until the stop request.
TEST(Playback, RecordedSpeedWaitsForTimestampsOfOppositeSign) {
  const TempDir dir("far_apart");
  Recording rec = OpenRecording(MakeRecording(dir, 2));
  rec.frames[0].timestamp_left_ns = rec.frames[0].timestamp_right_ns = std::numeric_limits<std::int64_t>::min();
  rec.frames[1].timestamp_left_ns = rec.frames[1].timestamp_right_ns = std::numeric_limits<std::int64_t>::max();
  ExpectAStopEndsTheWaitForTheSecondFrame(rec);
}

TEST(Playback, LoopKeepsIndicesIncreasing) {
  const TempDir dir("loop");
  PlaybackOptions options;
  options.loop = true;
  PlaybackSource source(OpenRecording(MakeRecording(dir, 3)), options);
  std::int64_t last = -1;
  for (int i = 0; i < 8; ++i) {
    const FrameResult r = source.Next();
    ASSERT_EQ(r.status, FrameStatus::kFrame);
    EXPECT_GT(r.frame.index, last);
    last = r.frame.index;
  }
}

TEST(Recorder, StopsAtLimitAndFinishesIndex) {
  const TempDir dir("limit");
  FakeFrameSource source(32, 16);
  RecordingWriter writer(dir.path() + "/rec", std::nullopt, source.Meta());
  RecorderOptions options;
  options.max_frames = 7;
  const RecorderSummary s = Record(source, writer, options);
  EXPECT_EQ(s.stop, RecorderStop::kMaxFrames);
  EXPECT_EQ(s.frames_written, 7);
  const Recording rec = OpenRecording(dir.path() + "/rec");
  EXPECT_EQ(rec.num_frames(), 7);
  EXPECT_EQ(rec.meta.at("complete"), "true");
  EXPECT_EQ(rec.meta.at("source"), "fake source");
}

TEST(Recorder, DeviceLostMidStreamKeepsRecording) {
  const TempDir dir("lost");
  FakeFrameSource source(32, 16);
  source.hook = [](std::int64_t i) {
    if (i == 3) return FrameStatus::kSkipped;
    if (i == 5) throw Error("/dev/video9: device disappeared (ENODEV) after frame 4");
    return FrameStatus::kFrame;
  };
  RecordingWriter writer(dir.path() + "/rec", std::nullopt, {});
  const RecorderSummary s = Record(source, writer);
  EXPECT_EQ(s.stop, RecorderStop::kSourceError);
  EXPECT_NE(s.error.find("ENODEV"), std::string::npos);
  EXPECT_EQ(s.frames_written, 4);
  EXPECT_EQ(s.frames_skipped, 1);
  const Recording rec = OpenRecording(dir.path() + "/rec");
  EXPECT_EQ(rec.num_frames(), 4);
  EXPECT_EQ(rec.meta.at("complete"), "true");
  EXPECT_NE(rec.meta.at("error").find("ENODEV"), std::string::npos);
  ExpectRecordingHoldsTestFrames(rec, 32, 16, CV_8UC1);
}

TEST(Recorder, StalledSourceEndsAfterTimeouts) {
  const TempDir dir("stall");
  FakeFrameSource source(32, 16);
  source.hook = [](std::int64_t i) { return i < 2 ? FrameStatus::kFrame : FrameStatus::kTimeout; };
  RecordingWriter writer(dir.path() + "/rec", std::nullopt, {});
  RecorderOptions options;
  options.max_consecutive_timeouts = 4;
  const RecorderSummary s = Record(source, writer, options);
  EXPECT_EQ(s.stop, RecorderStop::kStalled);
  EXPECT_EQ(s.timeouts, 4);
  EXPECT_EQ(s.frames_written, 2);
}

TEST(Recorder, StopFlagEndsCleanly) {
  const TempDir dir("flag");
  std::atomic<bool> stop{false};
  FakeFrameSource source(32, 16);
  source.hook = [&](std::int64_t i) {
    if (i == 4) stop = true;
    return FrameStatus::kFrame;
  };
  RecordingWriter writer(dir.path() + "/rec", std::nullopt, {});
  RecorderOptions options;
  options.stop = &stop;
  const RecorderSummary s = Record(source, writer, options);
  EXPECT_EQ(s.stop, RecorderStop::kStopRequested);
  EXPECT_EQ(s.frames_written, 5);
}

// Runs a recorder in a child process on an endless source; returns the child's pid once it has written
// at least `frames` frames.
pid_t StartRecordingChild(const std::string& folder, int frames) {
  int ready[2];
  if (pipe(ready) != 0) return -1;
  const pid_t child = fork();
  if (child != 0) {
    close(ready[1]);
    char c = 0;
    if (read(ready[0], &c, 1) != 1) return -1;
    close(ready[0]);
    return child;
  }
  close(ready[0]);
  int code = 3;
  try {
    InstallStopSignalHandlers();
    FakeFrameSource source(64, 48);
    source.hook = [&](std::int64_t i) {
      if (i == frames) {
        const char c = 'x';
        (void)!write(ready[1], &c, 1);
      }
      if (i > frames) usleep(2000);
      return FrameStatus::kFrame;
    };
    RecordingWriter writer(folder, TestRig(64, 48), {});
    RecorderOptions options;
    options.stop = &StopFlag();
    const RecorderSummary s = Record(source, writer, options);
    code = s.stop == RecorderStop::kStopRequested ? 0 : 4;
  } catch (...) {
    code = 5;
  }
  _exit(code);
}

TEST(Recorder, SigintFinishesTheIndex) {
  const TempDir dir("sigint");
  const std::string folder = dir.path() + "/rec";
  const pid_t child = StartRecordingChild(folder, 5);
  ASSERT_GT(child, 0);
  const int status = SignalAndWait(child, SIGINT);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  RecordingReadSummary rs;
  const Recording rec = OpenRecording(folder, &rs);
  EXPECT_GE(rec.num_frames(), 5);
  EXPECT_FALSE(rs.truncated_last_line);
  EXPECT_EQ(rec.meta.at("complete"), "true");
  EXPECT_EQ(rec.meta.at("stopped"), "stop requested");
  EXPECT_EQ(rec.meta.at("frame_count"), std::to_string(rec.num_frames()));
}

TEST(Recorder, SigkillLeavesReadableRecording) {
  const TempDir dir("sigkill");
  const std::string folder = dir.path() + "/rec";
  const pid_t child = StartRecordingChild(folder, 8);
  ASSERT_GT(child, 0);
  const int status = SignalAndWait(child, SIGKILL);
  ASSERT_TRUE(WIFSIGNALED(status));
  RecordingReadSummary rs;
  const Recording rec = OpenRecording(folder, &rs);
  EXPECT_GE(rec.num_frames(), 8);
  EXPECT_EQ(rec.meta.at("complete"), "false");
  EXPECT_EQ(rs.missing_files, 0);
  ExpectRecordingHoldsTestFrames(rec, 64, 48, CV_8UC1);
}

}  // namespace
}  // namespace rangebayes

namespace rangebayes {
namespace {

// The system's file calls, remembering the path of each descriptor opened: the base of the failing file systems
// below, each of which overrides the calls it makes fail.
class SystemCalls : public FileSysCalls {
 public:
  int Open(const std::string& path, int flags, mode_t mode) override {
    const int fd = real_->Open(path, flags, mode);
    if (fd >= 0) paths_[fd] = path;
    return fd;
  }
  ssize_t Write(int fd, const void* data, size_t size) override { return real_->Write(fd, data, size); }
  int Fsync(int fd) override { return real_->Fsync(fd); }
  int Close(int fd) override { return real_->Close(fd); }
  int Rename(const std::string& from, const std::string& to) override { return real_->Rename(from, to); }

 protected:
  bool PathHas(int fd, const std::string& part) const {
    const auto it = paths_.find(fd);
    return it != paths_.end() && it->second.find(part) != std::string::npos;
  }
  std::shared_ptr<FileSysCalls> real_ = RealFileSysCalls();

 private:
  std::map<int, std::string> paths_;
};

// The file system calls with a disk that fills up: from the `fail_at`-th write to a file whose name contains
// `pattern` (counting from 1), that write stores half of its bytes and every later write to any file of the
// recording fails with ENOSPC, as on a full disk.
class FullDisk final : public SystemCalls {
 public:
  FullDisk(std::string pattern, int fail_at) : pattern_(std::move(pattern)), fail_at_(fail_at) {}
  ssize_t Write(int fd, const void* data, size_t size) override {
    if (full_) {
      errno = ENOSPC;
      return -1;
    }
    if (PathHas(fd, pattern_) && ++writes_ == fail_at_) {
      full_ = true;
      return real_->Write(fd, data, size / 2);
    }
    return real_->Write(fd, data, size);
  }

 private:
  std::string pattern_;
  int fail_at_;
  int writes_ = 0;
  bool full_ = false;
};

// The system's file calls, except that fsync of frames.csv fails with EIO from its `fail_fsync_from`-th call on
// (0: never), and closing frames.csv reports EIO when `fail_close` (the descriptor is closed all the same), as a
// disk or network file system that loses writes does.
class FailingIndexSync final : public SystemCalls {
 public:
  FailingIndexSync(int fail_fsync_from, bool fail_close) : fail_fsync_from_(fail_fsync_from), fail_close_(fail_close) {}
  int Open(const std::string& path, int flags, mode_t mode) override {
    const int fd = SystemCalls::Open(path, flags, mode);
    if (fd >= 0 && path.find("frames.csv") != std::string::npos) index_fd_ = fd;
    return fd;
  }
  int Fsync(int fd) override {
    if (fd == index_fd_ && fail_fsync_from_ > 0 && ++fsyncs_ >= fail_fsync_from_) {
      errno = EIO;
      return -1;
    }
    return real_->Fsync(fd);
  }
  int Close(int fd) override {
    const int r = real_->Close(fd);
    if (fd != index_fd_) return r;
    index_fd_ = -1;  // the number may be handed out again
    if (!fail_close_) return r;
    errno = EIO;
    return -1;
  }

 private:
  int fail_fsync_from_;
  bool fail_close_;
  int index_fd_ = -1;
  int fsyncs_ = 0;
};

// A failed fsync or close of frames.csv at Finish is an error naming the file and the system's reason, and
// meta.yaml does not say complete (both were ignored, and the recording said complete: "true").
TEST(RecordingWriter, FailedFsyncOrCloseAtFinishIsAnErrorAndTheRecordingNotComplete) {
  for (const bool close : {false, true}) {
    SCOPED_TRACE(close ? "close" : "fsync");
    const TempDir dir("finish_sync");
    const std::string folder = dir.path() + "/rec";
    RecordingWriterOptions options;
    options.files = std::make_shared<FailingIndexSync>(close ? 0 : 1, close);
    RecordingWriter writer(folder, std::nullopt, {}, options);
    for (int i = 0; i < 3; ++i) writer.Write(TestFrame(i, 32, 16, CV_8UC1));
    const std::string error = ErrorOf([&] { writer.Finish({{"stopped", "end of stream"}}); });
    EXPECT_NE(
        error.find(folder + "/frames.csv: " + (close ? "close" : "fsync") + " failed (" + std::strerror(EIO) + ")"),
        std::string::npos)
        << error;
    EXPECT_EQ(ErrorOf([&] { writer.Finish(); }), "no error");  // once
    const Recording rec = OpenRecording(folder);
    EXPECT_EQ(rec.meta.at("complete"), "false");
    EXPECT_EQ(rec.meta.at("frame_count"), "3");
    EXPECT_EQ(rec.meta.at("stopped"), "end of stream");
    EXPECT_EQ(rec.num_frames(), 3);
    ExpectRecordingHoldsTestFrames(rec, 32, 16, CV_8UC1);
  }
}

// With fsync every frame, a failed fsync in the middle of a recording does not stop it (the frames after it would
// be lost); every frame is recorded and the failure is the recorder's error at the end.
TEST(Recorder, FailedPeriodicFsyncLosesNoFrameAndIsReportedAtTheEnd) {
  const TempDir dir("periodic_sync");
  FakeFrameSource source(32, 16, 6);
  RecordingWriterOptions options;
  options.fsync_every_frames = 1;
  options.files = std::make_shared<FailingIndexSync>(2, false);  // after frame 1 and every later one
  RecordingWriter writer(dir.path() + "/rec", std::nullopt, {}, options);
  const RecorderSummary s = Record(source, writer);
  EXPECT_EQ(s.stop, RecorderStop::kEndOfStream);
  EXPECT_EQ(s.frames_written, 6);
  EXPECT_NE(s.error.find("frames.csv: fsync failed after frame 1 (" + std::string(std::strerror(EIO)) + ")"),
            std::string::npos)
      << s.error;
  const Recording rec = OpenRecording(dir.path() + "/rec");
  EXPECT_EQ(rec.num_frames(), 6);
  EXPECT_EQ(rec.meta.at("complete"), "false");
  ExpectRecordingHoldsTestFrames(rec, 32, 16, CV_8UC1);
}

std::vector<std::string> PartialFiles(const std::string& folder) {
  std::vector<std::string> found;
  for (const auto& e : fs::recursive_directory_iterator(folder)) {
    if (e.path().extension() == ".partial") found.push_back(e.path().string());
  }
  return found;
}

// Image writes fail with ENOSPC from the `fail_from`-th on (a large file that no longer fits where a small one
// such as meta.yaml still does); every other call is the system's.
class ImagesDoNotFit final : public SystemCalls {
 public:
  explicit ImagesDoNotFit(int fail_from) : fail_from_(fail_from) {}
  ssize_t Write(int fd, const void* data, size_t size) override {
    if (PathHas(fd, ".png") && ++writes_ >= fail_from_) {
      errno = ENOSPC;
      return -1;
    }
    return real_->Write(fd, data, size);
  }

 private:
  int fail_from_;
  int writes_ = 0;
};

// A writer whose caller goes on after a failed Write (synth, the console's recording) leaves a recording that says
// it is not complete and why, and reading it says so; it said `complete: "true"` and replayed without a word.
TEST(RecordingWriter, AFrameNotRecordedLeavesTheRecordingIncomplete) {
  const TempDir dir("not_recorded");
  const std::string folder = dir.path() + "/rec";
  RecordingWriterOptions options;
  options.files = std::make_shared<ImagesDoNotFit>(5);  // the left image of frame 2
  RecordingWriter writer(folder, std::nullopt, {}, options);
  for (int i = 0; i < 4; ++i) {
    const std::string error = ErrorOf([&] { writer.Write(TestFrame(i, 32, 16, CV_8UC1)); });
    EXPECT_EQ(error == "no error", i < 2) << i << ": " << error;
  }
  writer.Finish();
  RecordingReadSummary read;
  const Recording rec = OpenRecording(folder, &read);
  EXPECT_EQ(rec.num_frames(), 2);
  EXPECT_EQ(rec.meta.at("complete"), "false");
  EXPECT_EQ(rec.meta.at("frame_count"), "2");
  EXPECT_NE(rec.meta.at("error").find("frame 2 not recorded"), std::string::npos) << rec.meta.at("error");
  ASSERT_EQ(read.notices.size(), 1u);
  EXPECT_NE(read.notices[0].find("marked incomplete (meta.yaml complete: false; error: "), std::string::npos)
      << read.notices[0];
}

TEST(Recorder, DiskFullDuringAnImageLosesOnlyThatFrameAndSaysSo) {
  const TempDir dir("full_image");
  FakeFrameSource source(32, 16, 8);
  RecordingWriterOptions options;
  options.files = std::make_shared<FullDisk>(".png", 7);  // the left image of frame 3
  RecordingWriter writer(dir.path() + "/rec", std::nullopt, {}, options);
  const RecorderSummary s = Record(source, writer);
  EXPECT_EQ(s.stop, RecorderStop::kWriteFailed);
  EXPECT_EQ(s.frames_written, 3);
  EXPECT_NE(s.error.find("frame 3 not recorded"), std::string::npos) << s.error;
  EXPECT_NE(s.error.find(std::strerror(ENOSPC)), std::string::npos) << s.error;
  EXPECT_EQ(PartialFiles(dir.path() + "/rec"), std::vector<std::string>{});
  RecordingReadSummary read;
  const Recording rec = OpenRecording(dir.path() + "/rec", &read);
  EXPECT_EQ(rec.num_frames(), 3);
  EXPECT_EQ(read.missing_files, 0);
  ExpectRecordingHoldsTestFrames(rec, 32, 16, CV_8UC1);
}

// The system's file calls, counting the descriptors of frames.csv still open; its first write fails with ENOSPC.
class IndexHeaderFails final : public SystemCalls {
 public:
  int Open(const std::string& path, int flags, mode_t mode) override {
    const int fd = SystemCalls::Open(path, flags, mode);
    if (fd >= 0 && path.find("frames.csv") != std::string::npos) index_fds.insert(fd);
    return fd;
  }
  ssize_t Write(int fd, const void* data, size_t size) override {
    if (index_fds.count(fd) > 0) {
      errno = ENOSPC;
      return -1;
    }
    return real_->Write(fd, data, size);
  }
  int Close(int fd) override {
    index_fds.erase(fd);
    return real_->Close(fd);
  }
  std::set<int> index_fds;
};

// A recording whose frames.csv header cannot be written is an error, and the file is closed (the constructor
// threw, so no destructor closed it: one descriptor lost per attempt).
TEST(Recorder, AnIndexHeaderThatCannotBeWrittenLeavesNoOpenFile) {
  const TempDir dir("header_fails");
  const auto files = std::make_shared<IndexHeaderFails>();
  RecordingWriterOptions options;
  options.files = files;
  EXPECT_THROW(RecordingWriter(dir.path() + "/rec", std::nullopt, {}, options), Error);
  EXPECT_TRUE(files->index_fds.empty());
}

TEST(Recorder, DiskFullInTheIndexLeavesACutLineTheReaderDrops) {
  const TempDir dir("full_index");
  FakeFrameSource source(32, 16, 8);
  RecordingWriterOptions options;
  options.files = std::make_shared<FullDisk>("frames.csv", 4);  // the header, frames 0 and 1, then frame 2's line
  RecordingWriter writer(dir.path() + "/rec", std::nullopt, {}, options);
  const RecorderSummary s = Record(source, writer);
  EXPECT_EQ(s.stop, RecorderStop::kWriteFailed);
  EXPECT_EQ(s.frames_written, 2);
  EXPECT_NE(s.error.find("frame 2 not recorded"), std::string::npos) << s.error;
  EXPECT_NE(s.error.find(std::strerror(ENOSPC)), std::string::npos) << s.error;
  EXPECT_THROW(writer.Write(TestFrame(9, 32, 16, CV_8UC1)), Error);  // nothing may follow a cut line
  RecordingReadSummary read;
  const Recording rec = OpenRecording(dir.path() + "/rec", &read);
  EXPECT_TRUE(read.truncated_last_line);
  ASSERT_EQ(read.notices.size(), 2u);
  EXPECT_NE(read.notices[0].find("truncated"), std::string::npos) << read.notices[0];
  // meta.yaml could not be written at Finish either: it says what it said from the start, not complete.
  EXPECT_NE(read.notices[1].find("marked incomplete"), std::string::npos) << read.notices[1];
  EXPECT_EQ(rec.num_frames(), 2);
  ExpectRecordingHoldsTestFrames(rec, 32, 16, CV_8UC1);
}

}  // namespace
}  // namespace rangebayes
