// The stereo-to-mesh pipeline (docs/design.md §1): capture → rectify → stereo (one frame, or space-time over a
// window of frames) → triangulate → smooth → decimate → sinks, each stage in its own thread, connected by
// bounded queues. Replay (QueueFullPolicy::kBlock) never drops a frame; live (kDropOldest) drops the oldest
// captured frame when the pipeline is busy and counts it: only the queue after capture drops, every later
// stage waits for the next one, so no work is spent on a frame that would be thrown away and the pipeline
// runs at its slowest stage's pace. A source that is not realtime() is never dropped from (it is read when
// there is room). Every result carries its frame index and timestamp.
//
// A frame a PipelineControl asks for at full quality (a capture) leaves the live stages where it enters and goes
// through every step on a worker thread of its own, using that thread only, so that the live stages go on meanwhile
// with what CPU is left; its result joins the live results at the sinks when it is finished.
//
// Errors: a frame that fails in a stage (a corrupt image, a matcher or solver error) is counted, its reason
// kept, and the run goes on; no exception leaves a stage thread. A lost device ends the run early with
// PipelineSummary::fatal_error set, everything finished before it complete. The stop flag (Ctrl-C) ends the
// capture; work already in flight is abandoned except the result the sink is writing, which is completed, and a
// finished full-quality result, which is delivered. A full-quality frame still being processed is cancelled (at
// the next progress report of its smoothing or decimation) and counted as a full-quality failure with the reason.
// The end of the source (or a fatal error) waits for every full-quality frame already taken.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bayes/decimation/decimate.h"
#include "bayes/smooth.h"
#include "calibration/stereo_rig.h"
#include "capture/frame_source.h"
#include "core/mesh.h"
#include "core/progress.h"
#include "pipeline/bounded_queue.h"
#include "reconstruction/triangulate.h"
#include "stereo/depth_frame.h"
#include "stereo/rectify.h"
#include "stereo/sgbm_matcher.h"
#include "stereo/spacetime_matcher.h"

namespace rangebayes {

enum class PipelineMatcher { kSgbm, kSpaceTime };

class PipelineControl;  // pipeline/pipeline_control.h

// What one pass through the stages produced for a frame (or a space-time window of frames). Stages that
// are switched off leave their part empty; `error` is set when a stage failed (later parts are empty).
struct PipelineResult {
  std::int64_t index = 0;          // frame index of the first frame of the window
  std::int64_t last_index = 0;     // frame index of the last frame of the window (== index for one frame)
  std::int64_t timestamp_ns = 0;   // the last frame's capture time
  std::int64_t entered_steady_ns = 0;  // when the last frame entered the pipeline (steady_clock), for latency
  int frames = 0;                  // frames in the window
  cv::Mat left_rectified;          // last frame of the window, for previews
  DepthFrame depth;
  NoisyMesh raw_mesh;
  std::optional<Mesh> smoothed;
  std::optional<DecimatedMesh> decimated;
  std::string error;               // "<stage>: <reason>" when the frame failed
  std::string error_stage;
  bool full_quality = false;       // went through the full-quality path (PipelineControl::RequestFullQuality)
  int stereo_downsample = 1;       // the factor this result was matched at
  // Smoothing (when it ran on the normal path): iterations of the final solve, whether the budget stopped it,
  // and its estimated distance to the optimum E − E* relative to E (SmoothSummary::remaining_decrease; infinity
  // when unknown).
  int smooth_iterations = 0;
  bool smooth_time_limited = false;
  double smooth_distance = 0.0;
  int smooth_warm_vertices = 0;  // vertices that started from the previous result (0: solved from the measurements)
};

// Receives finished results from the sink thread, one call at a time: the live results in frame order, a
// full-quality result when it is finished (after the results of the frames that came out while it was made).
class PipelineSink {
 public:
  virtual ~PipelineSink() = default;
  // May throw; the error is counted against the frame and the run goes on.
  virtual void Consume(const PipelineResult& result) = 0;
  // Called once after the last result (also after a stop or a fatal error).
  virtual void Finish() {}
};

struct PipelineOptions {
  QueueFullPolicy queue_policy = QueueFullPolicy::kBlock;  // kBlock: replay; kDropOldest: live (see above)
  int queue_capacity = 4;            // 1–64 items between two stages
  PipelineMatcher matcher = PipelineMatcher::kSgbm;
  int window_frames = 1;             // 1–256: frames per space-time window (1: single-frame stereo)
  int window_step_frames = 0;        // 0: = window_frames (windows do not overlap); else 1–window_frames
  RectifierOptions rectify;
  // 1, 2, 4 or 8: match on the rectified pair shrunk this many times by cv::pyrDown (1: full resolution).
  // The rectified camera (f, c, doffs) is scaled with it, so depths stay in metres; the matcher's
  // disparity range (sgbm/spacetime num_disparities, min_disparity_px) and triangulate.downsample are given
  // in full-resolution pixels and divided by it here. Triangle vertices keep full-resolution pixels.
  int stereo_downsample = 1;
  SgbmMatcherOptions sgbm;
  SpaceTimeMatcherOptions spacetime;
  DepthFromDisparityOptions depth;
  // Optional calibrated disparity noise (ApplyDisparityNoiseModel below): every frame checks that it applies to
  // its matcher and matched width (an error counted against the frame otherwise); a learned model gives σ_d.
  std::optional<DisparityNoiseModel> noise_model;
  std::string noise_model_name = "noise model";  // names the model (its file) in errors
  TriangulateOptions triangulate;
  bool smooth = true;                // run Bayesian smoothing (bayes/smooth.h)
  SmoothOptions smoothing;           // its progress callback is also called from the full-quality worker, concurrently
  // ≥ 0 ms; 0: no budget. Else a deadline for each frame's smoothing (SmoothOptions::time_limit_s): it stops
  // there with the most converged result it reached and says how far from converged (PipelineResult). Results
  // then depend on timing.
  double smooth_budget_ms = 0.0;
  // Under a budget, each frame's solve starts where the previous result lies at the same pixel, wherever that is
  // within 3σ of the new measurement (StartFromEarlierResult), if that holds for at least half the vertices; else
  // from the measurements, with the ε continuation. A static scene's results then keep converging from frame to
  // frame (BENCHMARKS.md "Smoothing on real stereo", target 3). Without a budget every frame is solved cold.
  bool smooth_warm_start = true;
  bool decimate = true;              // run Bayesian decimation (bayes/decimation/decimate.h) on the smoothed mesh
  DecimateOptions decimation;
  int max_consecutive_timeouts = 50; // ≥ 1: a live source that stalls this long ends the run
  const std::atomic<bool>* stop = nullptr;  // polled by the stages (e.g. &StopFlag()); null: never
  // Optional: settings changed while the run goes on (pause, budget, downsample, matcher), full-quality
  // requests, live counters (pipeline/pipeline_control.h). Must outlive the run.
  PipelineControl* control = nullptr;
  // Optional: called from the capture thread with every frame that enters, before any drop (to record the
  // raw frames). Must be quick (hand the frame to another thread); an exception counts the frame as skipped.
  std::function<void(const StereoFrame&)> on_frame;
  // The full-quality path a control can ask for: stereo at full resolution, triangulation every this many
  // pixels (1–64), smoothing to the library's default tolerance without a time budget on one thread, decimation on
  // (decimation.progress is then called from that thread).
  int full_quality_triangulate_downsample = 1;
  ProgressCallback progress;         // from the sink thread; fraction of frames_total() when known
  void Check() const;
};

// The live-path preset (what `rangebayes live` and `replay --live-path` run; BENCHMARKS.md "Capture and
// pipeline" has the measurements): a preview needs a usable surface per frame, not a converged one. Sets on
// `options`: queue_policy kDropOldest with one item per queue, stereo_downsample kLiveStereoDownsample,
// triangulate.downsample 4, the fast smoothing tolerance within smooth_budget_ms = kLiveSmoothBudgetMs, and
// decimation off (far over the 2-core frame budget). Everything else is left as it is.
inline constexpr int kLiveStereoDownsample = 2;
inline constexpr int kLiveTriangulateDownsample = 4;
inline constexpr double kLiveSmoothBudgetMs = 80.0;

// Throws Error unless a per-frame smoothing budget (ms) lies in [0, 1000 · kMaxSmoothTimeLimitS] (0: none): the
// one check of PipelineOptions and PipelineSettings.
void CheckSmoothBudgetMs(double budget_ms);
void ApplyLivePathPreset(PipelineOptions* options);

// Uses a calibrated noise model (`rangebayes calibrate noise`) in the stereo stage: sets noise_model and, for the
// constant and floor-plus-scale forms, the triangulation's default σ_d and the space-time matcher's σ_d model
// (ApplyDisparityNoiseModel of reconstruction/ and stereo/). `name` names the model in errors.
void ApplyDisparityNoiseModel(const DisparityNoiseModel& model, const std::string& name, PipelineOptions* options);

struct StageTiming {
  std::string name;
  std::int64_t items = 0;            // items that went through the stage (successfully or not)
  std::int64_t errors = 0;
  double total_ms = 0.0;
  double max_ms = 0.0;
  double mean_ms() const { return items > 0 ? total_ms / static_cast<double>(items) : 0.0; }
};

struct PipelineSummary {
  std::string source;                // FrameSource::Describe()
  std::int64_t frames_captured = 0;  // frames that entered the pipeline
  std::int64_t frames_skipped = 0;   // frames the source could not deliver (reason in errors)
  std::int64_t timeouts = 0;
  std::int64_t results = 0;          // results delivered to the sinks without error
  std::int64_t failed = 0;           // results that failed in a stage
  std::int64_t dropped = 0;          // live: items dropped from full queues (all queues)
  std::vector<std::int64_t> dropped_per_queue;
  int queue_capacity = 0;            // of each queue between two stages (PipelineOptions::queue_capacity)
  std::int64_t abandoned = 0;        // items discarded after a stop request
  bool stopped = false;              // the stop flag ended the run
  std::string fatal_error;           // the source failed for good (device lost)
  std::vector<std::string> errors;   // one line per failed or skipped frame (first 100)
  std::vector<StageTiming> stages;
  std::vector<std::string> notices;  // stages switched off, settings chosen
  FrameSourceStats source_stats;
  double wall_s = 0.0;
  double frames_per_s = 0.0;         // frames captured and fully processed per wall second
  double latency_mean_ms = 0.0;      // capture-to-sink time per result
  double smooth_iterations_mean = 0.0;  // smoothing iterations per smoothed result
  double smooth_ms_per_iteration_mean = 0.0;  // smoothing time (setup excluded) per iteration of the final solve
                                              // (continuation stages included in the time), mean over results
  int smooth_time_limited = 0;       // results the budget stopped
  int smooth_warm_started = 0;       // results whose solve started from the previous result
  double smooth_distance_mean = 0.0; // mean estimated distance to the optimum, relative to E (NaN: unknown)

  // The source, the counts, a table of the stages, then notices, errors and a stop request, one per line.
  std::string BriefReport() const;
};

// The rectified left camera of an image shrunk `factor` times (1, 2, 4, 8) by repeated cv::pyrDown: dst(x)
// averages src around 2x, so f and c halve exactly per halving; the size is ((w + 1) / 2, (h + 1) / 2).
CameraIntrinsics DownsampledIntrinsics(const CameraIntrinsics& full, int factor);

// Runs the pipeline until the source ends, the stop flag is set, or the source fails. Throws Error only
// before starting (invalid options, a rig whose size does not match the first frame); everything after
// that is reported in the summary.
PipelineSummary RunPipeline(FrameSource& source, const StereoRig& rig, const PipelineOptions& options,
                            const std::vector<PipelineSink*>& sinks);

// Writes the summary as JSON (stages, counts, errors); bytes of its strings that are not UTF-8 are written as
// U+FFFD. Throws Error naming the path on failure.
void WritePipelineSummaryJson(const PipelineSummary& summary, const std::string& path);

}  // namespace rangebayes
