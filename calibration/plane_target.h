// A plane target for noise-model tuning: a robust plane fit to triangulated disparities (RANSAC, then least
// squares) and the disparity residuals along the camera rays about it.
#pragma once

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "calibration/disparity_noise_model.h"
#include "core/camera.h"

namespace rangebayes {

// One valid disparity of the rectified left view.
struct DisparityObservation {
  double u_px = 0.0;
  double v_px = 0.0;
  double disparity_px = 0.0;
  double sigma_pred_px = 0.0;  // the matcher's predicted σ_d; NaN when it has none
};

// The valid pixels of a disparity image (CV_32F, NaN invalid) with its σ (CV_32F, or empty: σ NaN), inside
// `roi` (empty rect: the whole image) and `mask` (CV_8U, non-zero = use; empty: all), every stride-th pixel
// in both directions. Throws Error when sizes or types differ.
struct ObservationSelection {
  cv::Rect roi;        // pixels; empty = whole image
  cv::Mat mask;        // CV_8U or empty
  int stride_px = 1;   // [1, 64]
  void Check() const;
};
std::vector<DisparityObservation> ObservationsFromDisparity(const cv::Mat& disparity_px, const cv::Mat& sigma_px,
                                                            const ObservationSelection& selection = {});

// Rectified stereo geometry: Z = f·B / (d + doffs), f = fx of `camera`.
struct DisparityGeometry {
  CameraIntrinsics camera;
  double baseline_m = 0.0;
  double doffs_px = 0.0;
};

struct PlaneTargetOptions {
  double ransac_threshold_m = 0.0;  // RANSAC inlier distance; 0 = 3 × the depth step of 0.5 px at the median depth
  int ransac_iterations = 2000;     // [10, 1e6]
  int refine_iterations = 5;        // least-squares passes, each re-selecting inliers; [1, 50]
  double refine_inlier_sigmas = 3.0;  // inlier band of a pass, in robust σ of the disparity residuals; [1.5, 10]
  void Check() const;
};

struct PlaneTargetSummary {
  Eigen::Vector4d plane = Eigen::Vector4d::Zero();  // n_x, n_y, n_z, c with n·p + c = 0 (left camera, metres)
  int observations = 0;
  int ransac_inliers = 0;
  int inliers = 0;                 // within the final least-squares band
  double inlier_rms_px = 0.0;      // disparity residual RMS of the inliers
  double ransac_threshold_m = 0.0;
};

// Fits the plane to the observations triangulated by `geometry` (PCL RANSAC on 3-D points, then iterated least
// squares in disparity space, where a plane is d + doffs = a·u + b·v + c exactly and the residual runs along
// the ray) and returns one NoiseSample per observation: residual = measured − plane disparity, the
// observation's σ_pred, and the plane's depth at that pixel. Throws Error on fewer than 10 observations or a
// degenerate fit.
std::vector<NoiseSample> PlaneDisparityResiduals(const std::vector<DisparityObservation>& observations,
                                                 const DisparityGeometry& geometry, const PlaneTargetOptions& options,
                                                 PlaneTargetSummary* summary = nullptr);

// PCL adapter (plane_target_pcl.cpp): RANSAC plane through points (n×3, metres) with PCL's
// SampleConsensusModelPlane; returns the inlier indices and sets *plane (n, c; |n| = 1). Deterministic.
std::vector<int> RansacPlane(const Eigen::MatrixX3d& points, double threshold_m, int iterations, Eigen::Vector4d* plane);

}  // namespace rangebayes
