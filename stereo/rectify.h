// Rectification of stereo pairs from a calibrated rig: maps computed once, one remap per frame.
#pragma once

#include <opencv2/core.hpp>

#include "calibration/stereo_rig.h"
#include "core/camera.h"

namespace rangebayes {

struct RectifierOptions {
  double alpha = 0.0;  // −1 or 0–1: OpenCV stereoRectify free scaling (0: only valid pixels, 1: all pixels)
  int interpolation = 1;  // OpenCV interpolation flag for remap (1: bilinear)
  void Check() const;
};

// Holds the rectification maps of one rig. When the rig says is_rectified (Middlebury), images pass through
// untouched. When the rig has no rectification yet (P1 zero) it is computed with cv::stereoRectify
// (CALIB_ZERO_DISPARITY) and stored in rectified_rig().
class Rectifier {
 public:
  // Throws Error when the rig fails StereoRig::Check.
  explicit Rectifier(const StereoRig& rig, const RectifierOptions& options = {});

  // Rectifies one pair (any type remap supports). Throws Error naming the size when an image is not the
  // rig's size.
  void Rectify(const cv::Mat& left, const cv::Mat& right, cv::Mat* left_rectified, cv::Mat* right_rectified) const;

  bool passthrough() const { return passthrough_; }
  const StereoRig& rectified_rig() const { return rig_; }
  // The rectified left camera, the baseline (m) and doffs (px) that turn disparity into depth.
  CameraIntrinsics intrinsics() const { return intrinsics_; }
  double baseline_m() const { return baseline_m_; }
  double doffs_px() const { return rig_.doffs_px; }

 private:
  StereoRig rig_;
  bool passthrough_ = false;
  CameraIntrinsics intrinsics_;
  double baseline_m_ = 0.0;
  int interpolation_ = 1;
  cv::Mat map_left_x_, map_left_y_, map_right_x_, map_right_y_;
};

}  // namespace rangebayes
