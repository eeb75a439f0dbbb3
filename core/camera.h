// Pinhole intrinsics of one (rectified) camera.
#pragma once

#include <Eigen/Core>

namespace rangebayes {

// fx, fy, cx, cy in pixels; the image is width × height pixels.
struct CameraIntrinsics {
  double fx_px = 0.0;
  double fy_px = 0.0;
  double cx_px = 0.0;
  double cy_px = 0.0;
  int width = 0;
  int height = 0;

  // Unit ray direction (camera frame, z forward) through pixel (u, v).
  Eigen::Vector3d Ray(double u, double v) const {
    return Eigen::Vector3d((u - cx_px) / fx_px, (v - cy_px) / fy_px, 1.0).normalized();
  }
};

}  // namespace rangebayes
