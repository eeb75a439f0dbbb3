// A depth image in the rectified left view, with its per-pixel uncertainty (docs/design.md §2).
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>

#include "core/camera.h"
#include "stereo/matcher.h"

namespace rangebayes {

// All images are CV_32F, intrinsics.height × intrinsics.width, NaN where there is no measurement.
//   disparity_px: left-view disparity d (left x minus right x), pixels.
//   sigma_disparity_px: standard deviation of d (from the matcher's cost curvature; NaN when unknown).
//   depth_m: Z = f·B / (d + doffs), metres along the optical axis of the rectified left camera.
//   sigma_depth_m: σ_Z = Z² / (f·B) · σ_d (first order in d).
struct DepthFrame {
  cv::Mat depth_m;
  cv::Mat sigma_depth_m;
  cv::Mat disparity_px;
  cv::Mat sigma_disparity_px;
  // Optional: the σ_Z the mesh's discontinuity test reads where it differs from sigma_depth_m (empty: that one). A
  // learned noise model's σ grows with the jump to a neighbour and so would hide every jump from a test in units of
  // itself (a Teddy mesh went from 971 edges cut to none); this is its σ without that term.
  cv::Mat edge_sigma_depth_m;
  std::int64_t frame_id = 0;
  std::int64_t timestamp_ns = 0;
  CameraIntrinsics intrinsics;  // the rectified left camera
  double baseline_m = 0.0;
  double doffs_px = 0.0;        // Middlebury 2014 principal-point offset; 0 for our own rectification
  double sigma_pixel_px = 0.2;  // lateral pixel localisation σ, used for the across-ray covariance

  bool empty() const { return depth_m.empty(); }
  int width() const { return depth_m.cols; }
  int height() const { return depth_m.rows; }
};

struct DepthFromDisparityOptions {
  double min_depth_m = 0.0;       // ≥ 0: depths below become NaN
  double max_depth_m = 1e9;       // > min_depth_m: depths above become NaN
  double sigma_pixel_px = 0.2;    // > 0: lateral pixel localisation σ stored in the frame
  void Check() const;
};

// Builds a DepthFrame from a float disparity (CV_32F, NaN invalid) and optionally its σ (empty: σ NaN).
// Disparities with d + doffs ≤ 0 become NaN. Throws Error when sizes differ from each other or from
// intrinsics, when the intrinsics fail CameraIntrinsics::Check, the baseline is not finite and positive or doffs
// not finite, or when a valid pixel's σ is negative or infinite.
DepthFrame DepthFromDisparity(const cv::Mat& disparity_px, const cv::Mat& sigma_disparity_px,
                              const CameraIntrinsics& intrinsics, double baseline_m, double doffs_px,
                              const DepthFromDisparityOptions& options = {});

// The same from a matcher's result, its edge_sigma_disparity_px (when there is one) converted into
// DepthFrame::edge_sigma_depth_m as σ_d into σ_Z.
DepthFrame DepthFromDisparity(const DisparityResult& result, const CameraIntrinsics& intrinsics, double baseline_m,
                              double doffs_px, const DepthFromDisparityOptions& options = {});

}  // namespace rangebayes
