// Our space-time stereo matcher (Davis, Nehab, Ramamoorthi, Rusinkiewicz 2005; Zhang, Curless, Seitz 2003):
// the matching cost of a left pixel at disparity d is summed over a w×w×T spatio-temporal window, the
// disparity is the winner-take-all minimum refined by a parabola through the three costs around it, a
// left-right check removes occlusions and mismatches, and σ_d comes from the cost curvature (DESIGN.md §2).
// With T = 1 it is a single-frame block matcher that also yields σ_d.
#pragma once

#include "stereo/matcher.h"

namespace rangebayes {

enum class SpaceTimeCost {
  kAuto,       // kZnccTime when T ≥ 3 frames, kSsd otherwise
  kSsd,        // sum of squared grey-level differences
  kZnccSpace,  // SSD of images normalised by the mean and deviation of each pixel's w×w neighbourhood
  kZnccTime,   // SSD of per-pixel temporally normalised signals = Σ over the window of 2T(1 − temporal ZNCC)
};

struct SpaceTimeMatcherOptions {
  int min_disparity_px = 0;          // any integer: smallest disparity searched
  int num_disparities = 64;          // 3–1024: disparities min … min + num − 1 are searched
  int window_px = 5;                 // odd, 1–31: spatial window side w
  SpaceTimeCost cost = SpaceTimeCost::kAuto;
  double uniqueness_ratio = 0.05;    // ≥ 0: best cost × (1 + ratio) must stay below all costs ≥ 2 px away (0: off)
  double left_right_max_diff_px = 1.0;  // < 0: off; else max |d_left − d_right| (integer disparities)
  double image_noise_gray = 2.0;     // > 0: σ_n of one image sample, grey levels of the input (8-bit: 0–255)
  // σ_d = sqrt(floor² + (scale · σ_pred)²), σ_pred² = 2σ_n²/Σg² at the refined minimum (= 4σ_n²/C″, DESIGN.md
  // §2). Fitted on synthetic scenes from stereo/synth (planes, sphere, box, cylinder, stairs; 320×240, noise
  // 2 grey levels; normalised squared residuals averaging 1 per σ_pred decile, residuals beyond 5σ left out
  // as outliers, 1–2% of pixels): T = 8 gives floor ≈ 0, scale 2.1; T = 1: scale 1.4; T = 16: scale 2.5 (the
  // error left after many frames is mostly model error, which does not shrink with T as σ_pred does).
  // Real cameras need their own fit (calibration's disparity noise model).
  double sigma_floor_px = 0.01;      // ≥ 0
  double sigma_scale = 2.1;          // > 0
  double max_sigma_disparity_px = 0.0;  // ≥ 0: pixels with a larger σ_d become NaN (0: keep all)
  int subpixel_iterations = 2;       // 0–5: Gauss–Newton steps after the parabola (0: parabola only)
  int rows_per_task = 16;            // 1–1024: rows per parallel task (a band's cost volume stays in cache)
  void Check() const;
};

struct SpaceTimeMatchSummary {
  SpaceTimeCost cost_used = SpaceTimeCost::kSsd;
  int frames = 0;
  int valid_pixels = 0;
  int rejected_left_right = 0;
  int rejected_flat = 0;      // no curvature (textureless) or minimum at the end of the search range
  int rejected_sigma = 0;
  int rejected_ambiguous = 0;  // failed the uniqueness test
};

class SpaceTimeMatcher : public StereoMatcher {
 public:
  explicit SpaceTimeMatcher(const SpaceTimeMatcherOptions& options = {});
  DisparityResult Match(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right) override;
  std::string name() const override { return "spacetime"; }
  const SpaceTimeMatchSummary& last_summary() const { return summary_; }
  const SpaceTimeMatcherOptions& options() const { return options_; }

 private:
  SpaceTimeMatcherOptions options_;
  SpaceTimeMatchSummary summary_;
};

}  // namespace rangebayes
