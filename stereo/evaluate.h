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
  double rms_px = 0.0;         // over estimated pixels (with bad_valid_only and mean_abs_px: NaN when none)
  double mean_abs_px = 0.0;    // over estimated pixels

  // Pixels, coverage, RMS and mean error, then a table of bad-x with holes as errors and holes excluded.
  std::string BriefReport() const;
};

// estimate, ground_truth: CV_32F of one size, NaN unknown. mask: empty or CV_8U of the same size. Throws
// Error on mismatched sizes or types, and when no pixel has ground truth where the mask selects.
DisparityEvaluation EvaluateDisparity(const cv::Mat& estimate, const cv::Mat& ground_truth, const cv::Mat& mask,
                                      const DisparityEvaluationOptions& options = {});

// Ground truth stored in whole steps (Middlebury's PNG and PGM maps: 1/3, 1/4 or 1/8 px; the 2014 ArtL and Teddy
// maps: 1/4 px) is a staircase of fronto-parallel treads on slanted surfaces, whose normals are not the surface's.
// The step: the coarsest of 1, 1/2, 1/3, 1/4, 1/8 and 1/16 px of which at least 99% of the finite values of
// `disparity` (CV_32F, NaN unknown) are whole multiples; 0 when none is (a continuous map) or no value is finite.
double QuantisationStep(const cv::Mat& disparity);

// The same map with its steps smoothed out: each finite pixel takes the centre value of a least-squares plane
// through the finite pixels of its (2·half_window + 1)² window that lie within 1.5 steps of it (so no neighbour from
// across a depth jump), when there are at least 6; the value moves by at most one step (the stored value is
// right to within half a step). On continuous 2014 maps quantised on purpose to 1/3 px it halves the RMS error
// (docs/journal/real-noise.md, session 27). step_px > 0, half_window in [1, 10]; NaN stays NaN.
cv::Mat RemoveQuantisationSteps(const cv::Mat& disparity, double step_px, int half_window = 3);

// A ground-truth map as scoring and noise fitting take it: with its steps removed when QuantisationStep finds one,
// else as stored. *step_px (when given): the step found, 0 for a continuous map.
cv::Mat GroundTruthWithoutSteps(const cv::Mat& disparity, double* step_px = nullptr);

}  // namespace rangebayes
