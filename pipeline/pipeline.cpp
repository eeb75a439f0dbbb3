#include "pipeline/pipeline.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <string_view>
#include <thread>

#include "core/error.h"
#include "core/files.h"
#include "core/json_text.h"
#include "pipeline/pipeline_control.h"
#include "stereo/disparity_features.h"

namespace rangebayes {
namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// The settings one frame is processed with (from the options, or from a PipelineControl when it entered).
struct ItemSettings {
  int ds = 1;
  PipelineMatcher matcher = PipelineMatcher::kSgbm;
  int window = 1;
  int step = 1;
  double smooth_budget_ms = 0.0;
  bool full_quality = false;
};

struct Item {
  std::vector<StereoFrame> frames;
  std::vector<cv::Mat> left_rect, right_rect;
  PipelineResult result;
  Clock::time_point captured;
  ItemSettings settings;
};
using ItemPtr = std::unique_ptr<Item>;
using ItemQueue = BoundedQueue<ItemPtr>;

// Thrown by a stage's work when a stop is requested while it runs (through the library's progress callback, see
// Run::EndOnStop): the item is abandoned as one popped after the stop is, not counted as failed.
struct StopRequested {};

// State shared by the stage threads of one run.
class Run {
 public:
  Run(const PipelineOptions& options, const std::vector<PipelineSink*>& sinks) : options_(options), sinks_(sinks) {}

  bool Stopping() const {
    return halt_.load(std::memory_order_relaxed) ||
           (options_.stop != nullptr && options_.stop->load(std::memory_order_relaxed));
  }
  void Halt() { halt_.store(true); }

  // `progress` that first ends the call once a stop was requested: a converged solve of a full-resolution frame
  // runs for minutes, and Ctrl-C waited for it (15-20 s on a 320x240 replay). It throws StopRequested (the item is
  // abandoned), or Error(reason) when a reason is given (a capture, whose failure is reported with it).
  ProgressCallback EndOnStop(ProgressCallback progress, const char* reason = nullptr) const {
    return [this, progress = std::move(progress), reason](double fraction, std::string_view stage) {
      if (Stopping()) {
        if (reason != nullptr) throw Error(reason);
        throw StopRequested{};
      }
      if (progress) progress(fraction, stage);
    };
  }

  void AddError(const std::string& line) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (summary_.errors.size() < 100) summary_.errors.push_back(line);
  }
  void AddAbandoned() {
    std::lock_guard<std::mutex> lock(mutex_);
    ++summary_.abandoned;
  }

  // Runs `work` on an item with timing and error capture: no exception leaves it. False when a stop ended the work
  // (StopRequested): the caller abandons the item.
  template <typename Work>
  bool Process(Item& item, StageTiming* timing, const Work& work) {
    if (!item.result.error.empty()) return true;
    const auto start = Clock::now();
    try {
      work(item);
    } catch (const StopRequested&) {
      return false;
    } catch (const std::exception& e) {
      // "smooth: …" from the library keeps its own prefix (it was "smooth: smooth: …").
      const std::string what = e.what();
      const std::string prefix = StrCat(timing->name, ": ");
      item.result.error = what.rfind(prefix, 0) == 0 ? what : prefix + what;
      item.result.error_stage = timing->name;
    } catch (...) {
      item.result.error = StrCat(timing->name, ": unknown error");
      item.result.error_stage = timing->name;
    }
    const double ms = MsSince(start);
    std::lock_guard<std::mutex> lock(mutex_);  // a PipelineControl may read the timings while the run goes on
    if (!item.result.error.empty()) ++timing->errors;
    ++timing->items;
    timing->total_ms += ms;
    timing->max_ms = std::max(timing->max_ms, ms);
    return true;
  }

  // A plain one-in-one-out stage; returns once `in` is closed and drained (the caller closes `out`).
  template <typename Work>
  void Stage(ItemQueue& in, ItemQueue& out, StageTiming* timing, const Work& work) {
    while (auto item = in.Pop()) {
      if (Stopping() || !Process(**item, timing, work)) {
        AddAbandoned();
        continue;
      }
      out.Push(std::move(*item));
    }
  }

  // Counts a full-quality result, done or failed (with its reason).
  void AddFullQuality(const PipelineResult& result) {
    std::lock_guard<std::mutex> lock(mutex_);
    if (result.error.empty()) {
      ++full_quality_done_;
    } else {
      ++full_quality_failed_;
      full_quality_error_ = StrCat("frame ", result.index, ": ", result.error);
    }
  }
  // Under mutex().
  std::int64_t full_quality_done() const { return full_quality_done_; }
  std::int64_t full_quality_failed() const { return full_quality_failed_; }
  const std::string& full_quality_error() const { return full_quality_error_; }

  PipelineSummary& summary() { return summary_; }
  std::mutex& mutex() { return mutex_; }
  const PipelineOptions& options() const { return options_; }
  const std::vector<PipelineSink*>& sinks() const { return sinks_; }

 private:
  const PipelineOptions& options_;
  const std::vector<PipelineSink*>& sinks_;
  std::atomic<bool> halt_{false};
  std::mutex mutex_;
  PipelineSummary summary_;
  std::int64_t full_quality_done_ = 0;
  std::int64_t full_quality_failed_ = 0;
  std::string full_quality_error_;
};

// Matcher, camera and triangulation settings for stereo at 1/ds resolution.
struct MatchSetup {
  CameraIntrinsics intrinsics;
  SgbmMatcherOptions sgbm;
  SpaceTimeMatcherOptions spacetime;
  TriangulateOptions triangulate;
};

MatchSetup MakeMatchSetup(const PipelineOptions& options, const CameraIntrinsics& full, int ds,
                          int triangulate_downsample) {
  MatchSetup m;
  m.intrinsics = DownsampledIntrinsics(full, ds);
  // Disparity ranges are given in full-resolution pixels: at 1/ds resolution they shrink by ds.
  m.sgbm = options.sgbm;
  m.spacetime = options.spacetime;
  if (ds > 1) {
    const auto floor_div = [ds](int v) { return v >= 0 ? v / ds : -((-v + ds - 1) / ds); };
    m.sgbm.num_disparities = std::max(1, (options.sgbm.num_disparities + ds - 1) / ds);
    m.sgbm.min_disparity_px = floor_div(options.sgbm.min_disparity_px);
    m.spacetime.num_disparities = std::max(3, (options.spacetime.num_disparities + ds - 1) / ds);
    m.spacetime.min_disparity_px = floor_div(options.spacetime.min_disparity_px);
  }
  m.triangulate = options.triangulate;
  m.triangulate.downsample = std::max(1, (triangulate_downsample + ds / 2) / ds);
  return m;
}

int DsSlot(int ds) { return ds == 1 ? 0 : ds == 2 ? 1 : ds == 4 ? 2 : 3; }

ItemPtr MakeItem(StereoFrame frame) {
  auto item = std::make_unique<Item>();
  item->captured = Clock::now();
  item->result.index = frame.index;
  item->result.last_index = frame.index;
  item->result.timestamp_ns = frame.timestamp_ns();
  item->result.entered_steady_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(item->captured.time_since_epoch()).count();
  item->result.frames = 1;
  item->frames.push_back(std::move(frame));
  return item;
}

cv::Mat ToMatcherInput(const cv::Mat& image) {
  // Our matchers take 8/16-bit grey or colour; keep it, but drop an alpha channel if a camera gave one.
  if (image.channels() == 4) {
    cv::Mat bgr;
    cv::Mat channels[4];
    cv::split(image, channels);
    cv::merge(channels, 3, bgr);
    return bgr;
  }
  return image;
}

cv::Mat Shrink(const cv::Mat& image, int factor) {
  cv::Mat out = image;
  for (int f = factor; f > 1; f /= 2) {
    cv::Mat half;
    cv::pyrDown(out, half);
    out = half;
  }
  return out;
}

// The gate of a warm start (PipelineOptions::smooth_warm_start): the previous result counts at a vertex within
// this many standard deviations of its new measurement (Mahalanobis distance under its covariance).
constexpr double kWarmStartSigmas = 3.0;

// What the smoothing stage did, for the summary (written by the smooth stage only, read after the join).
struct SmoothTally {
  int smoothed = 0;
  double iterations_sum = 0.0;
  double ms_per_iteration_sum = 0.0;
  int timed = 0;
  int time_limited = 0;
  int warm_started = 0;
  double distance_sum = 0.0;  // relative E − E* estimates, over results with a finite one
  int distances = 0;
};

// Results whose search range looks too short (DisparityResult::range_end_fraction), for the summary's notice.
struct RangeEndTally {
  int results = 0;
  double max = 0.0;
};

int MatcherSlot(PipelineMatcher matcher) { return matcher == PipelineMatcher::kSgbm ? 0 : 1; }

// The matcher held in `slot`, made with `setup` when it is first needed.
StereoMatcher& MatcherFor(PipelineMatcher matcher, const MatchSetup& setup, std::unique_ptr<StereoMatcher>* slot) {
  if (!*slot) {
    if (matcher == PipelineMatcher::kSgbm) {
      *slot = std::make_unique<SgbmMatcher>(setup.sgbm);
    } else {
      *slot = std::make_unique<SpaceTimeMatcher>(setup.spacetime);
    }
  }
  return **slot;
}

// The full-quality worker (Stages::FullQualityStage): captures that may wait for it (a further request waits for
// room) and the threads its steps use. One thread leaves the live stages the other core of a 2-core rig; a lower
// priority for it (nice +10) measured no faster live path and a capture 2.3 times as long (docs/console.md).
constexpr size_t kMaxWaitingCaptures = 4;
constexpr int kFullQualityThreads = 1;
constexpr const char* kCaptureStopped = "stopped before the capture finished";

}  // namespace

CameraIntrinsics DownsampledIntrinsics(const CameraIntrinsics& full, int factor) {
  RB_CHECK(factor == 1 || factor == 2 || factor == 4 || factor == 8, "stereo downsample must be 1, 2, 4 or 8, got ",
           factor);
  CameraIntrinsics k = full;
  for (int f = factor; f > 1; f /= 2) {
    k.fx_px *= 0.5;
    k.fy_px *= 0.5;
    k.cx_px *= 0.5;
    k.cy_px *= 0.5;
    k.width = (k.width + 1) / 2;
    k.height = (k.height + 1) / 2;
  }
  return k;
}

void CheckSmoothBudgetMs(double budget_ms) {
  RB_CHECK(budget_ms >= 0.0 && budget_ms <= 1e3 * kMaxSmoothTimeLimitS, "smoothing budget must be in [0, ",
           1e3 * kMaxSmoothTimeLimitS, "] ms, got ", budget_ms);
}

void PipelineOptions::Check() const {
  RB_CHECK(queue_capacity >= 1 && queue_capacity <= 64, "pipeline queue capacity must be in 1..64, got ",
           queue_capacity);
  RB_CHECK(window_frames >= 1 && window_frames <= 256, "space-time window must be 1..256 frames, got ",
           window_frames);
  RB_CHECK(window_step_frames >= 0 && window_step_frames <= window_frames,
           "space-time window step must be in 0..window_frames, got ", window_step_frames);
  RB_CHECK(max_consecutive_timeouts >= 1, "max_consecutive_timeouts must be >= 1");
  RB_CHECK(stereo_downsample == 1 || stereo_downsample == 2 || stereo_downsample == 4 || stereo_downsample == 8,
           "stereo downsample must be 1, 2, 4 or 8, got ", stereo_downsample);
  CheckSmoothBudgetMs(smooth_budget_ms);
  RB_CHECK(full_quality_triangulate_downsample >= 1 && full_quality_triangulate_downsample <= 64,
           "full-quality triangulation downsample must be in 1..64, got ", full_quality_triangulate_downsample);
  rectify.Check();
  sgbm.Check();
  spacetime.Check();
  depth.Check();
  triangulate.Check();
  if (smooth) smoothing.Check();
  if (decimate) decimation.Check();
}

void ApplyDisparityNoiseModel(const DisparityNoiseModel& model, const std::string& name, PipelineOptions* options) {
  model.Check();
  options->noise_model = model;
  options->noise_model_name = name;
  ApplyDisparityNoiseModel(model, &options->triangulate);
  ApplyDisparityNoiseModel(model, &options->spacetime);
}

void ApplyLivePathPreset(PipelineOptions* options) {
  options->queue_policy = QueueFullPolicy::kDropOldest;
  options->queue_capacity = 1;
  options->stereo_downsample = kLiveStereoDownsample;
  options->triangulate.downsample = kLiveTriangulateDownsample;
  options->smoothing.tolerance = SmoothTolerance::kFast;
  options->smooth_budget_ms = kLiveSmoothBudgetMs;
  options->decimate = false;
}

namespace {

// One run of the pipeline: the settings, the queues between the stages and the summary they fill, with one
// member function per stage thread. Constructed (and the first frame read) before any thread starts.
class Stages {
 public:
  Stages(FrameSource& source, const StereoRig& rig, const PipelineOptions& options,
         const std::vector<PipelineSink*>& sinks)
      : source(source),
        rig(rig),
        options(options),
        sinks(sinks),
        rectifier(rig, options.rectify),
        ds(options.stereo_downsample),
        window(options.window_frames),
        step(options.window_step_frames > 0 ? options.window_step_frames : options.window_frames),
        control(options.control),
        frames_total(source.frames_total()),
        run(options, sinks),
        summary(run.summary()) {
    // One setup per downsample factor (a control may change it between frames), and one for the full-quality
    // path.
    for (const int f : {1, 2, 4, 8}) {
      setups[DsSlot(f)] = MakeMatchSetup(options, rectifier.intrinsics(), f, options.triangulate.downsample);
    }
    full_quality_setup = MakeMatchSetup(options, rectifier.intrinsics(), 1, options.full_quality_triangulate_downsample);
    summary.source = source.Describe();
    const std::vector<std::string> names = {"capture", "rectify", "stereo", "triangulate", "smooth", "decimate",
                                            "sinks"};
    summary.stages.resize(names.size());
    for (size_t i = 0; i < names.size(); ++i) summary.stages[i].name = names[i];
    t_capture = &summary.stages[0];
    t_rectify = &summary.stages[1];
    t_stereo = &summary.stages[2];
    t_triangulate = &summary.stages[3];
    t_smooth = &summary.stages[4];
    t_decimate = &summary.stages[5];
    t_sinks = &summary.stages[6];
    summary.queue_capacity = options.queue_capacity;
    if (!options.smooth) summary.notices.push_back("smoothing switched off: results carry no smoothed mesh");
    if (!options.decimate) summary.notices.push_back("decimation switched off: results carry no decimated mesh");

    // The first frame is read before the threads start so that a rig that does not fit the recording is one
    // clear error instead of a failure per frame.
    run_start = Clock::now();
    {
      const auto start = Clock::now();
      FrameResult r = source.Next();
      first_read_ms = MsSince(start);
      if (r.status == FrameStatus::kFrame) {
        RB_CHECK(r.frame.left.cols == rig.width && r.frame.left.rows == rig.height, "the rig is for ", rig.width, "x",
                 rig.height, " images but frame ", r.frame.index, " is ", r.frame.left.cols, "x", r.frame.left.rows,
                 " (wrong rig.yaml?)");
      }
      first = std::move(r);
    }

    // Live drops only where frames enter: a stage downstream waits for the next one rather than work on a
    // frame that would be thrown away, so the pipeline runs at the pace of its slowest stage and no CPU time
    // goes to frames that never come out. A source that is not real time (a recording played as fast as
    // possible) is never dropped from: it is simply asked for the next frame when there is room.
    // A frame a control asked to see at full quality goes to the full-quality worker instead, through a queue that
    // never drops (CaptureStage takes a request only when that queue has room).
    const bool drop_at_capture = options.queue_policy == QueueFullPolicy::kDropOldest && source.realtime();
    for (int i = 0; i < 6; ++i) {
      queues.push_back(std::make_unique<ItemQueue>(
          options.queue_capacity, i == 0 && drop_at_capture ? QueueFullPolicy::kDropOldest : QueueFullPolicy::kBlock));
    }
    if (options.queue_policy == QueueFullPolicy::kDropOldest && !source.realtime()) {
      summary.notices.push_back(
          "live settings on a source that is not real time: frames are read when the pipeline has room, none dropped");
    }
  }

  // What a PipelineControl shows while the run goes on.
  PipelineSnapshot Snapshot() {
    PipelineSnapshot snap;
    snap.running = true;
    snap.wall_s = std::chrono::duration<double>(Clock::now() - run_start).count();
    for (const auto& q : queues) {
      snap.queue_fill.push_back(static_cast<int>(q->size()));
      snap.dropped += q->dropped();
    }
    snap.queue_capacity = options.queue_capacity;
    std::lock_guard<std::mutex> lock(run.mutex());
    snap.frames_captured = summary.frames_captured;
    snap.frames_skipped = summary.frames_skipped;
    snap.timeouts = summary.timeouts;
    snap.results = summary.results;
    snap.failed = summary.failed;
    snap.full_quality_done = run.full_quality_done();
    snap.full_quality_failed = run.full_quality_failed();
    snap.full_quality_error = run.full_quality_error();
    snap.stages = summary.stages;
    const size_t n = summary.errors.size();
    snap.errors.assign(summary.errors.begin() + static_cast<std::ptrdiff_t>(n > 20 ? n - 20 : 0),
                       summary.errors.end());
    return snap;
  }

  // The settings a frame entering now is processed with.
  ItemSettings SettingsNow() {
    ItemSettings s;
    s.ds = ds;
    s.matcher = options.matcher;
    s.window = window;
    s.step = step;
    s.smooth_budget_ms = options.smooth_budget_ms;
    if (control != nullptr) {
      const PipelineSettings c = control->settings();
      s.ds = c.stereo_downsample;
      s.matcher = c.matcher;
      s.window = c.window_frames;
      s.step = c.window_frames == window ? step : c.window_frames;
      s.smooth_budget_ms = c.smooth_budget_ms;
      // A request waits (and later requests join it) while kMaxWaitingCaptures captures wait for the worker.
      if (full_quality_queue.size() < kMaxWaitingCaptures && control->TakeFullQualityRequest()) {
        s.full_quality = true;
        s.ds = 1;
        s.window = 1;
        s.step = 1;
        s.smooth_budget_ms = 0.0;
      }
    }
    return s;
  }

  void CaptureStage() {
    int consecutive_timeouts = 0;
    while (!run.Stopping()) {
      if (control != nullptr && control->settings().paused) {
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        continue;
      }
      FrameResult r;
      const auto start = Clock::now();
      double earlier_ms = 0.0;  // the first frame's read, before the threads started
      try {
        if (first.has_value()) {
          r = std::move(*first);
          first.reset();
          earlier_ms = first_read_ms;
        } else {
          r = source.Next();
        }
      } catch (const std::exception& e) {
        std::lock_guard<std::mutex> lock(run.mutex());
        summary.fatal_error = e.what();
        break;
      }
      if (r.status == FrameStatus::kEndOfStream) break;
      if (r.status == FrameStatus::kTimeout) {
        std::lock_guard<std::mutex> lock(run.mutex());
        ++summary.timeouts;
        if (++consecutive_timeouts >= options.max_consecutive_timeouts) {
          summary.fatal_error = StrCat(source.Describe(), ": no frame after ", consecutive_timeouts, " timeouts",
                                       r.reason.empty() ? "" : " (" + r.reason + ")");
          break;
        }
        continue;
      }
      consecutive_timeouts = 0;
      if (r.status == FrameStatus::kSkipped) {
        {
          std::lock_guard<std::mutex> lock(run.mutex());
          ++summary.frames_skipped;
        }
        run.AddError(StrCat("frame ", r.frame.index, " skipped: ", r.reason));
        continue;
      }
      if (options.on_frame) {
        try {
          options.on_frame(r.frame);
        } catch (const std::exception& e) {
          {
            std::lock_guard<std::mutex> lock(run.mutex());
            ++summary.frames_skipped;
          }
          run.AddError(StrCat("frame ", r.frame.index, " skipped: frame observer: ", e.what()));
          continue;
        }
      }
      const double ms = MsSince(start) + earlier_ms;
      ItemPtr item = MakeItem(std::move(r.frame));
      item->settings = SettingsNow();
      item->result.full_quality = item->settings.full_quality;
      item->result.stereo_downsample = item->settings.ds;
      {
        std::lock_guard<std::mutex> lock(run.mutex());
        ++t_capture->items;
        t_capture->total_ms += ms;
        t_capture->max_ms = std::max(t_capture->max_ms, ms);
        ++summary.frames_captured;
      }
      (item->settings.full_quality ? full_quality_queue : *queues[0]).Push(std::move(item));
    }
    (*queues[0]).Close();
    full_quality_queue.Close();
  }

  // The work of each stage on one item, shared by the live stages and the full-quality worker.
  void Rectify(Item& item) const {
    const StereoFrame& f = item.frames.front();
    RB_CHECK(f.left.size() == f.right.size(), "frame ", f.index, ": left is ", f.left.cols, "x", f.left.rows,
             " but right is ", f.right.cols, "x", f.right.rows);
    cv::Mat l, r;
    rectifier.Rectify(ToMatcherInput(f.left), ToMatcherInput(f.right), &l, &r);
    item.result.left_rectified = l;
    item.left_rect.push_back(Shrink(l, item.settings.ds));
    item.right_rect.push_back(Shrink(r, item.settings.ds));
    item.frames.clear();  // the raw images are not needed downstream
  }

  void Match(Item& item, StereoMatcher& matcher, const MatchSetup& setup, RangeEndTally* range_end) const {
    const int f = item.settings.ds;
    DisparityResult d = matcher.Match(item.left_rect, item.right_rect);
    if (d.range_end_fraction >= kRangeEndWarning) ++range_end->results;
    range_end->max = std::max(range_end->max, d.range_end_fraction);
    if (options.noise_model) {
      // The space-time matcher of the pipeline runs the block matcher's configuration (SpaceTimeMatcherOptions{})
      // over the window's frames: the models of `calibrate noise --matcher block` are fitted on it (σ_pred, from
      // the cost's curvature, carries the frame count). Its 'spacetime' models are of `rangebayes spacetime`'s
      // static-scene preset (another window, a Gauss–Newton step), and the default 'block' model was refused.
      const char* name = item.settings.matcher == PipelineMatcher::kSgbm ? "sgbm" : "block";
      options.noise_model->CheckApplicable(name, d.disparity_px.cols, options.noise_model_name);
      if (options.noise_model->form == NoiseForm::kLearned) {
        d.sigma_disparity_px =
            LearnedDisparitySigma(*options.noise_model, name, item.left_rect, item.right_rect, d.disparity_px,
                                  options.noise_model_name, &d.edge_sigma_disparity_px);
      }
    }
    item.result.depth =
        DepthFromDisparity(d, setup.intrinsics, rectifier.baseline_m(), rectifier.doffs_px() / f, options.depth);
    item.result.depth.frame_id = item.result.index;
    item.result.depth.timestamp_ns = item.result.timestamp_ns;
    item.left_rect.clear();
    item.right_rect.clear();
  }

  static void Triangulate(Item& item, const MatchSetup& setup) {
    TriangulateSummary ts;
    const int f = item.settings.ds;
    item.result.raw_mesh = TriangulateDepth(item.result.depth, setup.triangulate, &ts);
    // pyrDown pixel x sits at full-resolution 2x (see DownsampledIntrinsics).
    if (f > 1) item.result.raw_mesh.pixel *= static_cast<float>(f);
    RB_CHECK(item.result.raw_mesh.mesh.num_faces() > 0, "frame ", item.result.index, ": no surface (", ts.vertices,
             " valid depth pixels, no triangle)");
  }

  void Decimate(Item& item, const ProgressCallback& progress) const {
    const Mesh& input = item.result.smoothed.has_value() ? *item.result.smoothed : item.result.raw_mesh.mesh;
    DecimateOptions decimation = options.decimation;
    if (progress) decimation.progress = progress;
    item.result.decimated = rangebayes::Decimate(input, decimation);
  }

  void RectifyStage() {
    run.Stage((*queues[0]), (*queues[1]), t_rectify, [&](Item& item) { Rectify(item); });
    (*queues[1]).Close();
  }

  void StereoStage() {
    // One matcher per (matcher, downsample) pair, made when a frame first needs it.
    std::array<std::array<std::unique_ptr<StereoMatcher>, 4>, 2> matchers;
    auto match = [&](Item& item) {
      const MatchSetup& setup = setups[DsSlot(item.settings.ds)];
      Match(item,
            MatcherFor(item.settings.matcher, setup,
                       &matchers[MatcherSlot(item.settings.matcher)][DsSlot(item.settings.ds)]),
            setup, &range_end);
    };
    // Frames wait here until a window is full; a window's result takes the first frame's index. A frame
    // whose settings differ from the waiting ones (a control changed them) discards the waiting frames.
    std::deque<ItemPtr> buffer;
    const auto same_window = [](const ItemSettings& a, const ItemSettings& b) {
      return a.ds == b.ds && a.matcher == b.matcher && a.window == b.window && a.step == b.step;
    };
    while (auto popped = (*queues[1]).Pop()) {
      ItemPtr item = std::move(*popped);
      if (run.Stopping()) {
        run.AddAbandoned();
        continue;
      }
      if (!item->result.error.empty() || item->settings.window == 1) {
        run.Process(*item, t_stereo, match);
        (*queues[2]).Push(std::move(item));
        continue;
      }
      if (!buffer.empty() && !same_window(buffer.front()->settings, item->settings)) {
        for (size_t i = 0; i < buffer.size(); ++i) run.AddAbandoned();
        buffer.clear();
      }
      buffer.push_back(std::move(item));
      const int w = buffer.front()->settings.window;
      if (static_cast<int>(buffer.size()) < w) continue;
      auto merged = std::make_unique<Item>();
      merged->captured = buffer.back()->captured;
      merged->settings = buffer.front()->settings;
      merged->result.index = buffer.front()->result.index;
      merged->result.last_index = buffer.back()->result.index;
      merged->result.timestamp_ns = buffer.back()->result.timestamp_ns;
      merged->result.entered_steady_ns = buffer.back()->result.entered_steady_ns;
      merged->result.frames = w;
      merged->result.stereo_downsample = merged->settings.ds;
      merged->result.left_rectified = buffer.back()->result.left_rectified;
      for (const ItemPtr& b : buffer) {
        merged->left_rect.push_back(b->left_rect.front());
        merged->right_rect.push_back(b->right_rect.front());
      }
      for (int i = 0; i < merged->settings.step && !buffer.empty(); ++i) buffer.pop_front();
      run.Process(*merged, t_stereo, match);
      (*queues[2]).Push(std::move(merged));
    }
    if (!buffer.empty() && !run.Stopping()) {
      std::lock_guard<std::mutex> lock(run.mutex());
      summary.notices.push_back(StrCat("the last ", buffer.size(), " frame(s) did not fill a ",
                                       buffer.front()->settings.window,
                                       "-frame space-time window and were not matched"));
    }
    (*queues[2]).Close();
  }

  void TriangulateStage() {
    run.Stage((*queues[2]), (*queues[3]), t_triangulate,
              [&](Item& item) { Triangulate(item, setups[DsSlot(item.settings.ds)]); });
    (*queues[3]).Close();
  }

  void SmoothStage() {
    run.Stage((*queues[3]), (*queues[4]), t_smooth, [&](Item& item) {
      if (!options.smooth) return;
      SmoothOptions smoothing = options.smoothing;
      smoothing.progress = run.EndOnStop(smoothing.progress);
      // Per frame the pipeline runs the plain solve: the adaptive-ε pre-pass is not part of a frame's budget.
      smoothing.adaptive_epsilon = false;
      // Under a budget, the ray preconditioner's matrix per stage costs more than it saves (a 640x480 live replay:
      // 3.6 results/s with it, 7.1 without, same load; BENCHMARKS.md "Smoothing on real stereo").
      if (options.smooth_budget_ms > 0) smoothing.precondition_rays = false;
      // The budget is a deadline for the whole solve (stages and levels included): it buys the most converged
      // result it can, and the summary says how far from converged it stopped.
      // What the stage spends beyond the solve's limit (the warm start below, the solve's setup, the iteration
      // running at the deadline) is learned from the frames before (a running mean) and taken off the next limit,
      // so the stage keeps to the budget; the limit never drops below a quarter of the budget.
      const Clock::time_point stage_start = Clock::now();
      const double budget_ms = item.settings.smooth_budget_ms;
      double limit_ms = 0;
      if (budget_ms > 0.0) {
        limit_ms = std::max(0.25 * budget_ms, budget_ms - smooth_overrun_ms);
        smoothing.time_limit_s = 1e-3 * limit_ms;
      }
      // A static scene's previous result is nearly this frame's: start there where it agrees with the new
      // measurements (options.smooth_warm_start).
      Vertices start;
      const NoisyMesh& raw = item.result.raw_mesh;
      if (budget_ms > 0.0 && options.smooth_warm_start && earlier_positions.rows() > 0) {
        const int taken = StartFromEarlierResult(raw, earlier_pixel, earlier_positions, kWarmStartSigmas, &start);
        if (2 * taken >= raw.mesh.num_vertices()) {
          smoothing.initial_positions = &start;
          item.result.smooth_warm_vertices = taken;
        }
      }
      SmoothSummary ss;
      item.result.smoothed = Smooth(raw, smoothing, &ss);
      if (budget_ms > 0.0) {
        const double stage_ms = std::chrono::duration<double, std::milli>(Clock::now() - stage_start).count();
        smooth_overrun_ms = 0.7 * smooth_overrun_ms + 0.3 * std::max(0.0, stage_ms - limit_ms);
        if (options.smooth_warm_start) {
          earlier_pixel = raw.pixel;
          earlier_positions = item.result.smoothed->V;
        }
      }
      smooth_tally.warm_started += item.result.smooth_warm_vertices > 0 ? 1 : 0;
      item.result.smooth_iterations = ss.iterations;
      item.result.smooth_time_limited = ss.termination == SmoothTermination::kTimeLimit;
      item.result.smooth_distance =
          ss.energy.empty() ? 0.0 : ss.remaining_decrease / std::max(std::abs(ss.energy.back()), 1e-300);
      ++smooth_tally.smoothed;
      smooth_tally.iterations_sum += ss.iterations;
      smooth_tally.time_limited += item.result.smooth_time_limited ? 1 : 0;
      if (std::isfinite(item.result.smooth_distance)) {
        smooth_tally.distance_sum += item.result.smooth_distance;
        ++smooth_tally.distances;
      }
      if (ss.iterations > 0) {
        smooth_tally.ms_per_iteration_sum += 1000.0 * (ss.time_s - ss.setup_time_s) / ss.iterations;
        ++smooth_tally.timed;
      }
    });
    (*queues[4]).Close();
  }

  void DecimateStage() {
    run.Stage((*queues[4]), (*queues[5]), t_decimate, [&](Item& item) {
      if (options.decimate) Decimate(item, run.EndOnStop(options.decimation.progress));
    });
    SinkInputDone();
  }

  // The full-quality path (PipelineControl::RequestFullQuality), beside the live stages so that they go on while a
  // capture is made: one frame at a time, every step in a task arena of kFullQualityThreads on this thread, so the
  // live stages keep the other core. Its result joins the live
  // ones at the sinks. A stop request cancels the capture in progress at the next report of its smoothing or
  // decimation (a capture waiting is not begun); it is then abandoned, with the reason kept as the full-quality
  // error.
  void FullQualityStage() {
    tbb::task_arena arena(kFullQualityThreads);
    std::array<std::unique_ptr<StereoMatcher>, 2> matchers;
    while (auto popped = full_quality_queue.Pop()) {
      Item& item = **popped;
      arena.execute([&] {
        const auto step = [&](StageTiming* timing, const auto& work) {
          if (item.result.error.empty() && run.Stopping()) {
            item.result.error = StrCat(timing->name, ": ", kCaptureStopped);
            item.result.error_stage = timing->name;
          }
          run.Process(item, timing, work);
        };
        step(t_rectify, [&](Item& it) { Rectify(it); });
        step(t_stereo, [&](Item& it) {
          Match(it, MatcherFor(it.settings.matcher, full_quality_setup, &matchers[MatcherSlot(it.settings.matcher)]),
                full_quality_setup, &full_quality_range_end);
        });
        step(t_triangulate, [&](Item& it) { Triangulate(it, full_quality_setup); });
        step(t_smooth, [&](Item& it) {
          SmoothOptions smoothing = options.smoothing;
          smoothing.tolerance = SmoothOptions{}.tolerance;
          smoothing.num_threads = kFullQualityThreads;
          smoothing.progress = run.EndOnStop(options.smoothing.progress, kCaptureStopped);
          it.result.smoothed = Smooth(it.result.raw_mesh, smoothing);
        });
        step(t_decimate, [&](Item& it) { Decimate(it, run.EndOnStop(options.decimation.progress, kCaptureStopped)); });
      });
      (*queues[5]).Push(std::move(*popped));
    }
    SinkInputDone();
  }

  // queues[5] has two producers, the decimate stage and the full-quality worker: the last one to finish closes it.
  void SinkInputDone() {
    if (sink_producers_left.fetch_sub(1) == 1) (*queues[5]).Close();
  }

  void SinkStage() {
    // The sink finishes the result it is writing even after a stop, so every file it wrote is complete.
    // So is a capture (full-quality result) that was finished: the operator asked for it.
    while (auto popped = (*queues[5]).Pop()) {
      Item& item = **popped;
      if (run.Stopping() && !(item.settings.full_quality && item.result.error.empty())) {
        if (item.settings.full_quality) {
          run.AddFullQuality(item.result);
          std::lock_guard<std::mutex> lock(run.mutex());
          summary.notices.push_back(
              StrCat("the capture of frame ", item.result.index, " was abandoned: ", item.result.error));
        }
        run.AddAbandoned();
        continue;
      }
      if (item.result.error.empty()) {
        run.Process(item, t_sinks, [&](Item& it) {
          for (PipelineSink* sink : sinks) sink->Consume(it.result);
        });
      }
      const bool ok = item.result.error.empty();
      if (item.settings.full_quality) run.AddFullQuality(item.result);
      {
        std::lock_guard<std::mutex> lock(run.mutex());
        ++(ok ? summary.results : summary.failed);
      }
      if (!ok) {
        run.AddError(item.result.frames > 1 ? StrCat("frames ", item.result.index, "-", item.result.last_index, ": ",
                                                     item.result.error)
                                            : StrCat("frame ", item.result.index, ": ", item.result.error));
      }
      latency_sum_ms += MsSince(item.captured);
      frames_done += item.result.frames > 1 ? item.settings.step : 1;
      if (options.progress) {
        const double elapsed_s = std::chrono::duration<double>(Clock::now() - run_start).count();
        const double fps = elapsed_s > 0 ? static_cast<double>(frames_done) / elapsed_s : 0.0;
        // Live drops frames: progress through the source is what was captured, not what came out.
        std::int64_t consumed = frames_done;
        if (options.queue_policy == QueueFullPolicy::kDropOldest) {
          std::lock_guard<std::mutex> lock(run.mutex());
          consumed = summary.frames_captured + summary.frames_skipped;
        }
        const double fraction =
            frames_total.has_value() && *frames_total > 0
                ? std::min(1.0, static_cast<double>(consumed) / static_cast<double>(*frames_total))
                : 0.0;
        // With a known total, how many of it went through ("frame 5/4" once counted a window's frame indices from
        // --first against its --count); without one, the source's frame index.
        const std::string done =
            frames_total.has_value() ? StrCat(consumed, "/", *frames_total) : StrCat(item.result.last_index + 1);
        char rate[32];
        std::snprintf(rate, sizeof(rate), "%.2f", fps);
        options.progress(fraction, StrCat("frame ", done, ", ", rate, " frames/s"));
      }
    }
    for (PipelineSink* sink : sinks) {
      try {
        sink->Finish();
      } catch (const std::exception& e) {
        run.AddError(StrCat("sink finish: ", e.what()));
      }
    }
  }

  // The summary's totals, rates and notices, after every stage has finished.
  void FinishSummary() {
    const MatchSetup& default_setup = setups[DsSlot(ds)];
    summary.wall_s = std::chrono::duration<double>(Clock::now() - run_start).count();
    summary.stopped = options.stop != nullptr && options.stop->load();
    summary.source_stats = source.stats();
    if (summary.source_stats.gaps_shortened > 0) {
      summary.notices.push_back(StrCat(summary.source_stats.gaps_shortened,
                                       " gap(s) between recorded timestamps were longer than the longest wait of "
                                       "playback at recorded speed and were played shorter"));
    }
    for (const auto& q : queues) {
      summary.dropped_per_queue.push_back(q->dropped());
      summary.dropped += q->dropped();
    }
    const std::int64_t finished = summary.results + summary.failed;
    summary.latency_mean_ms = finished > 0 ? latency_sum_ms / static_cast<double>(finished) : 0.0;
    summary.frames_per_s = summary.wall_s > 0 ? static_cast<double>(frames_done) / summary.wall_s : 0.0;
    if (smooth_tally.smoothed > 0) {
      summary.smooth_iterations_mean = smooth_tally.iterations_sum / smooth_tally.smoothed;
      summary.smooth_time_limited = smooth_tally.time_limited;
      summary.smooth_warm_started = smooth_tally.warm_started;
    }
    if (smooth_tally.timed > 0) {
      summary.smooth_ms_per_iteration_mean = smooth_tally.ms_per_iteration_sum / smooth_tally.timed;
    }
    summary.smooth_distance_mean =
        smooth_tally.distances > 0 ? smooth_tally.distance_sum / smooth_tally.distances : std::nan("");
    if (options.smooth && options.smooth_budget_ms > 0.0 && smooth_tally.smoothed > 0) {
      char line[300];
      std::snprintf(line, sizeof(line),
                    "smoothing budget %.0f ms per frame: %d of %d results stopped by it, %.1f iterations of the final "
                    "solve per result, %d started from the previous result, ",
                    options.smooth_budget_ms, smooth_tally.time_limited, smooth_tally.smoothed,
                    summary.smooth_iterations_mean, smooth_tally.warm_started);
      std::string notice = line;
      if (std::isfinite(summary.smooth_distance_mean)) {
        // The rate estimate under-reads solves that a budget cut short (2.5–20× on live frames, docs/design.md).
        std::snprintf(line, sizeof(line),
                      "distance to the optimum %.2g × E on average (estimated from the rate of decrease; an "
                      "underestimate where the budget stopped the solve)",
                      summary.smooth_distance_mean);
        notice += line;
      } else {
        notice += "distance to the optimum unknown (too few iterations to estimate)";
      }
      summary.notices.push_back(notice);
    }
    const int range_end_results = range_end.results + full_quality_range_end.results;
    if (range_end_results > 0) {
      char share[32];
      std::snprintf(share, sizeof(share), "%.1f%%", 100.0 * std::max(range_end.max, full_quality_range_end.max));
      summary.notices.push_back(StrCat("in ", range_end_results, " of ", summary.results + summary.failed,
                                       " results many pixels matched best at an end of the disparities searched (up ",
                                       "to ", share, "): ", RangeEndAdvice()));
    }
    if (ds > 1) {
      summary.notices.push_back(StrCat("stereo matched at 1/", ds, " resolution (", default_setup.intrinsics.width, "x",
                                       default_setup.intrinsics.height, ", ",
                                       options.matcher == PipelineMatcher::kSgbm ? default_setup.sgbm.num_disparities
                                                                                 : default_setup.spacetime.num_disparities,
                                       " disparities), triangulated every ", default_setup.triangulate.downsample,
                                       " pixel(s) of it"));
    }
  }

  FrameSource& source;
  const StereoRig& rig;
  const PipelineOptions& options;
  const std::vector<PipelineSink*>& sinks;
  const Rectifier rectifier;
  const int ds;
  std::array<MatchSetup, 4> setups;
  MatchSetup full_quality_setup;
  const int window;
  const int step;
  PipelineControl* control;
  const std::optional<std::int64_t> frames_total;
  Run run;
  PipelineSummary& summary;
  StageTiming* t_capture = nullptr;
  StageTiming* t_rectify = nullptr;
  StageTiming* t_stereo = nullptr;
  StageTiming* t_triangulate = nullptr;
  StageTiming* t_smooth = nullptr;
  StageTiming* t_decimate = nullptr;
  StageTiming* t_sinks = nullptr;
  Clock::time_point run_start;
  std::optional<FrameResult> first;
  double first_read_ms = 0.0;  // the read of `first`, counted with its frame
  std::vector<std::unique_ptr<ItemQueue>> queues;
  SmoothTally smooth_tally;  // written by the smooth stage only, read after the join
  RangeEndTally range_end;   // stereo stage only
  RangeEndTally full_quality_range_end;  // full-quality worker only
  // Frames a control asked for at full quality, from the capture stage to the full-quality worker.
  ItemQueue full_quality_queue{kMaxWaitingCaptures, QueueFullPolicy::kBlock};
  std::atomic<int> sink_producers_left{2};  // SinkInputDone
  double smooth_overrun_ms = 0.0;  // smooth stage only: mean time a budgeted solve ran past its limit
  // Smooth stage only: the last budgeted result (pixels and smoothed positions), where the next frame starts.
  Eigen::Matrix<float, Eigen::Dynamic, 2, Eigen::RowMajor> earlier_pixel;
  Vertices earlier_positions;
  double latency_sum_ms = 0.0;   // sink stage only
  std::int64_t frames_done = 0;  // sink stage only
};

}  // namespace

PipelineSummary RunPipeline(FrameSource& source, const StereoRig& rig, const PipelineOptions& options,
                            const std::vector<PipelineSink*>& sinks) {
  options.Check();
  Stages stages(source, rig, options, sinks);
  if (options.control != nullptr) options.control->Begin(options, [&stages]() { return stages.Snapshot(); });
  std::array<std::thread, 8> threads = {
      std::thread([&stages] { stages.CaptureStage(); }),     std::thread([&stages] { stages.RectifyStage(); }),
      std::thread([&stages] { stages.StereoStage(); }),      std::thread([&stages] { stages.TriangulateStage(); }),
      std::thread([&stages] { stages.SmoothStage(); }),      std::thread([&stages] { stages.DecimateStage(); }),
      std::thread([&stages] { stages.FullQualityStage(); }), std::thread([&stages] { stages.SinkStage(); })};
  for (std::thread& t : threads) t.join();
  if (options.control != nullptr) {
    PipelineSnapshot last = options.control->Snapshot();
    last.running = false;
    options.control->End(std::move(last));
  }
  stages.FinishSummary();
  return stages.summary;
}

std::string PipelineSummary::BriefReport() const {
  std::string out;
  char line[512];
  out += source + "\n";
  std::snprintf(line, sizeof(line),
                "%lld frames in, %lld results, %lld failed, %lld skipped, %lld dropped, %.1f s, %.2f frames/s end "
                "to end, latency %.0f ms\n",
                static_cast<long long>(frames_captured), static_cast<long long>(results),
                static_cast<long long>(failed), static_cast<long long>(frames_skipped),
                static_cast<long long>(dropped), wall_s, frames_per_s, latency_mean_ms);
  out += line;
  std::snprintf(line, sizeof(line), "  %-12s %7s %7s %10s %10s %9s\n", "stage", "items", "errors", "mean ms",
                "max ms", "items/s");
  out += line;
  for (const StageTiming& t : stages) {
    // A rate over less than a millisecond in all measures nothing (a stage that is off passes its items on at
    // once: "3846153.85 items/s").
    char rate[32] = "-";
    if (t.total_ms >= 1.0)
      std::snprintf(rate, sizeof(rate), "%.2f", 1000.0 * static_cast<double>(t.items) / t.total_ms);
    std::snprintf(line, sizeof(line), "  %-12s %7lld %7lld %10.1f %10.1f %9s\n", t.name.c_str(),
                  static_cast<long long>(t.items), static_cast<long long>(t.errors), t.mean_ms(), t.max_ms, rate);
    out += line;
  }
  for (const std::string& n : notices) out += "note: " + n + "\n";
  for (const std::string& e : errors) out += e + "\n";
  if (stopped) out += "stopped by request; finished results are complete\n";
  return out;
}

void WritePipelineSummaryJson(const PipelineSummary& summary, const std::string& path) {
  nlohmann::json j;
  j["source"] = summary.source;
  j["frames_captured"] = summary.frames_captured;
  j["frames_skipped"] = summary.frames_skipped;
  j["timeouts"] = summary.timeouts;
  j["results"] = summary.results;
  j["failed"] = summary.failed;
  j["dropped"] = summary.dropped;
  j["dropped_per_queue"] = summary.dropped_per_queue;
  j["queue_capacity"] = summary.queue_capacity;
  j["abandoned"] = summary.abandoned;
  j["stopped"] = summary.stopped;
  j["fatal_error"] = summary.fatal_error;
  j["errors"] = summary.errors;
  j["notices"] = summary.notices;
  j["wall_s"] = summary.wall_s;
  j["frames_per_s"] = summary.frames_per_s;
  j["latency_mean_ms"] = summary.latency_mean_ms;
  j["smooth_iterations_mean"] = summary.smooth_iterations_mean;
  j["smooth_ms_per_iteration_mean"] = summary.smooth_ms_per_iteration_mean;
  j["smooth_time_limited"] = summary.smooth_time_limited;
  j["smooth_warm_started"] = summary.smooth_warm_started;
  if (std::isfinite(summary.smooth_distance_mean)) j["smooth_distance_mean"] = summary.smooth_distance_mean;
  j["source_stats"] = {{"frames_delivered", summary.source_stats.frames_delivered},
                       {"frames_skipped", summary.source_stats.frames_skipped},
                       {"timeouts", summary.source_stats.timeouts},
                       {"dropped_left", summary.source_stats.dropped_left},
                       {"dropped_right", summary.source_stats.dropped_right},
                       {"unpaired_left", summary.source_stats.unpaired_left},
                       {"unpaired_right", summary.source_stats.unpaired_right},
                       {"gaps_shortened", summary.source_stats.gaps_shortened}};
  nlohmann::json stages = nlohmann::json::array();
  for (const StageTiming& s : summary.stages) {
    stages.push_back({{"name", s.name},
                      {"items", s.items},
                      {"errors", s.errors},
                      {"total_ms", s.total_ms},
                      {"mean_ms", s.mean_ms()},
                      {"max_ms", s.max_ms},
                      {"items_per_s", s.total_ms > 0 ? 1000.0 * static_cast<double>(s.items) / s.total_ms : 0.0}});
  }
  j["stages"] = stages;
  // An error message or source name may hold bytes that are not UTF-8 (a file name from frames.csv). Written
  // whole or not at all (a full disk left a summary.json of 0 bytes), with the reason when not.
  WriteFileAtomically(path, JsonText(j, 2) + "\n");
}

}  // namespace rangebayes
