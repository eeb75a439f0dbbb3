// What a matcher knows about each pixel of its disparity, as the learned noise model reads it (calibration/
// disparity_noise_model.h, form "learned"): the cost-curvature σ_d at the chosen disparity and the largest step to
// a 4-neighbour; and σ_d from a learned model.
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "calibration/disparity_noise_model.h"

namespace rangebayes {

struct DisparityFeatureOptions {
  int window_px = 5;               // odd, 1–31: the SSD window (w × w × T)
  double image_noise_gray = 2.0;   // > 0: σ_n of σ_pred² = 2σ_n² / C″
  double max_sigma_pred_px = 10.0; // > 0: σ_pred where the cost has no positive curvature (and its cap)
  void Check() const;
};

// sigma_pred_px: sqrt(2σ_n² / C″) with C″ = C(d−1) − 2C(d) + C(d+1), C the SSD of grey levels over the w×w
// window and all T frames, the right image sampled linearly at x − d (the matcher's sub-pixel d, any matcher;
// OpenCV SGBM exposes no costs, so they are recomputed here). jump_px: max |d − d_n| over the 4-neighbours n
// with a disparity (0 when none). Both CV_32F of the disparity's size, NaN where the disparity is NaN.
struct DisparityFeatures {
  cv::Mat sigma_pred_px;
  cv::Mat jump_px;
};

// left/right: the rectified frames the disparity came from (8- or 16-bit, 1 or 3 channels, as for a matcher).
// Throws Error on empty or mismatched input.
DisparityFeatures ComputeDisparityFeatures(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right,
                                           const cv::Mat& disparity_px, const DisparityFeatureOptions& options);

// σ_d (CV_32F, NaN where the disparity is NaN) of a learned model for the disparity of `matcher_name` from these
// frames: checks the model applies (DisparityNoiseModel::CheckApplicable; `what` names the model file) and
// computes the features with the model's window and image noise. Throws Error for another form than learned.
// without_jump, when given, receives σ_d without the neighbour-jump term: what the mesh's discontinuity test reads
// (DepthFrame::edge_sigma_depth_m), since a σ that grows with the jump to a neighbour hides every jump from a test
// in units of itself.
cv::Mat LearnedDisparitySigma(const DisparityNoiseModel& model, const std::string& matcher_name,
                              const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right,
                              const cv::Mat& disparity_px, const std::string& what, cv::Mat* without_jump = nullptr);

}  // namespace rangebayes
