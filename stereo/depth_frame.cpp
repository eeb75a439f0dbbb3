#include "stereo/depth_frame.h"

#include <cmath>
#include <limits>

#include "core/error.h"

namespace rangebayes {
namespace {

// σ_Z = σ_d · dZ/dd, with dZ/dd = f·B/(d + doffs)² = Z²/(f·B).
float DepthSigma(double depth_m, double focal_baseline, float sigma_disparity_px) {
  return static_cast<float>(depth_m * depth_m / focal_baseline * sigma_disparity_px);
}

}  // namespace

void DepthFromDisparityOptions::Check() const {
  RB_CHECK(min_depth_m >= 0.0 && max_depth_m > min_depth_m, "depth range [", min_depth_m, ", ", max_depth_m,
           "] m is empty or negative");
  RB_CHECK(sigma_pixel_px > 0.0, "sigma_pixel_px ", sigma_pixel_px, " must be positive");
}

DepthFrame DepthFromDisparity(const cv::Mat& disparity_px, const cv::Mat& sigma_disparity_px,
                              const CameraIntrinsics& intrinsics, double baseline_m, double doffs_px,
                              const DepthFromDisparityOptions& options) {
  options.Check();
  RB_CHECK(!disparity_px.empty() && disparity_px.type() == CV_32F, "disparity must be a non-empty float image");
  RB_CHECK(sigma_disparity_px.empty() || (sigma_disparity_px.type() == CV_32F &&
                                          sigma_disparity_px.size() == disparity_px.size()),
           "sigma_disparity size ", sigma_disparity_px.cols, "x", sigma_disparity_px.rows,
           " differs from the disparity ", disparity_px.cols, "x", disparity_px.rows);
  RB_CHECK(intrinsics.width == disparity_px.cols && intrinsics.height == disparity_px.rows, "intrinsics are for ",
           intrinsics.width, "x", intrinsics.height, " but the disparity is ", disparity_px.cols, "x",
           disparity_px.rows);
  intrinsics.Check();
  RB_CHECK(baseline_m > 0.0 && std::isfinite(baseline_m) && std::isfinite(doffs_px), "baseline ", baseline_m,
           " m must be finite and positive, and doffs ", doffs_px, " px finite");
  DepthFrame frame;
  frame.intrinsics = intrinsics;
  frame.baseline_m = baseline_m;
  frame.doffs_px = doffs_px;
  frame.sigma_pixel_px = options.sigma_pixel_px;
  frame.disparity_px = disparity_px.clone();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  frame.sigma_disparity_px =
      sigma_disparity_px.empty() ? cv::Mat(disparity_px.size(), CV_32F, cv::Scalar(nan)) : sigma_disparity_px.clone();
  frame.depth_m.create(disparity_px.size(), CV_32F);
  frame.sigma_depth_m.create(disparity_px.size(), CV_32F);
  const double fb = intrinsics.fx_px * baseline_m;
  for (int y = 0; y < disparity_px.rows; ++y) {
    const float* d = frame.disparity_px.ptr<float>(y);
    float* s = frame.sigma_disparity_px.ptr<float>(y);
    float* z = frame.depth_m.ptr<float>(y);
    float* sz = frame.sigma_depth_m.ptr<float>(y);
    for (int x = 0; x < disparity_px.cols; ++x) {
      const double dd = static_cast<double>(d[x]) + doffs_px;
      const double depth = std::isfinite(dd) && dd > 0.0 ? fb / dd : std::numeric_limits<double>::quiet_NaN();
      if (!(depth >= options.min_depth_m && depth <= options.max_depth_m)) {
        z[x] = nan;
        sz[x] = nan;
        continue;
      }
      RB_CHECK(!(s[x] < 0.0f) && s[x] != std::numeric_limits<float>::infinity(), "sigma_disparity at (", x, ", ", y,
               ") is ", s[x], " px: it must be finite and >= 0 (NaN: unknown)");
      z[x] = static_cast<float>(depth);
      sz[x] = DepthSigma(depth, fb, s[x]);
    }
  }
  return frame;
}

DepthFrame DepthFromDisparity(const DisparityResult& result, const CameraIntrinsics& intrinsics, double baseline_m,
                              double doffs_px, const DepthFromDisparityOptions& options) {
  DepthFrame frame =
      DepthFromDisparity(result.disparity_px, result.sigma_disparity_px, intrinsics, baseline_m, doffs_px, options);
  if (result.edge_sigma_disparity_px.empty()) return frame;
  RB_CHECK(result.edge_sigma_disparity_px.type() == CV_32F &&
               result.edge_sigma_disparity_px.size() == result.disparity_px.size(),
           "edge_sigma_disparity size ", result.edge_sigma_disparity_px.cols, "x", result.edge_sigma_disparity_px.rows,
           " differs from the disparity");
  const double fb = intrinsics.fx_px * baseline_m;
  frame.edge_sigma_depth_m.create(frame.depth_m.size(), CV_32F);
  for (int y = 0; y < frame.depth_m.rows; ++y) {
    const float* z = frame.depth_m.ptr<float>(y);
    const float* s = result.edge_sigma_disparity_px.ptr<float>(y);
    float* o = frame.edge_sigma_depth_m.ptr<float>(y);
    for (int x = 0; x < frame.depth_m.cols; ++x) {
      o[x] = DepthSigma(z[x], fb, s[x]);  // NaN where there is no depth
    }
  }
  return frame;
}

}  // namespace rangebayes
