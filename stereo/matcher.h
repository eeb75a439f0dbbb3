// The stereo matcher interface: rectified image sequence of a static scene in, float disparity out.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace rangebayes {

// Output of a matcher, in the left view. disparity_px: CV_32F, left x minus right x, NaN where the matcher
// gives no answer (occluded, failed left-right check, no texture). sigma_disparity_px: CV_32F standard
// deviation of the disparity, or empty when the matcher cannot estimate it (OpenCV SGBM exposes no cost
// volume).
struct DisparityResult {
  cv::Mat disparity_px;
  cv::Mat sigma_disparity_px;
  // Optional (a learned noise model): σ_d for the mesh's discontinuity test, as DepthFrame::edge_sigma_depth_m.
  cv::Mat edge_sigma_disparity_px;
  double match_ms = 0.0;      // wall time of the matching itself
  int frames_used = 0;
  double valid_fraction = 0.0;
  // Share of the pixels whose best match lies at an end of the disparities searched (a distinct minimum there; the
  // lower end only above disparity 0): much of it says that part of the scene lies outside the search range
  // (closer or farther), where nothing can be matched. See kRangeEndWarning.
  double range_end_fraction = 0.0;
  // The disparities searched, when the matcher searched other than those asked for (SGBM: a multiple of 16); 0:
  // as asked.
  int num_disparities_searched = 0;

  // One line for people: "disparity: WxH, P% valid, matched in T ms over N frame(s)".
  std::string BriefReport() const;
};

// range_end_fraction from which the commands warn that the search range looks too short. Measured: with each
// Middlebury 2014 scene's own range, SGBM 0.0–0.1% (PianoL, lit differently, 2.4%); with the default 64 px where
// a scene needs more, Vintage 10.3%, Jadeplant 8.0%, Playroom 3.5%, PianoL 3.0%, Pipes 1.8%; the D435 Gray-code
// plane (disparities 60–100) 3.1% for SGBM and 6.8% for space-time stereo, against 0.1% and 0.7% with 112 px;
// Tsukuba with its range 0.1% (SGBM) and 0.3% (single-frame block matcher), 24–31% with half of it
// (tests/stereo/sgbm_test.cpp).
constexpr double kRangeEndWarning = 0.03;

// What the commands add to a range-end warning: what it may mean and the options that widen the range.
std::string RangeEndAdvice();

class StereoMatcher {
 public:
  virtual ~StereoMatcher() = default;
  // left[i], right[i]: frame i of a rectified sequence (T ≥ 1 frames, static scene), all the same size and
  // type (8- or 16-bit, 1 or 3 channels). Single-frame matchers use frame 0. Throws Error on empty input,
  // mismatched sizes/types or differing frame counts.
  virtual DisparityResult Match(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right) = 0;
  virtual std::string name() const = 0;
};

// Pixels whose σ_d exceeds max_sigma_px become NaN (disparity and σ_d); valid_fraction follows. For a σ_d that a
// noise model gave after matching (the matcher's own max_sigma_disparity_px saw the matcher's σ_d). Requires
// result->sigma_disparity_px; max_sigma_px > 0.
void DropAboveSigma(double max_sigma_px, DisparityResult* result);

// Throws Error unless left and right hold the same number (≥ 1) of non-empty images of one size and type.
void CheckStereoSequence(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right);

}  // namespace rangebayes
