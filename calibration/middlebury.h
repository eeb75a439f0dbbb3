// Middlebury 2014 calib.txt (rectified views: cam0, cam1, doffs, baseline in mm, ndisp, ...) as a StereoRig.
#pragma once

#include <Eigen/Core>
#include <string>

#include "calibration/stereo_rig.h"

namespace rangebayes {

struct MiddleburyCalib {
  Eigen::Matrix3d cam0 = Eigen::Matrix3d::Identity();  // rectified left K, pixels at the file's resolution
  Eigen::Matrix3d cam1 = Eigen::Matrix3d::Identity();
  double doffs_px = 0.0;     // x difference of the principal points: Z = f·B / (d + doffs)
  double baseline_mm = 0.0;
  int width = 0;
  int height = 0;
  int ndisp = 0;             // conservative bound on the number of disparity levels
  double vmin = 0.0;         // tight disparity bounds (optional in the file; 0 when absent)
  double vmax = 0.0;
};

// Parses `key=value` lines; matrices as `[a b c; d e f; g h i]`. Throws Error naming the file and the key on a
// missing file, a missing required key (cam0, cam1, baseline, width, height) or a malformed value.
MiddleburyCalib ReadMiddleburyCalib(const std::string& path);

// The rig of a Middlebury scene: is_rectified, K_left = cam0, K_right = cam1, R = I,
// t_right_from_left = (−B, 0, 0) in metres, P1/P2 from cam0/cam1, doffs_px kept.
StereoRig StereoRigFromMiddlebury(const MiddleburyCalib& calib);

}  // namespace rangebayes
