// Helpers shared by the capture tests: temporary folders, deterministic frames, a plausible rig.
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>

#include "calibration/stereo_rig.h"
#include "capture/recording.h"
#include "capture/stereo_frame.h"

namespace rangebayes {

// A frame whose pixels and timestamps are a function of its index only (seeded, so reproducible).
inline StereoFrame TestFrame(std::int64_t index, int width, int height, int type) {
  StereoFrame f;
  f.index = index;
  f.timestamp_left_ns = 1'000'000'000LL + index * 33'333'333LL;
  f.timestamp_right_ns = f.timestamp_left_ns + 1000 + index;
  f.pattern_id = static_cast<int>(index % 4);
  cv::RNG rng(static_cast<std::uint64_t>(1234 + index));
  f.left.create(height, width, type);
  f.right.create(height, width, type);
  const double top = CV_MAT_DEPTH(type) == CV_16U ? 65535.0 : 255.0;
  rng.fill(f.left, cv::RNG::UNIFORM, 0.0, top);
  rng.fill(f.right, cv::RNG::UNIFORM, 0.0, top);
  return f;
}

// Sends `signal` to a child process and reaps it; returns the waitpid status.
inline int SignalAndWait(pid_t child, int signal) {
  ::kill(child, signal);
  int status = 0;
  ::waitpid(child, &status, 0);
  return status;
}

// Every frame of `rec` loads and equals TestFrame(its index) exactly (index, timestamps, pattern id, both
// images: the recording format is lossless).
inline void ExpectRecordingHoldsTestFrames(const Recording& rec, int width, int height, int type) {
  for (int i = 0; i < rec.num_frames(); ++i) {
    SCOPED_TRACE("frame position " + std::to_string(i));
    const StereoFrame got = LoadRecordingFrame(rec, i);
    const StereoFrame want = TestFrame(rec.frames[static_cast<size_t>(i)].index, width, height, type);
    EXPECT_EQ(got.index, want.index);
    EXPECT_EQ(got.timestamp_left_ns, want.timestamp_left_ns);
    EXPECT_EQ(got.timestamp_right_ns, want.timestamp_right_ns);
    EXPECT_EQ(got.pattern_id, want.pattern_id);
    ASSERT_EQ(got.left.type(), want.left.type());
    ASSERT_EQ(got.left.size(), want.left.size());
    EXPECT_EQ(cv::norm(got.left, want.left, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(got.right, want.right, cv::NORM_INF), 0.0);
  }
}

// A rectified rig of the given size: f = 100 px, baseline 0.1 m.
inline StereoRig TestRig(int width, int height) {
  StereoRig rig;
  rig.width = width;
  rig.height = height;
  rig.K_left << 100, 0, width / 2.0, 0, 100, height / 2.0, 0, 0, 1;
  rig.K_right = rig.K_left;
  rig.t_right_from_left_m = Eigen::Vector3d(-0.1, 0, 0);
  rig.is_rectified = true;
  rig.P1.leftCols<3>() = rig.K_left;
  rig.P2.leftCols<3>() = rig.K_right;
  rig.P2(0, 3) = -0.1 * 100;
  return rig;
}

}  // namespace rangebayes

#include <functional>
#include <stdexcept>

#include "capture/frame_source.h"
#include "core/error.h"
#include "tests/temp_dir.h"

namespace rangebayes {

// The message of the Error that f throws, or "no error".
inline std::string ErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

// An endless (or limited) source of TestFrames; `hook(i)` runs before frame i is returned and may throw
// (device lost) or return a status other than kFrame (timeout, skip).
class FakeFrameSource : public FrameSource {
 public:
  FakeFrameSource(int width, int height, std::int64_t limit = -1) : width_(width), height_(height), limit_(limit) {}
  std::function<FrameStatus(std::int64_t)> hook;

  FrameResult Next() override {
    FrameResult r;
    if (limit_ >= 0 && next_ >= limit_) return r;
    const std::int64_t i = next_++;
    r.status = hook ? hook(i) : FrameStatus::kFrame;
    if (r.status == FrameStatus::kFrame) {
      r.frame = TestFrame(i, width_, height_, CV_8UC1);
      ++stats_.frames_delivered;
    } else if (r.status == FrameStatus::kTimeout) {
      ++stats_.timeouts;
      r.reason = "fake timeout";
    } else if (r.status == FrameStatus::kSkipped) {
      ++stats_.frames_skipped;
      r.reason = "fake skip";
    }
    return r;
  }
  std::string Describe() const override { return "fake source"; }
  FrameSourceStats stats() const override { return stats_; }

 private:
  int width_, height_;
  std::int64_t limit_;
  std::int64_t next_ = 0;
  FrameSourceStats stats_;
};

}  // namespace rangebayes
