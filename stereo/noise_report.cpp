#include "stereo/noise_report.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <opencv2/imgproc.hpp>

namespace rangebayes {
namespace {

RgbImage FromRgbMat(const cv::Mat& m) {
  RgbImage out(m.cols, m.rows);
  for (int y = 0; y < m.rows; ++y) std::copy(m.ptr<std::uint8_t>(y), m.ptr<std::uint8_t>(y) + 3 * m.cols, out.at(0, y));
  return out;
}

constexpr int kPanelWidth = 480, kPanelHeight = 360, kMargin = 40;

// Left panel: the histogram of the residuals (a density) against the constant model and the fitted one,
// each a mixture over the samples' predicted σ with the uniform outlier share.
void DrawResidualHistogram(const std::vector<NoiseSample>& samples, const DisparityNoiseModel& model,
                           const NoiseFitSummary& fit, cv::Mat* image) {
  cv::Mat& canvas = *image;
  const int w = kPanelWidth, h = kPanelHeight, margin = kMargin;
  const double half = std::max(4.0 * fit.constant_sigma_px, 1e-3);
  const int bins = 80;
  std::vector<double> hist(bins, 0.0);
  std::vector<double> residuals, preds;
  for (const NoiseSample& s : samples) {
    if (!std::isfinite(s.residual_px)) continue;
    residuals.push_back(s.residual_px);
    preds.push_back(s.sigma_pred_px);
    const int b = static_cast<int>((s.residual_px + half) / (2 * half) * bins);
    if (b >= 0 && b < bins) hist[static_cast<size_t>(b)] += 1.0;
  }
  const double n = static_cast<double>(std::max<size_t>(residuals.size(), 1));
  const double bin_w = 2 * half / bins;
  for (double& v : hist) v /= n * bin_w;  // density
  const auto largest = std::max_element(residuals.begin(), residuals.end(),
                                         [](double a, double b) { return std::abs(a) < std::abs(b); });
  const double range = largest != residuals.end() ? std::abs(*largest) : 1.0;
  const auto density = [&](double x, const DisparityNoiseModel& m) {
    double g = 0;
    const size_t step = std::max<size_t>(1, preds.size() / 2000);
    size_t count = 0;
    for (size_t i = 0; i < preds.size(); i += step, ++count) {
      const double sd = std::max(m.Apply(preds[i]), 1e-9);
      g += std::exp(-0.5 * x * x / (sd * sd)) / (sd * std::sqrt(2 * M_PI));
    }
    g /= std::max<size_t>(count, 1);
    return (1 - m.outlier_fraction) * g + m.outlier_fraction / (2 * std::max(range, 1e-9));
  };
  DisparityNoiseModel constant = model;
  constant.form = NoiseForm::kConstant;
  constant.sigma_px = fit.constant_sigma_px;
  double top = *std::max_element(hist.begin(), hist.end());
  top = std::max(top, density(0.0, model));
  top = std::max(top, density(0.0, constant)) * 1.1;
  const auto px = [&](double x) { return margin + static_cast<int>((x + half) / (2 * half) * (w - 2 * margin)); };
  const auto py = [&](double y) { return h - margin - static_cast<int>(y / top * (h - 2 * margin)); };
  for (int b = 0; b < bins; ++b) {
    const double x0 = -half + b * bin_w;
    cv::rectangle(canvas, cv::Point(px(x0), py(hist[static_cast<size_t>(b)])), cv::Point(px(x0 + bin_w), py(0)),
                  cv::Scalar(180, 180, 180), cv::FILLED);
  }
  for (const auto& [m, colour] : {std::pair{constant, cv::Scalar(0, 0, 220)}, std::pair{model, cv::Scalar(220, 0, 0)}}) {
    cv::Point prev;
    for (int i = 0; i <= 200; ++i) {
      const double x = -half + 2 * half * i / 200.0;
      const cv::Point p(px(x), py(density(x, m)));
      if (i > 0) cv::line(canvas, prev, p, colour, 2, cv::LINE_AA);
      prev = p;
    }
  }
  cv::line(canvas, cv::Point(margin, h - margin), cv::Point(w - margin, h - margin), cv::Scalar(0, 0, 0));
  char text[160];
  std::snprintf(text, sizeof(text), "disparity residual, +-%.2f px", half);
  cv::putText(canvas, text, cv::Point(margin, h - 12), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1);
  std::snprintf(text, sizeof(text), "const sigma %.3f px", fit.constant_sigma_px);
  cv::putText(canvas, text, cv::Point(margin, 20), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 220), 1);
  if (model.form == NoiseForm::kFloorPlusScale) {
    std::snprintf(text, sizeof(text), "floor %.3f px, k %.2f", model.floor_px, model.scale);
    cv::putText(canvas, text, cv::Point(margin + 200, 20), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(220, 0, 0), 1);
  }
}

// Right panel: σ_d per depth bin, the constant σ and the fitted slope through the bins' weighted mean.
void DrawSigmaByDepth(const NoiseFitSummary& fit, cv::Mat* image) {
  if (fit.depth_bins.empty()) return;
  cv::Mat& canvas = *image;
  const int w = kPanelWidth, h = kPanelHeight, margin = kMargin;
  char text[160];
  double zlo = fit.depth_bins.front().depth_m, zhi = fit.depth_bins.back().depth_m;
  if (zhi - zlo < 1e-6) {
    zlo -= 0.05;
    zhi += 0.05;
  }
  const double pad = 0.1 * (zhi - zlo);
  zlo -= pad;
  zhi += pad;
  double smax = fit.constant_sigma_px;
  for (const NoiseDepthBin& b : fit.depth_bins) smax = std::max(smax, b.sigma_px);
  smax *= 1.3;
  const auto qx = [&](double z) { return w + margin + static_cast<int>((z - zlo) / (zhi - zlo) * (w - 2 * margin)); };
  const auto qy = [&](double s) { return h - margin - static_cast<int>(s / smax * (h - 2 * margin)); };
  cv::line(canvas, cv::Point(w + margin, h - margin), cv::Point(2 * w - margin, h - margin), cv::Scalar(0, 0, 0));
  cv::line(canvas, cv::Point(w + margin, h - margin), cv::Point(w + margin, margin), cv::Scalar(0, 0, 0));
  cv::line(canvas, cv::Point(qx(zlo), qy(fit.constant_sigma_px)), cv::Point(qx(zhi), qy(fit.constant_sigma_px)),
           cv::Scalar(0, 0, 220), 1, cv::LINE_AA);
  double mz = 0, ms = 0, cnt = 0;
  for (const NoiseDepthBin& b : fit.depth_bins) {
    mz += b.count * b.depth_m;
    ms += b.count * b.sigma_px;
    cnt += b.count;
  }
  mz /= cnt;
  ms /= cnt;
  const double slope = fit.depth_slope_px_per_m;
  if (std::isfinite(slope)) {
    cv::line(canvas, cv::Point(qx(zlo), qy(ms + slope * (zlo - mz))), cv::Point(qx(zhi), qy(ms + slope * (zhi - mz))),
             cv::Scalar(220, 0, 0), 1, cv::LINE_AA);
  }
  for (const NoiseDepthBin& b : fit.depth_bins) {
    cv::circle(canvas, cv::Point(qx(b.depth_m), qy(b.sigma_px)), 4, cv::Scalar(0, 0, 0), cv::FILLED, cv::LINE_AA);
  }
  if (std::isfinite(slope)) {
    std::snprintf(text, sizeof(text), "sigma_d per depth bin, %.2f-%.2f m; slope %.3f px/m", zlo, zhi, slope);
  } else {
    std::snprintf(text, sizeof(text), "sigma_d per depth bin, %.2f-%.2f m; slope n/a (one depth)", zlo, zhi);
  }
  cv::putText(canvas, text, cv::Point(w + margin, h - 12), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1);
  std::snprintf(text, sizeof(text), "max %.3f px", smax);
  cv::putText(canvas, text, cv::Point(w + margin, margin - 8), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 1);
}

}  // namespace

RgbImage NoiseReportFigure(const std::vector<NoiseSample>& samples, const DisparityNoiseModel& model,
                           const NoiseFitSummary& fit) {
  cv::Mat canvas(kPanelHeight, 2 * kPanelWidth, CV_8UC3, cv::Scalar(255, 255, 255));
  DrawResidualHistogram(samples, model, fit, &canvas);
  DrawSigmaByDepth(fit, &canvas);
  return FromRgbMat(canvas);
}

}  // namespace rangebayes
