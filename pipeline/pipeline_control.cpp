#include "pipeline/pipeline_control.h"

#include <utility>

#include "core/error.h"

namespace rangebayes {

void PipelineSettings::Check() const {
  CheckSmoothBudgetMs(smooth_budget_ms);
  RB_CHECK(stereo_downsample == 1 || stereo_downsample == 2 || stereo_downsample == 4 || stereo_downsample == 8,
           "stereo downsample must be 1, 2, 4 or 8, got ", stereo_downsample);
  RB_CHECK(window_frames >= 1 && window_frames <= 256, "space-time window must be 1..256 frames, got ",
           window_frames);
  RB_CHECK(window_frames == 1 || matcher == PipelineMatcher::kSpaceTime,
           "a window of more than one frame needs the space-time matcher");
}

PipelineSettings PipelineControl::settings() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return settings_;
}

void PipelineControl::SetPaused(bool paused) {
  std::lock_guard<std::mutex> lock(mutex_);
  settings_.paused = paused;
}

void PipelineControl::SetSmoothBudgetMs(double budget_ms) {
  std::lock_guard<std::mutex> lock(mutex_);
  PipelineSettings s = settings_;
  s.smooth_budget_ms = budget_ms;
  s.Check();
  settings_ = s;
}

void PipelineControl::SetStereoDownsample(int factor) {
  std::lock_guard<std::mutex> lock(mutex_);
  PipelineSettings s = settings_;
  s.stereo_downsample = factor;
  s.Check();
  settings_ = s;
}

void PipelineControl::SetMatcher(PipelineMatcher matcher, int window_frames) {
  std::lock_guard<std::mutex> lock(mutex_);
  PipelineSettings s = settings_;
  s.matcher = matcher;
  s.window_frames = window_frames;
  s.Check();
  settings_ = s;
}

void PipelineControl::RequestFullQuality() {
  std::lock_guard<std::mutex> lock(mutex_);
  full_quality_requested_ = true;
}

bool PipelineControl::TakeFullQualityRequest() {
  std::lock_guard<std::mutex> lock(mutex_);
  return std::exchange(full_quality_requested_, false);
}

PipelineSnapshot PipelineControl::Snapshot() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return snapshot_ ? snapshot_() : last_;
}

void PipelineControl::Begin(const PipelineOptions& options, std::function<PipelineSnapshot()> snapshot) {
  std::lock_guard<std::mutex> lock(mutex_);
  settings_.smooth_budget_ms = options.smooth_budget_ms;
  settings_.stereo_downsample = options.stereo_downsample;
  settings_.matcher = options.matcher;
  settings_.window_frames = options.window_frames;
  snapshot_ = std::move(snapshot);
}

void PipelineControl::End(PipelineSnapshot final_snapshot) {
  std::lock_guard<std::mutex> lock(mutex_);
  snapshot_ = nullptr;
  last_ = std::move(final_snapshot);
}

}  // namespace rangebayes
