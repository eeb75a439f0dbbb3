// Pinhole intrinsics of one (rectified) camera.
#pragma once

#include <Eigen/Core>
#include <cmath>

#include "core/error.h"

namespace rangebayes {

// fx, fy, cx, cy in pixels; the image is width × height pixels.
struct CameraIntrinsics {
  double fx_px = 0.0;
  double fy_px = 0.0;
  double cx_px = 0.0;
  double cy_px = 0.0;
  int width = 0;
  int height = 0;

  // Throws Error unless fx and fy are finite and positive and cx, cy finite (the image size is the caller's to
  // compare with its image).
  void Check() const {
    RB_CHECK(fx_px > 0 && fy_px > 0 && std::isfinite(fx_px) && std::isfinite(fy_px) && std::isfinite(cx_px) &&
                 std::isfinite(cy_px),
             "camera: fx ", fx_px, " and fy ", fy_px, " px must be finite and positive, cx ", cx_px, " and cy ", cy_px,
             " px finite");
  }

  // Unit ray direction (camera frame, z forward) through pixel (u, v).
  Eigen::Vector3d Ray(double u, double v) const {
    return Eigen::Vector3d((u - cx_px) / fx_px, (v - cy_px) / fy_px, 1.0).normalized();
  }
};

}  // namespace rangebayes
