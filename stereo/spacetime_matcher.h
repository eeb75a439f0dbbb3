// Our space-time stereo matcher (Davis, Nehab, Ramamoorthi, Rusinkiewicz 2005; Zhang, Curless, Seitz 2003):
// the matching cost of a left pixel at disparity d is summed over a w×w×T spatio-temporal window, the
// disparity is the winner-take-all minimum refined by a parabola through the three costs around it, a
// left-right check removes occlusions and mismatches, and σ_d comes from the cost curvature (docs/design.md §2).
// With T = 1 it is a single-frame block matcher that also yields σ_d.
#pragma once

#include "calibration/disparity_noise_model.h"
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
  // σ_d = sqrt(floor² + (scale · σ_pred)² + J), σ_pred² = 4σ_eff²/C″ + … from the cost curvature at the integer
  // minimum (docs/design.md §2; the other terms below). Fitted by maximum likelihood (J off) on synthetic scenes
  // from stereo/synth (planes, sphere, box, cylinder, stairs; 320×240, noise 2 grey levels, seeds 5–6;
  // residuals beyond 5σ left out as outliers, 0.5–0.8% of pixels; `bench_stereo --quality=sigmafit`) with
  // parabola sub-pixel refinement: T = 8 gives floor 0.03 px (the parabola's pixel-locking bias, which no
  // averaging removes), scale 1.7; T = 1: 0.05 / 1.1; T = 16: 0.02 / 1.9. Mean squared normalised residual
  // per σ_pred quintile 0.5–1.3 (the residual-noise term over-predicts a little on clean synthetic data).
  // Real cameras need their own fit (calibration's disparity noise model).
  double sigma_floor_px = 0.03;      // ≥ 0
  double sigma_scale = 1.7;          // > 0
  // Match ambiguity and window consistency, for the confident gross mismatches the curvature cannot see
  // (Middlebury 2014, T = 1: with curvature alone the lowest-σ decile holds errors of RMS 8.3 px and the
  // top/bottom decile RMS ratio is 1.4; with the three terms below 7.3, `bench_stereo --quality=2014`):
  //   σ_d² = floor² + scale²·σ_pred² + J,   σ_pred² = 4σ_eff²/C″ + a·p₂/(1 + p₂)·(d₂ − d)²
  // σ_eff² = max(σ_n², C(d)/(2N)) (residual_noise; N = w²T samples: the noise the fit itself shows, which
  // is larger than σ_n where the model fails); p₂ = exp(−(C(d₂) − C(d))/(4σ_eff²)) the likelihood ratio of
  // the runner-up minimum d₂ (≥ 2 px away) under Gaussian noise, a = ambiguity_weight, so σ_pred grows to
  // the runner-up's distance as the two become equally likely; J = mean over the valid w×w neighbours of
  // e_n² for |d_n − d| and |e_n| > neighbour_jump_px, e_n = d_n − d − g·Δ_n the departure from the local slope g
  // (a window straddling a depth edge, isolated mismatches; a slant is not one). The edge test below reads e_n too.
  bool residual_noise = true;
  double ambiguity_weight = 1.0;     // ≥ 0 (0: off)
  double neighbour_jump_px = 1.0;    // < 0: off; ≥ 0: neighbour differences above this count into J
  double max_sigma_disparity_px = 0.0;  // ≥ 0: pixels with a larger σ_d become NaN (0: keep all)
  // < 0: off (library default); ≥ 0: a pixel with a hole (no valid disparity) or a valid pixel whose
  // disparity differs by more than this per pixel of (chessboard) distance within r + 1 = w/2 + 1 of it
  // becomes NaN: its window mixes two surfaces (depth edge, occlusion border, a grazing face), which drags the
  // match to the other surface. On the synthetic scenes 1.0 removes the gross edge errors that dominate the
  // depth RMS (box, T = 16, w = 5, noise 4, 1 GN step: 26.5 → 2.3 mm over the pixels both it and SGBM
  // measured), but also 4–11% of the non-occluded pixels, most of them right: the static preset keeps them
  // as doubtful instead (`rangebayes spacetime --edge-reject 1` still drops them).
  double edge_reject_jump_px = -1.0;
  // < 0: off (library default); ≥ 0 (and edge rejection off): the same test as edge_reject_jump_px, but the
  // pixel is kept and called doubtful: σ_d² += doubtful_sigma_px² + the largest offending jump². Most such
  // pixels are right to 1 px (BENCHMARKS.md, space-time coverage); the smoother then trusts them less.
  double doubtful_jump_px = -1.0;
  double doubtful_sigma_px = 1.0;    // ≥ 0: σ_d added in quadrature to every doubtful pixel (px)
  // 0: keep every doubtful pixel; odd 1–31: keep it only where a v×v×T window (full search range, winner take
  // all) agrees with its disparity to 1 px, else drop it (rejected_edge): a small window sees little of the
  // other surface, so it catches the foreground disparity smeared over the background (the "fattening").
  int doubtful_verify_window_px = 3;
  // 0–5: Gauss–Newton steps after the parabola on the pixels that passed the checks, with the planar window
  // and the left image's gradient (see RefineGaussNewton). 0: parabola only, the library default (the speed
  // case; 0.051 px about the Gray-code plane at T = 16 against 0.050 px with 2 steps). The parabola's pixel
  // locking (±0.03 px, by fractional disparity) leaves depth RMS up to 0.37 of SGBM's away from edges on
  // the synthetic scenes at T = 16, w = 5; one step: up to 0.25 (the static preset uses 1).
  int subpixel_iterations = 0;
  int rows_per_task = 32;            // 1–1024: rows per parallel task (each band recomputes w − 1 rows above it)
  void Check() const;
};

// σ_d model for the Gauss–Newton path (subpixel_iterations > 0, with edge rejection): the parabola's floor
// (its pixel-locking bias) is gone, so the defaults above overstate σ_d there (along-ray normalised residual
// 0.4–0.5 instead of 1 on the synthetic scenes). Fitted like the defaults (`bench_stereo --quality=sigmafit
// --synth-sigmafit-gn=1`): T = 8, w = 7: floor 0.00 px, scale 1.9; T = 16, w = 5: 0.01 px, 1.7. Used by
// `rangebayes spacetime` unless --sigma-floor/--sigma-scale/--noise-model are given.
inline constexpr double kGaussNewtonSigmaFloorPx = 0.01;
inline constexpr double kGaussNewtonSigmaScale = 1.8;

// The configuration for a static scene under T projected patterns, what `rangebayes spacetime` runs: one
// Gauss–Newton step with its σ_d model (kGaussNewtonSigma*), a window of about 400 samples per match (w = 7
// for T < 16, 5 for T ≥ 16; w = 5 at T = 8 misses the synthetic target at noise 4), doubtful pixels kept
// with an inflated σ_d where a 5×5×T (T < 16) or 3×3×T (T ≥ 16) window confirms them. Slower than SpaceTimeMatcherOptions{} (parabola only), which the live path keeps.
// Measured: BENCHMARKS.md, space-time sections (`bench_stereo --quality=synth`, `--quality=coverage`).
SpaceTimeMatcherOptions SpaceTimeStaticSceneOptions(int frames);

// Sets subpixel_iterations together with the σ_d model that belongs to the sub-pixel method:
// kGaussNewtonSigma* with Gauss–Newton steps, SpaceTimeMatcherOptions{}'s (the parabola's) without. Leaves
// the options unchanged when `iterations` is already theirs.
void SetSubpixelIterations(int iterations, SpaceTimeMatcherOptions* options);

// Replaces the matcher's σ_d model by a calibrated one (`rangebayes calibrate noise`): floor-plus-scale gives
// floor and scale (the scale rescaled from the model's image noise to options->image_noise_gray, when the
// model records one); a constant model gives floor σ and a negligible scale (the matcher needs one > 0); a learned
// model leaves the options as they are (LearnedDisparitySigma replaces σ_d after matching).
void ApplyDisparityNoiseModel(const DisparityNoiseModel& model, SpaceTimeMatcherOptions* options);

struct SpaceTimeMatchSummary {
  SpaceTimeCost cost_used = SpaceTimeCost::kSsd;
  int frames = 0;
  int valid_pixels = 0;
  int rejected_left_right = 0;
  int rejected_flat = 0;       // no curvature (textureless), or the parabola's neighbour outside the image
  int rejected_range_end = 0;  // minimum at an end of the search range (DisparityResult::range_end_fraction)
  int rejected_sigma = 0;
  int rejected_ambiguous = 0;  // failed the uniqueness test
  int rejected_edge = 0;       // near a depth edge or a hole (edge_reject_jump_px), or doubtful and unconfirmed
  int doubtful = 0;            // kept near a depth edge or a hole with an inflated σ_d (doubtful_jump_px)
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
