// PipelineControl: settings changed while a run goes on apply to the frames that enter after the change,
// a full-quality request sends one frame through the full-quality path, pause holds capture, and the live
// snapshot matches the summary at the end.
#include "pipeline/pipeline_control.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string_view>
#include <thread>

#include "capture/playback_source.h"
#include "core/error.h"
#include "stereo/synth.h"
#include "tests/capture/test_util.h"
#include "tests/pipeline/pipeline_test_util.h"

namespace rangebayes {
namespace {

using testing::MakeSynthRecording;

PipelineOptions SmallOptions() {
  PipelineOptions p = testing::SmallPipelineOptions();
  p.decimate = false;
  return p;
}

struct Seen {
  std::int64_t index;
  int ds;
  bool full_quality;
  bool decimated;
};

class CollectSink : public PipelineSink {
 public:
  void Consume(const PipelineResult& r) override {
    results.push_back({r.index, r.stereo_downsample, r.full_quality, r.decimated.has_value()});
  }
  std::vector<Seen> results;
};

TEST(PipelineControl, ChangesApplyToLaterFramesAndFullQualityRunsOnce) {
  TempDir dir("control_changes");
  const Recording rec = OpenRecording(MakeSynthRecording(dir, 6));
  PlaybackSource source(rec);
  PipelineControl control;
  PipelineOptions options = SmallOptions();
  options.control = &control;
  std::atomic<int> observed{0};
  // The observer runs in the capture thread before the frame takes its settings: changes made while frame
  // 2 is observed apply from frame 2 on.
  options.on_frame = [&](const StereoFrame& f) {
    ++observed;
    if (f.index == 2) {
      control.SetStereoDownsample(2);
      control.RequestFullQuality();
    }
  };
  CollectSink sink;
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
  ASSERT_EQ(s.results, 6);
  EXPECT_EQ(observed.load(), 6);
  ASSERT_EQ(sink.results.size(), 6u);
  for (const Seen& r : sink.results) {
    EXPECT_EQ(r.full_quality, r.index == 2) << r.index;
    EXPECT_EQ(r.ds, r.index < 3 ? 1 : 2) << r.index;  // the full-quality frame is matched at full resolution
    EXPECT_EQ(r.decimated, r.full_quality) << r.index;  // it is decimated even with decimation off
  }
  const PipelineSnapshot snap = control.Snapshot();
  EXPECT_FALSE(snap.running);
  EXPECT_EQ(snap.results, 6);
  EXPECT_EQ(snap.frames_captured, 6);
  EXPECT_EQ(snap.full_quality_done, 1);
  ASSERT_EQ(snap.stages.size(), s.stages.size());
  EXPECT_EQ(snap.stages[2].items, s.stages[2].items);
  EXPECT_EQ(control.settings().stereo_downsample, 2);
}

// Polls `done` until it holds or `seconds` pass; returns whether it held.
template <typename Predicate>
bool WaitFor(Predicate done, double seconds) {
  const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return done();
}

// A paused run takes no frame: each frame that enters is checked, as it enters, for a pause in force (the capture
// thread's observer), so a frame taken while paused fails the test whenever it comes. Once the run has started,
// it is held paused for a second (an unpaused run takes its first frame within milliseconds; the wait ends
// early only on a frame taken, so a working pause gives the same result on a slow machine), then resumed:
// every frame comes.
TEST(PipelineControl, PauseHoldsCaptureUntilResumed) {
  TempDir dir("control_pause");
  const Recording rec = OpenRecording(MakeSynthRecording(dir, 3));
  PlaybackSource source(rec);
  PipelineControl control;
  control.SetPaused(true);  // kept by RunPipeline
  PipelineOptions options = SmallOptions();
  options.control = &control;
  std::atomic<int> taken{0}, taken_while_paused{0};
  options.on_frame = [&](const StereoFrame&) {
    ++taken;
    if (control.settings().paused) ++taken_while_paused;
  };
  PipelineSummary s;
  std::thread run([&] { s = RunPipeline(source, *rec.rig, options, {}); });
  EXPECT_TRUE(WaitFor([&] { return control.Snapshot().running; }, 60.0));
  EXPECT_FALSE(WaitFor([&] { return taken.load() > 0; }, 1.0));
  const PipelineSnapshot paused = control.Snapshot();
  EXPECT_TRUE(paused.running);
  EXPECT_EQ(paused.frames_captured, 0);
  control.SetPaused(false);
  run.join();
  EXPECT_EQ(taken_while_paused.load(), 0);
  EXPECT_EQ(taken.load(), 3);
  EXPECT_EQ(s.frames_captured, 3);
  EXPECT_EQ(s.results, 3);
}

// A sink that holds its first result until released, so that every queue and stage before it fills up.
class GateSink : public PipelineSink {
 public:
  void Consume(const PipelineResult& r) override {
    std::unique_lock<std::mutex> lock(mutex_);
    open_.wait(lock, [&] { return released_; });
    full_quality_seen_ |= r.full_quality;
  }
  void Release() {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      released_ = true;
    }
    open_.notify_all();
  }
  bool full_quality_seen() {
    std::lock_guard<std::mutex> lock(mutex_);
    return full_quality_seen_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable open_;
  bool released_ = false;
  bool full_quality_seen_ = false;
};

std::int64_t StageItems(const PipelineSnapshot& snap, const std::string& name) {
  for (const StageTiming& t : snap.stages) {
    if (t.name == name) return t.items;
  }
  return -1;
}

// On the live path the queue after capture drops its oldest frame: the frame a "capture now" took was dropped by
// the next one whenever the pipeline was busy, and the operator's capture never came. Here the pipeline is held
// full (the sink waits), the request is taken by a frame then, and two more frames arrive behind it (and are
// dropped) before the sink lets go.
TEST(PipelineControl, AFullQualityFrameIsNeverDroppedOnTheLivePath) {
  TempDir dir("control_full_quality_live");
  const Recording rec = OpenRecording(MakeSynthRecording(dir, 24));
  PlaybackOptions camera_like;
  camera_like.speed = PlaybackSpeed::kRecorded;  // real time: the queue after capture drops
  camera_like.speed_factor = 1000.0;
  PlaybackSource source(rec, camera_like);
  PipelineControl control;
  PipelineOptions options = SmallOptions();
  ApplyLivePathPreset(&options);
  options.control = &control;
  GateSink sink;
  // With the sink holding the first result, rectify has taken its last frame once it has handled one for the
  // sink, and one for each of the five queues and the five stages (it included) after it.
  constexpr std::int64_t kRectifiedWhenFull = 11;
  int requested_at = -1;
  options.on_frame = [&](const StereoFrame& f) {
    // Until the pipeline is full, each frame waits for the one before to be taken, so that none is dropped.
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    for (;;) {
      const PipelineSnapshot snap = control.Snapshot();
      if (StageItems(snap, "rectify") >= kRectifiedWhenFull) break;
      if (!snap.queue_fill.empty() && snap.queue_fill[0] == 0) return;
      if (std::chrono::steady_clock::now() > deadline) {
        sink.Release();
        throw Error("the pipeline did not fill up");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    if (requested_at < 0) {
      control.RequestFullQuality();  // taken by this frame, which then waits in the full queue
      requested_at = static_cast<int>(f.index);
    } else if (f.index >= requested_at + 2) {
      sink.Release();  // two frames came after it while it waited
    }
  };
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
  sink.Release();
  ASSERT_GE(requested_at, 0);
  EXPECT_GT(s.dropped, 0);  // frames did wait behind it and were dropped
  EXPECT_TRUE(sink.full_quality_seen()) << "the requested frame " << requested_at << " never came out";
  EXPECT_EQ(control.Snapshot().full_quality_done, 1);
  EXPECT_EQ(control.Snapshot().full_quality_failed, 0);
}

// Keeps the results in the order they reach the sinks, and lets another thread wait for them.
class OrderSink : public PipelineSink {
 public:
  void Consume(const PipelineResult& r) override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      results_.push_back({r.index, r.stereo_downsample, r.full_quality, r.decimated.has_value()});
    }
    changed_.notify_all();
  }
  // Waits until `live` results that are not full-quality have arrived (or `seconds` pass); returns whether they did.
  bool WaitForLiveResults(int live, double seconds) {
    std::unique_lock<std::mutex> lock(mutex_);
    return changed_.wait_for(lock, std::chrono::duration<double>(seconds), [&] {
      return std::count_if(results_.begin(), results_.end(), [](const Seen& r) { return !r.full_quality; }) >= live;
    });
  }
  std::vector<Seen> results() {
    std::lock_guard<std::mutex> lock(mutex_);
    return results_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable changed_;
  std::vector<Seen> results_;
};

// Where the full-quality result of frame `index` lies in `results` (-1: absent).
int FullQualityPosition(const std::vector<Seen>& results, std::int64_t index) {
  for (size_t i = 0; i < results.size(); ++i) {
    if (results[i].full_quality && results[i].index == index) return static_cast<int>(i);
  }
  return -1;
}

// A capture (frame 2) ran on the stage threads in sequence with the live frames, so no live result came out while it
// was processed: the operator's live view froze for the whole capture. Here the capture's smoothing is held (in its
// progress callback: live smoothing is off, so every call is the capture's) until every other frame of the
// recording has reached the sink, then let go. The live frames must come meanwhile, and the run, whose source has
// ended by then, must wait for the capture and deliver it.
TEST(PipelineControl, LiveResultsGoOnWhileACaptureRunsAndTheRunWaitsForIt) {
  TempDir dir("control_capture_beside_live");
  constexpr int kFrames = 10;
  const Recording rec = OpenRecording(MakeSynthRecording(dir, kFrames));
  PlaybackSource source(rec);
  PipelineControl control;
  PipelineOptions options = SmallOptions();
  options.smooth = false;
  options.control = &control;
  options.on_frame = [&](const StereoFrame& f) {
    if (f.index == 2) control.RequestFullQuality();
  };
  OrderSink sink;
  std::atomic<bool> held{false};
  std::atomic<bool> live_went_on{false};
  options.smoothing.progress = [&](double, std::string_view) {
    if (held.exchange(true)) return;
    live_went_on = sink.WaitForLiveResults(kFrames - 1, 60.0);
  };
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
  ASSERT_TRUE(held.load()) << "the capture was never smoothed";
  EXPECT_TRUE(live_went_on.load()) << "no live result came while the capture was held";
  EXPECT_EQ(s.results, kFrames);
  const std::vector<Seen> results = sink.results();
  ASSERT_EQ(results.size(), static_cast<size_t>(kFrames));
  EXPECT_EQ(FullQualityPosition(results, 2), kFrames - 1) << "the capture is the last result";
  EXPECT_TRUE(results.back().decimated);
  EXPECT_EQ(control.Snapshot().full_quality_done, 1);
  EXPECT_EQ(control.Snapshot().full_quality_failed, 0);
}

// A second request while a capture is in progress is taken by the next frame, which waits for the first capture to
// finish: both come, each once, and every other frame comes once as a live result.
TEST(PipelineControl, ASecondCaptureWhileOneRunsIsQueued) {
  TempDir dir("control_capture_second");
  constexpr int kFrames = 10;
  const Recording rec = OpenRecording(MakeSynthRecording(dir, kFrames));
  PlaybackSource source(rec);
  PipelineControl control;
  PipelineOptions options = SmallOptions();
  options.smooth = false;
  options.control = &control;
  options.on_frame = [&](const StereoFrame& f) {
    if (f.index == 2 || f.index == 4) control.RequestFullQuality();
  };
  OrderSink sink;
  std::atomic<bool> held{false};
  std::atomic<bool> live_went_on{false};
  options.smoothing.progress = [&](double, std::string_view) {
    if (held.exchange(true)) return;
    live_went_on = sink.WaitForLiveResults(kFrames - 2, 60.0);  // frame 4 was taken while frame 2's capture ran
  };
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
  EXPECT_TRUE(live_went_on.load()) << "no live result came while the capture was held";
  EXPECT_EQ(s.results, kFrames);
  const std::vector<Seen> results = sink.results();
  const int first = FullQualityPosition(results, 2);
  const int second = FullQualityPosition(results, 4);
  EXPECT_GE(first, 0);
  EXPECT_GT(second, first);
  for (const Seen& r : results) EXPECT_EQ(r.full_quality, r.index == 2 || r.index == 4) << r.index;
  EXPECT_EQ(control.Snapshot().full_quality_done, 2);
}

// A stop request (Ctrl-C) while a capture is smoothed cancels it at the solver's next report instead of finishing a
// solve whose result would be thrown away, and says so: the capture counts as failed with the reason (what the
// console shows as capture_error), not as silently gone.
TEST(PipelineControl, AStopCancelsACaptureInProgressAndSaysSo) {
  TempDir dir("control_capture_stop");
  constexpr int kFrames = 6;
  const Recording rec = OpenRecording(MakeSynthRecording(dir, kFrames));
  PlaybackSource source(rec);
  PipelineControl control;
  PipelineOptions options = SmallOptions();
  options.smooth = false;
  options.control = &control;
  std::atomic<bool> stop{false};
  options.stop = &stop;
  options.on_frame = [&](const StereoFrame& f) {
    if (f.index == 1) control.RequestFullQuality();
  };
  OrderSink sink;
  std::atomic<int> reports_after_stop{0};
  options.smoothing.progress = [&](double, std::string_view) {
    if (stop.exchange(true)) ++reports_after_stop;
  };
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
  EXPECT_TRUE(s.stopped);
  EXPECT_EQ(reports_after_stop.load(), 0) << "the capture's solve went on after the stop";
  EXPECT_EQ(FullQualityPosition(sink.results(), 1), -1);
  const PipelineSnapshot snap = control.Snapshot();
  EXPECT_EQ(snap.full_quality_done, 0);
  EXPECT_EQ(snap.full_quality_failed, 1);
  EXPECT_NE(snap.full_quality_error.find("frame 1: "), std::string::npos) << snap.full_quality_error;
  EXPECT_NE(snap.full_quality_error.find("stopped"), std::string::npos) << snap.full_quality_error;
  EXPECT_EQ(s.failed, 0) << "a cancelled capture is abandoned work, not a failed frame";
  EXPECT_GE(s.abandoned, 1);
}

TEST(PipelineControl, RefusesSettingsOutOfRange) {
  PipelineControl control;
  EXPECT_THROW(control.SetStereoDownsample(3), Error);
  EXPECT_THROW(control.SetSmoothBudgetMs(-1.0), Error);
  EXPECT_THROW(control.SetMatcher(PipelineMatcher::kSgbm, 4), Error);
  EXPECT_EQ(control.settings().stereo_downsample, 1);  // unchanged
  control.SetMatcher(PipelineMatcher::kSpaceTime, 4);
  EXPECT_EQ(control.settings().window_frames, 4);
}

}  // namespace
}  // namespace rangebayes
