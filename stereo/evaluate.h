// Scoring a disparity map against ground truth (Middlebury's bad-N and RMS, docs/design.md §7).
#pragma once

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace rangebayes {

struct DisparityEvaluationOptions {
  std::vector<double> bad_thresholds_px = {0.5, 1.0, 2.0, 4.0};  // each > 0
  double estimate_scale = 1.0;  // > 0: the estimate is multiplied by this first (e.g. a full-size disparity
                                //     scored against quarter-size ground truth: 0.25)
  void Check() const;
};

// Pixels evaluated: ground truth finite and (if a mask is given) mask ≠ 0.
// bad_with_holes[i]: share of evaluated pixels whose estimate is missing (NaN) or off by more than
//   threshold i (Middlebury's convention: holes count as errors).
// bad_valid_only[i]: the same share among evaluated pixels that have an estimate (holes excluded);
//   coverage says how many those are.
struct DisparityEvaluation {
  long evaluated_pixels = 0;
  long estimated_pixels = 0;   // evaluated pixels with an estimate
  double coverage = 0.0;       // estimated / evaluated
  std::vector<double> thresholds_px;
  std::vector<double> bad_with_holes;
  std::vector<double> bad_valid_only;
  double rms_px = 0.0;         // over estimated pixels
  double mean_abs_px = 0.0;    // over estimated pixels

  // Pixels, coverage, RMS and mean error, then a table of bad-x with holes as errors and holes excluded.
  std::string BriefReport() const;
};

// estimate, ground_truth: CV_32F of one size, NaN unknown. mask: empty or CV_8U of the same size. Throws
// Error on mismatched sizes or types.
DisparityEvaluation EvaluateDisparity(const cv::Mat& estimate, const cv::Mat& ground_truth, const cv::Mat& mask,
                                      const DisparityEvaluationOptions& options = {});

}  // namespace rangebayes
