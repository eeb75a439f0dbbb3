// The threaded pipeline on small synthetic recordings: every frame comes out in replay, results are
// deterministic, per-frame errors are counted without stopping, the stop flag ends the run cleanly.
#include "pipeline/pipeline.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <thread>

#include "capture/playback_source.h"
#include "core/error.h"
#include "pipeline/file_sink.h"
#include "stereo/pfm.h"
#include "stereo/synth.h"
#include "tests/bayes/test_meshes.h"
#include "tests/capture/test_util.h"
#include "tests/pipeline/pipeline_test_util.h"

namespace rangebayes {
namespace {
namespace fs = std::filesystem;

using testing::MakeSynthRecording;
using testing::SmallPipelineOptions;

class CollectSink : public PipelineSink {
 public:
  std::vector<PipelineResult> results;
  std::int64_t throw_on_index = -1;
  bool finished = false;
  void Consume(const PipelineResult& r) override {
    if (r.index == throw_on_index) throw Error("sink refuses this frame");
    results.push_back(r);
  }
  void Finish() override { finished = true; }
};

TEST(BoundedQueue, BlockNeverDropsDropOldestCounts) {
  BoundedQueue<int> block(2, QueueFullPolicy::kBlock);
  std::thread producer([&] {
    for (int i = 0; i < 100; ++i) block.Push(i);
    block.Close();
  });
  int expected = 0;
  while (auto v = block.Pop()) EXPECT_EQ(*v, expected++);
  producer.join();
  EXPECT_EQ(expected, 100);
  EXPECT_EQ(block.dropped(), 0);

  BoundedQueue<int> drop(2, QueueFullPolicy::kDropOldest);
  for (int i = 0; i < 5; ++i) drop.Push(i);
  EXPECT_EQ(drop.dropped(), 3);
  EXPECT_EQ(*drop.Pop(), 3);  // the newest two survive
  drop.Close();
  EXPECT_EQ(*drop.Pop(), 4);
  EXPECT_FALSE(drop.Pop().has_value());
  EXPECT_FALSE(drop.Push(9));
}

// An item the queue's predicate keeps (a full-quality frame an operator asked for) is never the one dropped: the
// oldest other item goes, or the new one when only kept items wait.
TEST(BoundedQueue, DropOldestNeverDropsAKeptItem) {
  BoundedQueue<int> q(2, QueueFullPolicy::kDropOldest, [](const int& v) { return v < 0; });
  q.Push(-1);
  q.Push(1);
  q.Push(2);  // drops 1, not the older -1
  EXPECT_EQ(q.dropped(), 1);
  EXPECT_EQ(*q.Pop(), -1);
  EXPECT_EQ(*q.Pop(), 2);

  BoundedQueue<int> one(1, QueueFullPolicy::kDropOldest, [](const int& v) { return v < 0; });
  one.Push(-1);
  one.Push(1);   // only a kept item waits: the new one is dropped
  one.Push(-2);  // kept too: the queue holds both
  EXPECT_EQ(one.dropped(), 1);
  EXPECT_EQ(*one.Pop(), -1);
  EXPECT_EQ(*one.Pop(), -2);
  EXPECT_EQ(one.size(), 0u);
}

// Median |z − z_true| over the vertices of `V` (camera frame, one vertex per pixel of `pixel`) against the
// synthetic recording's true depth at each vertex's pixel.
double MedianDepthError(const Vertices& V, const NoisyMesh& raw, const cv::Mat& depth_m) {
  std::vector<double> errors;
  for (int i = 0; i < V.rows(); ++i) {
    const int u = static_cast<int>(std::lround(raw.pixel(i, 0))), v = static_cast<int>(std::lround(raw.pixel(i, 1)));
    if (u < 0 || v < 0 || u >= depth_m.cols || v >= depth_m.rows) continue;
    const float z = depth_m.at<float>(v, u);
    if (std::isfinite(z)) errors.push_back(std::abs(V(i, 2) - z));
  }
  if (errors.empty()) return std::nan("");
  std::nth_element(errors.begin(), errors.begin() + static_cast<std::ptrdiff_t>(errors.size() / 2), errors.end());
  return errors[errors.size() / 2];
}

// Every frame through every stage: the smoothing stage moves the vertices towards the true surface (median depth
// error below the raw mesh's on each frame; the scene is three planes, which the prior favours), decimation
// leaves fewer faces.
TEST(Pipeline, ReplayDeliversEveryFrameThroughAllStages) {
  const TempDir dir("pipe_all");
  const std::string folder = MakeSynthRecording(dir, 3);
  const Recording rec = OpenRecording(folder);
  const cv::Mat depth_m = ReadPfm(folder + "/ground_truth/depth_left_m.pfm");
  PlaybackSource source(rec);
  CollectSink sink;
  std::vector<double> progress;
  PipelineOptions options = SmallPipelineOptions();
  options.progress = [&](double f, std::string_view) { progress.push_back(f); };
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
  EXPECT_EQ(s.frames_captured, 3);
  EXPECT_EQ(s.results, 3);
  EXPECT_EQ(s.failed, 0) << (s.errors.empty() ? "" : s.errors.front());
  EXPECT_EQ(s.dropped, 0);
  EXPECT_TRUE(sink.finished);
  ASSERT_EQ(sink.results.size(), 3u);
  for (size_t i = 0; i < sink.results.size(); ++i) {
    const PipelineResult& r = sink.results[i];
    EXPECT_EQ(r.index, static_cast<std::int64_t>(i));  // in frame order
    EXPECT_GT(r.raw_mesh.mesh.num_faces(), 1000);
    EXPECT_TRUE(r.raw_mesh.has_covariance());
    ASSERT_TRUE(r.smoothed.has_value());
    EXPECT_EQ(r.smoothed->num_vertices(), r.raw_mesh.mesh.num_vertices());
    ASSERT_EQ(r.raw_mesh.pixel.rows(), r.raw_mesh.mesh.num_vertices());
    const double raw_error = MedianDepthError(r.raw_mesh.mesh.V, r.raw_mesh, depth_m);
    const double smoothed_error = MedianDepthError(r.smoothed->V, r.raw_mesh, depth_m);
    std::printf("frame %d: median depth error raw %.3g m, smoothed %.3g m\n", static_cast<int>(i), raw_error,
                smoothed_error);
    EXPECT_LT(smoothed_error, raw_error) << i;
    ASSERT_TRUE(r.decimated.has_value());
    EXPECT_LT(r.decimated->mesh.num_faces(), r.raw_mesh.mesh.num_faces());
  }
  for (const StageTiming& t : s.stages) {
    EXPECT_EQ(t.items, 3) << t.name;
    // The first frame's read (before the threads start) counts with that frame (the capture's mean exceeded its
    // maximum: the read was added to the total only).
    EXPECT_LE(t.mean_ms(), t.max_ms) << t.name;
  }
  ASSERT_FALSE(progress.empty());
  EXPECT_DOUBLE_EQ(progress.back(), 1.0);

  const std::string json = dir.path() + "/summary.json";
  WritePipelineSummaryJson(s, json);
  std::ifstream in(json);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("\"triangulate\""), std::string::npos);
  EXPECT_NE(text.find("\"frames_per_s\""), std::string::npos);
}

TEST(Pipeline, ReplayIsDeterministic) {
  const TempDir dir("pipe_det");
  const Recording rec = OpenRecording(MakeSynthRecording(dir, 2));
  std::vector<Mesh> meshes;
  for (int run = 0; run < 2; ++run) {
    PlaybackSource source(rec);
    CollectSink sink;
    PipelineOptions options = SmallPipelineOptions();
    options.decimate = false;
    RunPipeline(source, *rec.rig, options, {&sink});
    ASSERT_EQ(sink.results.size(), 2u);
    meshes.push_back(*sink.results[1].smoothed);
  }
  ASSERT_EQ(meshes[0].num_vertices(), meshes[1].num_vertices());
  EXPECT_EQ((meshes[0].V - meshes[1].V).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_TRUE(meshes[0].F == meshes[1].F);
}

TEST(Pipeline, BadFramesAreCountedAndTheRunGoesOn) {
  const TempDir dir("pipe_bad");
  const std::string folder = MakeSynthRecording(dir, 4);
  fs::remove(folder + "/left/000001.png");
  const Recording rec = OpenRecording(folder);
  PlaybackSource source(rec);
  CollectSink sink;
  sink.throw_on_index = 2;
  PipelineOptions options = SmallPipelineOptions();
  options.smooth = false;
  options.decimate = false;
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
  EXPECT_EQ(s.frames_skipped, 1);
  EXPECT_EQ(s.failed, 1);
  EXPECT_EQ(s.results, 2);
  ASSERT_EQ(s.errors.size(), 2u);
  EXPECT_NE(s.errors[0].find("frame 1 skipped"), std::string::npos) << s.errors[0];
  EXPECT_NE(s.errors[1].find("frame 2: sinks: sink refuses this frame"), std::string::npos) << s.errors[1];
  EXPECT_EQ(s.notices.size(), 2u);  // smoothing and decimation switched off
}

TEST(Pipeline, WrongRigIsOneClearError) {
  const TempDir dir("pipe_rig");
  const Recording rec = OpenRecording(MakeSynthRecording(dir, 1));
  PlaybackSource source(rec);
  StereoRig rig = *rec.rig;
  rig.width = 640;
  rig.height = 480;
  try {
    RunPipeline(source, rig, SmallPipelineOptions(), {});
    FAIL() << "a rig of the wrong size must throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("the rig is for 640x480 images but frame 0 is 96x72"), std::string::npos)
        << e.what();
  }
}

TEST(Pipeline, SpaceTimeWindowsCoverTheirFrames) {
  const TempDir dir("pipe_st");
  const Recording rec = OpenRecording(MakeSynthRecording(dir, 5));
  PlaybackSource source(rec);
  CollectSink sink;
  PipelineOptions options = SmallPipelineOptions();
  options.matcher = PipelineMatcher::kSpaceTime;
  options.window_frames = 2;
  options.decimate = false;
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
  ASSERT_EQ(sink.results.size(), 2u);
  EXPECT_EQ(sink.results[0].index, 0);
  EXPECT_EQ(sink.results[0].last_index, 1);
  EXPECT_EQ(sink.results[1].index, 2);
  EXPECT_EQ(sink.results[1].frames, 2);
  ASSERT_EQ(s.notices.size(), 2u);  // decimation off, and the fifth frame did not fill a window
  EXPECT_NE(s.notices[1].find("the last 1 frame(s) did not fill"), std::string::npos) << s.notices[1];
}

TEST(Pipeline, StopFlagEndsTheRunWithCompleteOutputs) {
  const TempDir dir("pipe_stop");
  const Recording rec = OpenRecording(MakeSynthRecording(dir, 4));
  PlaybackOptions loop;
  loop.loop = true;  // an endless source: only the stop flag can end this run
  PlaybackSource source(rec, loop);
  std::atomic<bool> stop{false};
  class StopAfterTwo : public PipelineSink {
   public:
    explicit StopAfterTwo(std::atomic<bool>* s) : stop_(s) {}
    int count = 0;
    void Consume(const PipelineResult&) override {
      if (++count == 2) stop_->store(true);
    }

   private:
    std::atomic<bool>* stop_;
  } stopper(&stop);
  FileSink files(dir.path() + "/out");
  PipelineOptions options = SmallPipelineOptions();
  options.smooth = false;
  options.decimate = false;
  options.stop = &stop;
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&files, &stopper});
  EXPECT_TRUE(s.stopped);
  EXPECT_EQ(s.results, 2);
  EXPECT_EQ(s.frames_captured, s.results + s.failed + s.abandoned);
  for (int i = 0; i < 2; ++i) {
    char name[16];
    std::snprintf(name, sizeof(name), "%06d", i);
    EXPECT_TRUE(fs::file_size(dir.path() + "/out/raw/" + name + ".ply") > 0);
    EXPECT_TRUE(fs::exists(dir.path() + "/out/shaded/" + name + ".png"));
  }
}

// Progress through a window of the recording counts the window's frames ("frame 3/2" counted the frame indices
// from --first against --count).
TEST(Pipeline, ProgressCountsTheFramesOfTheWindow) {
  const TempDir dir("pipe_window_progress");
  const Recording rec = OpenRecording(MakeSynthRecording(dir, 3));
  PlaybackOptions window;
  window.first_position = 1;
  window.count = 2;
  PlaybackSource source(rec, window);
  CollectSink sink;
  std::vector<std::string> labels;
  PipelineOptions options = SmallPipelineOptions();
  options.smooth = false;
  options.decimate = false;
  options.progress = [&](double, std::string_view stage) {
    if (stage.starts_with("frame ")) labels.emplace_back(stage.substr(0, stage.find(',')));
  };
  RunPipeline(source, *rec.rig, options, {&sink});
  EXPECT_EQ(labels, (std::vector<std::string>{"frame 1/2", "frame 2/2"}));
}

// Two runs into one folder: the second removed (or truncated) the first one's results.csv while it appended to it,
// and both ended "ok" with the first run's results unlisted. The second is refused while the first's sink lives;
// after it, the folder takes a new run (here: the first's index lists nothing yet, so nothing is lost).
TEST(FileSink, ASecondRunIntoTheSameFolderIsRefusedWhileTheFirstWrites) {
  const TempDir dir("file_sink_lock");
  const std::string out = dir.path() + "/out";
  {
    FileSink first(out);
    try {
      FileSink second(out);
      ADD_FAILURE() << "a second sink took the folder";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(out + ": another run is writing its results here"), std::string::npos)
          << e.what();
    }
    EXPECT_TRUE(fs::exists(out + "/results.csv"));
  }
  EXPECT_NO_THROW(FileSink again(out));
}

// A stop requested while a frame is being smoothed or decimated ends that call at its next progress report (a
// converged full-resolution solve runs for minutes; Ctrl-C waited for it): the library reports nothing more
// after the stop, and the frame is abandoned, not failed. The stop is set from the stage's own progress, so the
// test needs no clock.
TEST(Pipeline, StopEndsTheSmoothingAndDecimationInFlight) {
  const TempDir dir("pipe_stop_in_flight");
  const Recording rec = OpenRecording(MakeSynthRecording(dir, 3));
  for (const bool in_decimation : {false, true}) {
    SCOPED_TRACE(in_decimation ? "decimation" : "smoothing");
    PlaybackSource source(rec);
    std::atomic<bool> stop{false};
    std::atomic<int> reports_after_stop{0};
    const ProgressCallback stop_at_first_report = [&](double, std::string_view) {
      if (stop.exchange(true)) ++reports_after_stop;
    };
    CollectSink sink;
    PipelineOptions options = SmallPipelineOptions();
    options.smooth = true;
    options.decimate = true;
    options.stop = &stop;
    (in_decimation ? options.decimation.progress : options.smoothing.progress) = stop_at_first_report;
    const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
    EXPECT_TRUE(s.stopped);
    EXPECT_EQ(reports_after_stop.load(), 0);
    EXPECT_EQ(s.results, 0);
    EXPECT_EQ(s.failed, 0);
    EXPECT_TRUE(sink.results.empty());
    EXPECT_GE(s.abandoned, 1);
    EXPECT_EQ(s.frames_captured, s.results + s.failed + s.abandoned);
  }
}

TEST(PipelineScaling, DownsampledIntrinsicsHalveCoordinatesPerLevel) {
  CameraIntrinsics k;
  k.fx_px = 640;
  k.fy_px = 600;
  k.cx_px = 319.5;
  k.cy_px = 240;
  k.width = 641;
  k.height = 480;
  const CameraIntrinsics h = DownsampledIntrinsics(k, 2);
  EXPECT_DOUBLE_EQ(h.fx_px, 320);
  EXPECT_DOUBLE_EQ(h.fy_px, 300);
  EXPECT_DOUBLE_EQ(h.cx_px, 159.75);  // pyrDown's pixel x sits at 2x: coordinates halve exactly
  EXPECT_EQ(h.width, 321);            // cv::pyrDown's (w + 1) / 2
  const CameraIntrinsics q = DownsampledIntrinsics(k, 4);
  EXPECT_DOUBLE_EQ(q.fx_px, 160);
  EXPECT_EQ(q.width, 161);
  EXPECT_EQ(q.height, 120);
  EXPECT_THROW(DownsampledIntrinsics(k, 3), Error);
}

// Matching at half resolution with the rig scaled to match gives the same depths: every vertex against the
// ground truth at its (full-resolution) pixel.
TEST(Pipeline, StereoDownsampleKeepsDepthsInMetres) {
  const TempDir dir("pipe_ds");
  SynthOptions o;
  o.scene = SynthScene::kPlanes;
  o.frames = 1;
  o.width = 192;
  o.height = 144;
  o.supersample = 1;
  const std::string folder = dir.path() + "/synth";
  const SynthRecording scene = RenderSynthetic(o);
  WriteSyntheticRecording(scene, o, folder);
  const Recording rec = OpenRecording(folder);
  PlaybackSource source(rec);
  CollectSink sink;
  PipelineOptions options = SmallPipelineOptions();
  options.stereo_downsample = 2;
  options.sgbm.num_disparities = 64;  // full-resolution pixels: 32 are searched at 96×72
  options.triangulate.downsample = 2;  // every 2nd full-resolution pixel: every pixel of the 96×72 depth
  options.smooth = false;
  options.decimate = false;
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
  ASSERT_EQ(sink.results.size(), 1u) << (s.errors.empty() ? "" : s.errors.front());
  const PipelineResult& r = sink.results[0];
  EXPECT_EQ(r.depth.width(), 96);
  EXPECT_EQ(r.depth.height(), 72);
  EXPECT_EQ(r.left_rectified.cols, 192);
  const NoisyMesh& m = r.raw_mesh;
  ASSERT_GT(m.mesh.num_vertices(), 96 * 72 / 2);
  std::vector<double> relative_error;
  for (int i = 0; i < m.mesh.num_vertices(); ++i) {
    const float u = m.pixel(i, 0), v = m.pixel(i, 1);
    ASSERT_TRUE(u >= 0 && u <= 191 && v >= 0 && v <= 143) << u << " " << v;
    const float z_true = scene.depth_m.at<float>(static_cast<int>(std::lround(v)), static_cast<int>(std::lround(u)));
    if (std::isfinite(z_true)) relative_error.push_back(std::abs(m.mesh.V(i, 2) - z_true) / z_true);
  }
  ASSERT_FALSE(relative_error.empty());
  std::nth_element(relative_error.begin(), relative_error.begin() + relative_error.size() / 2, relative_error.end());
  // Measured median 0.96% (SGBM's 1/16-px steps at ~10 px disparity, edges); 5% leaves room for matcher
  // changes, while intrinsics scaled wrongly (or not at all) would be off by 50–100%.
  EXPECT_LT(relative_error[relative_error.size() / 2], 0.05);
  ASSERT_FALSE(s.notices.empty());
  EXPECT_NE(s.notices.back().find("1/2 resolution (96x72, 32 disparities)"), std::string::npos) << s.notices.back();
}

// A budget far below one iteration: every frame's solve stops at its first iteration of the final solve (the
// continuation stages are skipped), says so, and still returns a finite mesh.
TEST(Pipeline, SmoothBudgetStopsTheSolve) {
  const TempDir dir("pipe_budget");
  const Recording rec = OpenRecording(MakeSynthRecording(dir, 3));
  PlaybackSource source(rec);
  CollectSink sink;
  PipelineOptions options = SmallPipelineOptions();
  options.decimate = false;
  options.smooth_budget_ms = 1e-3;
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
  ASSERT_EQ(sink.results.size(), 3u);
  for (const PipelineResult& r : sink.results) {
    ASSERT_TRUE(r.smoothed.has_value());
    EXPECT_TRUE(r.smoothed->V.allFinite());
    EXPECT_TRUE(r.smooth_time_limited);
    EXPECT_EQ(r.smooth_iterations, 1);
  }
  EXPECT_EQ(s.smooth_time_limited, 3);
  EXPECT_DOUBLE_EQ(s.smooth_iterations_mean, 1.0);
  bool noticed = false;
  for (const std::string& n : s.notices) noticed |= n.find("3 of 3 results stopped by it") != std::string::npos;
  EXPECT_TRUE(noticed);
}

// Under a budget, a static scene's frames start where the previous result agrees with them, so the results keep
// converging from frame to frame. The budget here never binds: a cap of 5 iterations per frame stands in for it,
// so the run is deterministic, and both runs solve each frame in one stage (no ε continuation, one grid level),
// so they spend the same iterations per frame. Compared by each result's energy under its own frame's data (the
// pipeline's: no adaptive ε, as EnergyOf reads it; the ray preconditioner changes the path, not the energy).
TEST(Pipeline, WarmStartKeepsAStaticSceneConverging) {
  const TempDir dir("pipe_warm");
  const Recording rec = OpenRecording(MakeSynthRecording(dir, 8));
  PipelineOptions options = SmallPipelineOptions();
  options.decimate = false;
  options.smooth_budget_ms = 1e6;
  options.smoothing.max_iterations = 5;
  options.smoothing.epsilon_continuation_stages = 0;
  options.smoothing.multilevel = false;
  std::vector<std::vector<double>> energy(2);  // per run (warm, cold), per frame
  for (const bool warm : {true, false}) {
    PlaybackSource source(rec);
    CollectSink sink;
    options.smooth_warm_start = warm;
    const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
    ASSERT_EQ(sink.results.size(), 8u);
    for (size_t k = 0; k < sink.results.size(); ++k) {
      const PipelineResult& r = sink.results[k];
      ASSERT_TRUE(r.smoothed.has_value());
      if (warm && k > 0) {
        EXPECT_GT(2 * r.smooth_warm_vertices, r.raw_mesh.mesh.num_vertices()) << k;
      } else {
        EXPECT_EQ(r.smooth_warm_vertices, 0) << k;
      }
      energy[warm ? 0 : 1].push_back(testing::EnergyOf(r.raw_mesh, r.smoothed->V, options.smoothing));
    }
    EXPECT_EQ(s.smooth_warm_started, warm ? 7 : 0);
  }
  // The first frame has no earlier result. Measured: the warm run's energies fall from 7,058 to 6,242 over the
  // eight frames while the cold run's stay at 6,565–6,932; from the fifth frame on the warm one is lower on every
  // frame, by 10% on the last. The test asks for lower from the fifth frame and 5% lower on the last.
  EXPECT_EQ(energy[0][0], energy[1][0]);
  for (size_t k = 4; k < energy[0].size(); ++k) EXPECT_LT(energy[0][k], energy[1][k]) << k;
  EXPECT_LT(energy[0].back(), 0.95 * energy[1].back());
}

TEST(Pipeline, LiveQueuesAccountForEveryFrame) {
  const TempDir dir("pipe_live");
  const Recording rec = OpenRecording(MakeSynthRecording(dir, 6));
  PlaybackOptions camera_like;
  camera_like.speed = PlaybackSpeed::kRecorded;  // real time, like a camera: frames come whether taken or not
  camera_like.speed_factor = 1000.0;             // every 33 µs, far faster than the stages
  PlaybackSource source(rec, camera_like);
  CollectSink sink;
  PipelineOptions options = SmallPipelineOptions();
  options.queue_policy = QueueFullPolicy::kDropOldest;
  options.queue_capacity = 1;
  options.triangulate.downsample = 4;
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
  // Drops depend on timing; what must hold is that every frame is either a result or a counted drop, and
  // that only the queue after capture drops.
  EXPECT_EQ(s.frames_captured, 6);  // the source delivers every frame (it waits, it never skips one)
  EXPECT_EQ(s.frames_captured, s.results + s.failed + s.dropped);
  EXPECT_GE(s.results, 1);
  ASSERT_EQ(s.dropped_per_queue.size(), 6u);
  for (size_t i = 1; i < s.dropped_per_queue.size(); ++i) EXPECT_EQ(s.dropped_per_queue[i], 0) << i;
}

TEST(Pipeline, LiveSettingsOnAReplayAsFastAsPossibleDropNothing) {
  const TempDir dir("pipe_live_fast");
  const Recording rec = OpenRecording(MakeSynthRecording(dir, 4));
  PlaybackSource source(rec);  // kFastest: not real time
  CollectSink sink;
  PipelineOptions options = SmallPipelineOptions();
  options.queue_policy = QueueFullPolicy::kDropOldest;
  options.queue_capacity = 1;
  options.decimate = false;
  const PipelineSummary s = RunPipeline(source, *rec.rig, options, {&sink});
  EXPECT_EQ(s.dropped, 0);
  EXPECT_EQ(s.results, 4);
  bool noticed = false;
  for (const std::string& n : s.notices) noticed |= n.find("not real time") != std::string::npos;
  EXPECT_TRUE(noticed);
}

}  // namespace
}  // namespace rangebayes
