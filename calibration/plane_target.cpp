#include "calibration/plane_target.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "core/error.h"

namespace rangebayes {
namespace {

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(m), v.end());
  return v[m];
}

}  // namespace

void PlaneTargetOptions::Check() const {
  RB_CHECK(ransac_threshold_m >= 0 && std::isfinite(ransac_threshold_m), "ransac_threshold_m ", ransac_threshold_m,
           " must be ≥ 0");
  RB_CHECK(ransac_iterations >= 10 && ransac_iterations <= 1000000, "ransac_iterations ", ransac_iterations,
           " not in [10, 1e6]");
  RB_CHECK(refine_iterations >= 1 && refine_iterations <= 50, "refine_iterations ", refine_iterations,
           " not in [1, 50]");
  RB_CHECK(refine_inlier_sigmas >= 1.5 && refine_inlier_sigmas <= 10, "refine_inlier_sigmas ", refine_inlier_sigmas,
           " not in [1.5, 10]");
}

void ObservationSelection::Check() const {
  RB_CHECK(stride_px >= 1 && stride_px <= 64, "stride_px ", stride_px, " not in [1, 64]");
  RB_CHECK(mask.empty() || mask.type() == CV_8UC1, "observation mask must be 8-bit, one channel");
}

std::vector<DisparityObservation> ObservationsFromDisparity(const cv::Mat& disparity_px, const cv::Mat& sigma_px,
                                                            const ObservationSelection& selection) {
  selection.Check();
  RB_CHECK(!disparity_px.empty() && disparity_px.type() == CV_32FC1, "disparity image must be CV_32F, one channel");
  RB_CHECK(sigma_px.empty() || (sigma_px.type() == CV_32FC1 && sigma_px.size() == disparity_px.size()),
           "disparity sigma image must be CV_32F of the disparity's size");
  RB_CHECK(selection.mask.empty() || selection.mask.size() == disparity_px.size(), "mask is ", selection.mask.cols,
           "x", selection.mask.rows, ", the disparity ", disparity_px.cols, "x", disparity_px.rows);
  const cv::Rect full(0, 0, disparity_px.cols, disparity_px.rows);
  const cv::Rect roi = selection.roi.area() > 0 ? (selection.roi & full) : full;
  RB_CHECK(roi.area() > 0, "region of interest lies outside the ", full.width, "x", full.height, " image");
  std::vector<DisparityObservation> out;
  for (int v = roi.y; v < roi.y + roi.height; v += selection.stride_px) {
    const float* d = disparity_px.ptr<float>(v);
    const float* s = sigma_px.empty() ? nullptr : sigma_px.ptr<float>(v);
    const std::uint8_t* m = selection.mask.empty() ? nullptr : selection.mask.ptr<std::uint8_t>(v);
    for (int u = roi.x; u < roi.x + roi.width; u += selection.stride_px) {
      if (!std::isfinite(d[u]) || (m && m[u] == 0)) continue;
      DisparityObservation o;
      o.u_px = u;
      o.v_px = v;
      o.disparity_px = d[u];
      o.sigma_pred_px = s ? static_cast<double>(s[u]) : std::numeric_limits<double>::quiet_NaN();
      out.push_back(o);
    }
  }
  return out;
}

std::vector<NoiseSample> PlaneDisparityResiduals(const std::vector<DisparityObservation>& observations,
                                                 const DisparityGeometry& geometry, const PlaneTargetOptions& options,
                                                 PlaneTargetSummary* summary) {
  options.Check();
  const CameraIntrinsics& cam = geometry.camera;
  cam.Check();
  RB_CHECK(geometry.baseline_m > 0, "plane fit: baseline ", geometry.baseline_m, " m is not positive");
  const double fb = cam.fx_px * geometry.baseline_m;

  // Observations in front of the camera only.
  std::vector<size_t> usable;
  for (size_t i = 0; i < observations.size(); ++i) {
    const double dd = observations[i].disparity_px + geometry.doffs_px;
    if (std::isfinite(dd) && dd > 0) usable.push_back(i);
  }
  RB_CHECK(usable.size() >= 10, "plane fit: only ", usable.size(), " valid disparities (at least 10 needed)");
  Eigen::MatrixX3d points(static_cast<Eigen::Index>(usable.size()), 3);
  std::vector<double> depths;
  for (size_t k = 0; k < usable.size(); ++k) {
    const DisparityObservation& o = observations[usable[k]];
    const double z = fb / (o.disparity_px + geometry.doffs_px);
    points.row(static_cast<Eigen::Index>(k)) << (o.u_px - cam.cx_px) * z / cam.fx_px,
        (o.v_px - cam.cy_px) * z / cam.fy_px, z;
    depths.push_back(z);
  }
  double threshold = options.ransac_threshold_m;
  if (threshold <= 0) {
    const double z = Median(depths);
    threshold = 3.0 * z * z / fb * 0.5;
  }
  Eigen::Vector4d plane3d;
  const std::vector<int> ransac_inliers = RansacPlane(points, threshold, options.ransac_iterations, &plane3d);
  RB_CHECK(ransac_inliers.size() >= 3, "plane fit: RANSAC kept only ", ransac_inliers.size(), " points");

  // Least squares in disparity space: d + doffs = a·u + b·v + c for a plane (1/Z is affine in the pixel).
  std::vector<char> inlier(usable.size(), 0);
  for (int i : ransac_inliers) inlier[static_cast<size_t>(i)] = 1;
  Eigen::Vector3d abc = Eigen::Vector3d::Zero();
  std::vector<double> residual(usable.size());
  int inlier_count = 0;
  double inlier_rms = 0;
  for (int pass = 0; pass < options.refine_iterations; ++pass) {
    Eigen::Matrix3d ata = Eigen::Matrix3d::Zero();
    Eigen::Vector3d atb = Eigen::Vector3d::Zero();
    int n = 0;
    for (size_t k = 0; k < usable.size(); ++k) {
      if (!inlier[k]) continue;
      const DisparityObservation& o = observations[usable[k]];
      const Eigen::Vector3d row(o.u_px, o.v_px, 1.0);
      ata += row * row.transpose();
      atb += row * (o.disparity_px + geometry.doffs_px);
      ++n;
    }
    RB_CHECK(n >= 3, "plane fit: only ", n, " inliers left in the least-squares pass");
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(ata);
    RB_CHECK(ldlt.info() == Eigen::Success && ldlt.rcond() > 1e-14, "plane fit: the inliers do not span a plane");
    abc = ldlt.solve(atb);
    std::vector<double> abs_inlier;
    for (size_t k = 0; k < usable.size(); ++k) {
      const DisparityObservation& o = observations[usable[k]];
      residual[k] = o.disparity_px + geometry.doffs_px - (abc[0] * o.u_px + abc[1] * o.v_px + abc[2]);
      if (inlier[k]) abs_inlier.push_back(std::abs(residual[k]));
    }
    const double sigma = std::max(1.4826 * Median(abs_inlier), 1e-6);
    inlier_count = 0;
    double sum2 = 0;
    for (size_t k = 0; k < usable.size(); ++k) {
      inlier[k] = std::abs(residual[k]) < options.refine_inlier_sigmas * sigma;
      if (inlier[k]) {
        ++inlier_count;
        sum2 += residual[k] * residual[k];
      }
    }
    inlier_rms = inlier_count ? std::sqrt(sum2 / inlier_count) : 0.0;
  }

  std::vector<NoiseSample> samples;
  samples.reserve(usable.size());
  for (size_t k = 0; k < usable.size(); ++k) {
    const DisparityObservation& o = observations[usable[k]];
    NoiseSample s;
    s.residual_px = residual[k];
    s.sigma_pred_px = o.sigma_pred_px;
    const double plane_dd = abc[0] * o.u_px + abc[1] * o.v_px + abc[2];
    s.depth_m = plane_dd > 0 ? fb / plane_dd : std::numeric_limits<double>::quiet_NaN();
    samples.push_back(s);
  }
  if (summary) {
    // a·fx·X + b·fy·Y + (a·cx + b·cy + c)·Z − f·B = 0 is the same plane in the camera frame.
    Eigen::Vector4d p(abc[0] * cam.fx_px, abc[1] * cam.fy_px, abc[0] * cam.cx_px + abc[1] * cam.cy_px + abc[2], -fb);
    p /= p.head<3>().norm();
    summary->plane = p;
    summary->observations = static_cast<int>(usable.size());
    summary->ransac_inliers = static_cast<int>(ransac_inliers.size());
    summary->inliers = inlier_count;
    summary->inlier_rms_px = inlier_rms;
    summary->ransac_threshold_m = threshold;
  }
  return samples;
}

}  // namespace rangebayes
