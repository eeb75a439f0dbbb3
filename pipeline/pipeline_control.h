// Steering a running pipeline from another thread (a web console, a test): settings the stages read between
// frames, a request to send one frame through the full-quality path, and a live view of the run's counters.
// Every member function is thread-safe. A control is handed to RunPipeline through PipelineOptions::control;
// RunPipeline seeds the settings from its options when it starts (paused stays as it was).
#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include "pipeline/pipeline.h"

namespace rangebayes {

// What the stages apply to the next frame that enters the pipeline.
struct PipelineSettings {
  bool paused = false;               // capture reads no frame while paused
  double smooth_budget_ms = 0.0;     // ≥ 0 (0: no budget), as PipelineOptions::smooth_budget_ms
  int stereo_downsample = 1;         // 1, 2, 4 or 8, as PipelineOptions::stereo_downsample
  PipelineMatcher matcher = PipelineMatcher::kSgbm;
  int window_frames = 1;             // 1–256 (> 1 needs kSpaceTime)
  void Check() const;                // throws Error naming the field out of range
};

// The counters of a run so far (a copy: PipelineSummary's fields while the run goes on).
struct PipelineSnapshot {
  bool running = false;              // false before RunPipeline started and after it returned
  std::int64_t frames_captured = 0;
  std::int64_t frames_skipped = 0;
  std::int64_t timeouts = 0;
  std::int64_t results = 0;
  std::int64_t failed = 0;
  std::int64_t dropped = 0;          // all queues
  std::int64_t full_quality_done = 0;  // results that went through the full-quality path
  std::int64_t full_quality_failed = 0;  // full-quality frames that failed in a stage
  std::string full_quality_error;        // the last one's "frame N: <stage>: <reason>"
  double wall_s = 0.0;
  std::vector<StageTiming> stages;
  std::vector<int> queue_fill;       // items waiting in each queue between two stages
  int queue_capacity = 0;
  std::vector<std::string> errors;   // the most recent failed or skipped frames (at most 20, oldest first)
};

class PipelineControl {
 public:
  PipelineSettings settings() const;
  // Each throws Error (and changes nothing) when the value is out of range.
  void SetPaused(bool paused);
  void SetSmoothBudgetMs(double budget_ms);
  void SetStereoDownsample(int factor);
  void SetMatcher(PipelineMatcher matcher, int window_frames);
  // The next frame that enters goes alone through the full-quality path (pipeline.h), beside the live stages;
  // its result has PipelineResult::full_quality set. Requests made before it is taken count once. A request made
  // while a capture is in progress is taken the same way, its frame waiting for the capture before it (while four
  // wait, a request waits to be taken). That frame is never dropped; it ends as a result (full_quality_done) or a
  // failure (full_quality_failed, also when a stop request cancelled it).
  void RequestFullQuality();

  PipelineSnapshot Snapshot() const;

  // Used by RunPipeline.
  void Begin(const PipelineOptions& options, std::function<PipelineSnapshot()> snapshot);
  void End(PipelineSnapshot final_snapshot);
  bool TakeFullQualityRequest();

 private:
  mutable std::mutex mutex_;
  PipelineSettings settings_;
  bool full_quality_requested_ = false;
  std::function<PipelineSnapshot()> snapshot_;
  PipelineSnapshot last_;
};

}  // namespace rangebayes
