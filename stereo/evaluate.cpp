#include "stereo/evaluate.h"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <limits>

#include "core/error.h"

namespace rangebayes {

void DisparityEvaluationOptions::Check() const {
  RB_CHECK(!bad_thresholds_px.empty(), "no bad-N thresholds given");
  for (double t : bad_thresholds_px) RB_CHECK(t > 0.0, "bad-N threshold ", t, " must be positive");
  RB_CHECK(estimate_scale > 0.0, "estimate_scale ", estimate_scale, " must be positive");
}

DisparityEvaluation EvaluateDisparity(const cv::Mat& estimate, const cv::Mat& ground_truth, const cv::Mat& mask,
                                      const DisparityEvaluationOptions& options) {
  options.Check();
  RB_CHECK(estimate.type() == CV_32F && ground_truth.type() == CV_32F, "disparities must be float images");
  RB_CHECK(estimate.size() == ground_truth.size(), "estimate is ", estimate.cols, "x", estimate.rows,
           " but the ground truth is ", ground_truth.cols, "x", ground_truth.rows);
  RB_CHECK(mask.empty() || (mask.type() == CV_8U && mask.size() == estimate.size()), "mask is ", mask.cols, "x",
           mask.rows, " (must be 8-bit and the size of the ground truth, ", ground_truth.cols, "x",
           ground_truth.rows, ")");
  const size_t n = options.bad_thresholds_px.size();
  std::vector<long> bad(n, 0), bad_valid(n, 0);
  DisparityEvaluation ev;
  double sum2 = 0.0, sum1 = 0.0;
  for (int y = 0; y < estimate.rows; ++y) {
    const float* e = estimate.ptr<float>(y);
    const float* g = ground_truth.ptr<float>(y);
    const unsigned char* m = mask.empty() ? nullptr : mask.ptr<unsigned char>(y);
    for (int x = 0; x < estimate.cols; ++x) {
      if (!std::isfinite(g[x]) || (m && m[x] == 0)) continue;
      ++ev.evaluated_pixels;
      if (!std::isfinite(e[x])) {
        for (size_t i = 0; i < n; ++i) ++bad[i];
        continue;
      }
      ++ev.estimated_pixels;
      const double err = std::abs(e[x] * options.estimate_scale - g[x]);
      sum2 += err * err;
      sum1 += err;
      for (size_t i = 0; i < n; ++i) {
        if (err > options.bad_thresholds_px[i]) {
          ++bad[i];
          ++bad_valid[i];
        }
      }
    }
  }
  // No pixel scored would read as a perfect score (every bad-x 0%).
  RB_CHECK(ev.evaluated_pixels > 0, "no pixel to score: the ground truth has no value",
           mask.empty() ? "" : " where the mask selects");
  ev.thresholds_px = options.bad_thresholds_px;
  ev.bad_with_holes.resize(n);
  ev.bad_valid_only.resize(n);
  const double ne = static_cast<double>(ev.evaluated_pixels);
  // Without an estimated pixel the statistics over estimated pixels are unknown (NaN), not a perfect 0.
  const double nv =
      ev.estimated_pixels > 0 ? static_cast<double>(ev.estimated_pixels) : std::numeric_limits<double>::quiet_NaN();
  for (size_t i = 0; i < n; ++i) {
    ev.bad_with_holes[i] = static_cast<double>(bad[i]) / ne;
    ev.bad_valid_only[i] = static_cast<double>(bad_valid[i]) / nv;
  }
  ev.coverage = static_cast<double>(ev.estimated_pixels) / ne;
  ev.rms_px = std::sqrt(sum2 / nv);
  ev.mean_abs_px = sum1 / nv;
  return ev;
}

std::string DisparityEvaluation::BriefReport() const {
  std::string out;
  char line[256];
  if (estimated_pixels > 0) {
    std::snprintf(line, sizeof(line), "evaluated %ld pixels, coverage %.2f%%, RMS %.3f px, mean |error| %.3f px\n",
                  evaluated_pixels, 100.0 * coverage, rms_px, mean_abs_px);
  } else {
    std::snprintf(line, sizeof(line), "evaluated %ld pixels, coverage 0%%: no estimated pixel (RMS n/a)\n",
                  evaluated_pixels);
  }
  out += line;
  std::snprintf(line, sizeof(line), "%-10s %18s %18s\n", "threshold", "holes as errors", "holes excluded");
  out += line;
  for (size_t i = 0; i < thresholds_px.size(); ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "bad-%g", thresholds_px[i]);
    char excluded[32] = "n/a";
    if (estimated_pixels > 0) std::snprintf(excluded, sizeof excluded, "%.2f%%", 100.0 * bad_valid_only[i]);
    std::snprintf(line, sizeof(line), "%-10s %17.2f%% %18s\n", name, 100.0 * bad_with_holes[i], excluded);
    out += line;
  }
  return out;
}

double QuantisationStep(const cv::Mat& disparity) {
  RB_CHECK(disparity.type() == CV_32F, "QuantisationStep: the disparity must be CV_32F");
  constexpr int kDivisions[] = {1, 2, 3, 4, 8, 16};
  long finite = 0;
  long whole[std::size(kDivisions)] = {};
  for (int r = 0; r < disparity.rows; ++r) {
    const float* row = disparity.ptr<float>(r);
    for (int c = 0; c < disparity.cols; ++c) {
      if (!std::isfinite(row[c])) continue;
      ++finite;
      for (size_t k = 0; k < std::size(kDivisions); ++k) {
        const double scaled = static_cast<double>(row[c]) * kDivisions[k];
        whole[k] += std::abs(scaled - std::round(scaled)) < 1e-3;
      }
    }
  }
  if (finite == 0) return 0.0;
  for (size_t k = 0; k < std::size(kDivisions); ++k) {
    if (static_cast<double>(whole[k]) >= 0.99 * static_cast<double>(finite)) return 1.0 / kDivisions[k];
  }
  return 0.0;
}

cv::Mat RemoveQuantisationSteps(const cv::Mat& disparity, double step_px, int half_window) {
  RB_CHECK(disparity.type() == CV_32F, "RemoveQuantisationSteps: the disparity must be CV_32F");
  RB_CHECK(step_px > 0 && std::isfinite(step_px), "RemoveQuantisationSteps: step_px ", step_px, " must be > 0");
  RB_CHECK(half_window >= 1 && half_window <= 10, "RemoveQuantisationSteps: half_window ", half_window,
           " is outside [1, 10]");
  cv::Mat out = disparity.clone();
  const double reach = 1.5 * step_px;
  for (int r = 0; r < disparity.rows; ++r) {
    for (int c = 0; c < disparity.cols; ++c) {
      const float centre = disparity.at<float>(r, c);
      if (!std::isfinite(centre)) continue;
      // Normal equations of d = a + b·x + e·y in window coordinates centred on (r, c): the centre value is a.
      Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
      Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
      int used = 0;
      for (int dy = -half_window; dy <= half_window; ++dy) {
        const int y = r + dy;
        if (y < 0 || y >= disparity.rows) continue;
        for (int dx = -half_window; dx <= half_window; ++dx) {
          const int x = c + dx;
          if (x < 0 || x >= disparity.cols) continue;
          const float value = disparity.at<float>(y, x);
          if (!std::isfinite(value) || std::abs(static_cast<double>(value) - centre) > reach) continue;
          const Eigen::Vector3d basis(1.0, dx, dy);
          normal += basis * basis.transpose();
          rhs += basis * static_cast<double>(value);
          ++used;
        }
      }
      if (used < 6) continue;
      const Eigen::LDLT<Eigen::Matrix3d> solver(normal);
      if (solver.info() != Eigen::Success || !(solver.rcond() > 1e-9)) continue;
      const double fitted = solver.solve(rhs)[0];
      if (!std::isfinite(fitted)) continue;
      out.at<float>(r, c) = static_cast<float>(std::clamp(fitted, centre - step_px, centre + step_px));
    }
  }
  return out;
}

cv::Mat GroundTruthWithoutSteps(const cv::Mat& disparity, double* step_px) {
  const double step = QuantisationStep(disparity);
  if (step_px != nullptr) *step_px = step;
  return step > 0 ? RemoveQuantisationSteps(disparity, step) : disparity;
}

}  // namespace rangebayes
