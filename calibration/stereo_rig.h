// A calibrated stereo rig: intrinsics and distortion of both cameras, the extrinsics, and the rectification.
// Stored as OpenCV FileStorage YAML (rig.yaml) so that OpenCV users' own code can read it.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/camera.h"

namespace rangebayes {

// Conventions: OpenCV's. Translation in metres (the board square size sets the unit). right_from_left maps
// a point in the left camera frame into the right camera frame: p_right = R * p_left + t.
struct StereoRig {
  int width = 0;   // image size in pixels, both cameras
  int height = 0;
  Eigen::Matrix3d K_left = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d K_right = Eigen::Matrix3d::Identity();
  Eigen::VectorXd distortion_left;   // OpenCV order (k1 k2 p1 p2 [k3 [k4 k5 k6 ...]]); empty: none
  Eigen::VectorXd distortion_right;
  Eigen::Matrix3d R_right_from_left = Eigen::Matrix3d::Identity();
  Eigen::Vector3d t_right_from_left_m = Eigen::Vector3d::Zero();

  // Rectification (OpenCV stereoRectify). When is_rectified is true the images are already rectified
  // (Middlebury) and R1 = R2 = I, P1/P2 hold the rectified projections.
  bool is_rectified = false;
  Eigen::Matrix3d R1 = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R2 = Eigen::Matrix3d::Identity();
  Eigen::Matrix<double, 3, 4> P1 = Eigen::Matrix<double, 3, 4>::Zero();
  Eigen::Matrix<double, 3, 4> P2 = Eigen::Matrix<double, 3, 4>::Zero();
  Eigen::Matrix4d Q = Eigen::Matrix4d::Zero();
  // Middlebury 2014: x difference of the principal points of the rectified views; Z = f·B / (d + doffs).
  double doffs_px = 0.0;

  // Calibration quality, when the rig came from `rangebayes calibrate rig` (negative: unknown).
  double rms_left_px = -1.0;
  double rms_right_px = -1.0;
  double rms_stereo_px = -1.0;
  double epipolar_error_px = -1.0;         // mean |y_left − y_right| of rectified board corners
  std::vector<std::string> view_names;     // the views that entered the calibration (left file names)
  std::vector<double> view_rms_stereo_px;  // their per-view stereo RMS, same order

  // The rectified left camera (from P1) and the baseline |t| in metres.
  CameraIntrinsics RectifiedLeft() const;
  double baseline_m() const;
  // Throws Error unless the rig can be used: a positive image size, finite entries, positive focal lengths, a
  // baseline |t| > 0 and R a rotation (rounded entries of a hand-written file pass: |RᵀR − I| ≤ 1e-3, det > 0).
  // ReadStereoRig and the Rectifier check it, so a rig built in code (Python) is held to what a file is.
  void Check() const;
};

// Throws Error naming the file and the field on a missing file or a malformed/missing field, or a rig that fails
// StereoRig::Check.
StereoRig ReadStereoRig(const std::string& path);
// Throws Error (and writes nothing) for a rig that fails StereoRig::Check.
void WriteStereoRig(const StereoRig& rig, const std::string& path);

}  // namespace rangebayes
