#include "stereo/rectify.h"

#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"

namespace rangebayes {

void RectifierOptions::Check() const {
  RB_CHECK(alpha == -1.0 || (alpha >= 0.0 && alpha <= 1.0), "rectification alpha ", alpha,
           " must be −1 or in 0–1");
  RB_CHECK(interpolation >= 0 && interpolation <= 4, "interpolation flag ", interpolation, " is not valid");
}

namespace {
cv::Mat ToMat(const Eigen::MatrixXd& m) {
  cv::Mat out;
  cv::eigen2cv(m, out);
  return out;
}
}  // namespace

Rectifier::Rectifier(const StereoRig& rig, const RectifierOptions& options) : rig_(rig) {
  options.Check();
  interpolation_ = options.interpolation;
  try {
    rig.Check();
  } catch (const Error& e) {
    RB_FAIL("rig: ", e.what());
  }
  const cv::Size size(rig.width, rig.height);
  if (rig.is_rectified) {
    passthrough_ = true;
    if (!(rig_.P1(0, 0) > 0.0)) {
      rig_.P1.setZero();
      rig_.P1.leftCols<3>() = rig.K_left;
      rig_.P2.setZero();
      rig_.P2.leftCols<3>() = rig.K_right;
      rig_.P2(0, 3) = -rig.K_right(0, 0) * rig.baseline_m();
    }
  } else {
    const bool have_rectification = rig.P1(0, 0) > 0.0 && rig.P2(0, 0) > 0.0;
    cv::Mat K1 = ToMat(rig.K_left), K2 = ToMat(rig.K_right);
    cv::Mat D1 = rig.distortion_left.size() ? ToMat(rig.distortion_left) : cv::Mat();
    cv::Mat D2 = rig.distortion_right.size() ? ToMat(rig.distortion_right) : cv::Mat();
    cv::Mat R1, R2, P1, P2, Q;
    if (have_rectification) {
      R1 = ToMat(rig.R1);
      R2 = ToMat(rig.R2);
      P1 = ToMat(rig.P1);
      P2 = ToMat(rig.P2);
    } else {
      try {
        cv::stereoRectify(K1, D1, K2, D2, size, ToMat(rig.R_right_from_left), ToMat(rig.t_right_from_left_m), R1, R2,
                          P1, P2, Q, cv::CALIB_ZERO_DISPARITY, options.alpha, size);
      } catch (const cv::Exception& e) {
        RB_FAIL("stereoRectify failed on the rig (", e.err, ")");
      }
      Eigen::MatrixXd tmp;
      cv::cv2eigen(R1, tmp);
      rig_.R1 = tmp;
      cv::cv2eigen(R2, tmp);
      rig_.R2 = tmp;
      cv::cv2eigen(P1, tmp);
      rig_.P1 = tmp;
      cv::cv2eigen(P2, tmp);
      rig_.P2 = tmp;
      cv::cv2eigen(Q, tmp);
      rig_.Q = tmp;
    }
    cv::initUndistortRectifyMap(K1, D1, R1, P1, size, CV_32FC1, map_left_x_, map_left_y_);
    cv::initUndistortRectifyMap(K2, D2, R2, P2, size, CV_32FC1, map_right_x_, map_right_y_);
  }
  intrinsics_ = rig_.RectifiedLeft();
  // P2 = [f 0 cx' −f·B; ...] for a horizontal rig; the baseline from P2 is the rectified one.
  baseline_m_ = rig_.P2(0, 0) > 0.0 && rig_.P2(0, 3) != 0.0 ? std::abs(rig_.P2(0, 3) / rig_.P2(0, 0)) : rig.baseline_m();
  RB_CHECK(baseline_m_ > 0.0, "rig has a zero baseline");
}

void Rectifier::Rectify(const cv::Mat& left, const cv::Mat& right, cv::Mat* left_rectified,
                        cv::Mat* right_rectified) const {
  RB_CHECK(left.cols == rig_.width && left.rows == rig_.height && right.size() == left.size(), "images are ",
           left.cols, "x", left.rows, " and ", right.cols, "x", right.rows, " but the rig is ", rig_.width, "x",
           rig_.height);
  if (passthrough_) {
    *left_rectified = left;
    *right_rectified = right;
    return;
  }
  cv::remap(left, *left_rectified, map_left_x_, map_left_y_, interpolation_, cv::BORDER_CONSTANT);
  cv::remap(right, *right_rectified, map_right_x_, map_right_y_, interpolation_, cv::BORDER_CONSTANT);
}

}  // namespace rangebayes
