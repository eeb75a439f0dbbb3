#include "stereo/disparity_features.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "stereo/matcher.h"

namespace rangebayes {

void DisparityFeatureOptions::Check() const {
  RB_CHECK(window_px >= 1 && window_px <= 31 && window_px % 2 == 1, "disparity features: window_px ", window_px,
           " must be odd and in 1–31");
  RB_CHECK(image_noise_gray > 0 && std::isfinite(image_noise_gray), "disparity features: image_noise_gray ",
           image_noise_gray, " must be positive");
  RB_CHECK(max_sigma_pred_px > 0 && std::isfinite(max_sigma_pred_px), "disparity features: max_sigma_pred_px ",
           max_sigma_pred_px, " must be positive");
}

namespace {

cv::Mat GreyFloat(const cv::Mat& image) {
  cv::Mat grey = image;
  if (image.channels() == 3) cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  cv::Mat f;
  // 16-bit frames on the 8-bit grey scale, so that σ_n means the same grey levels.
  grey.convertTo(f, CV_32F, image.depth() == CV_16U ? 1.0 / 257.0 : 1.0);
  return f;
}

}  // namespace

DisparityFeatures ComputeDisparityFeatures(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right,
                                           const cv::Mat& disparity_px, const DisparityFeatureOptions& options) {
  options.Check();
  CheckStereoSequence(left, right);
  RB_CHECK(disparity_px.type() == CV_32F && disparity_px.size() == left[0].size(),
           "disparity features: the disparity must be CV_32F of the images' size");
  std::vector<cv::Mat> l, r;
  for (size_t t = 0; t < left.size(); ++t) {
    l.push_back(GreyFloat(left[t]));
    r.push_back(GreyFloat(right[t]));
  }
  const int w = disparity_px.cols, h = disparity_px.rows, half = options.window_px / 2;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  DisparityFeatures out;
  out.sigma_pred_px.create(h, w, CV_32F);
  out.jump_px.create(h, w, CV_32F);
  const double two_var = 2.0 * options.image_noise_gray * options.image_noise_gray;
  const double max_sigma = options.max_sigma_pred_px;
  tbb::parallel_for(0, h, [&](int y) {
    const float* d = disparity_px.ptr<float>(y);
    float* sp = out.sigma_pred_px.ptr<float>(y);
    float* jp = out.jump_px.ptr<float>(y);
    for (int x = 0; x < w; ++x) {
      if (!std::isfinite(d[x])) {
        sp[x] = jp[x] = nan;
        continue;
      }
      float jump = 0;
      const auto neighbour = [&](int xn, int yn) {
        if (xn < 0 || yn < 0 || xn >= w || yn >= h) return;
        const float dn = disparity_px.at<float>(yn, xn);
        if (std::isfinite(dn)) jump = std::max(jump, std::abs(dn - d[x]));
      };
      neighbour(x - 1, y);
      neighbour(x + 1, y);
      neighbour(x, y - 1);
      neighbour(x, y + 1);
      jp[x] = jump;
      double cost[3] = {0, 0, 0};
      for (size_t t = 0; t < l.size(); ++t) {
        for (int j = -half; j <= half; ++j) {
          const int yy = std::clamp(y + j, 0, h - 1);
          const float* lr = l[t].ptr<float>(yy);
          const float* rr = r[t].ptr<float>(yy);
          for (int i = -half; i <= half; ++i) {
            const int xx = std::clamp(x + i, 0, w - 1);
            for (int k = 0; k < 3; ++k) {
              const double xr = std::clamp(static_cast<double>(xx) - d[x] - (k - 1), 0.0, w - 1.0);
              const int x0 = std::min(static_cast<int>(xr), w - 2 < 0 ? 0 : w - 2);
              const double a = xr - x0;
              const double rv = w > 1 ? (1 - a) * rr[x0] + a * rr[x0 + 1] : rr[0];
              const double e = lr[xx] - rv;
              cost[k] += e * e;
            }
          }
        }
      }
      const double curvature = cost[0] - 2 * cost[1] + cost[2];
      const double s = curvature > 0 ? std::sqrt(two_var / curvature) : max_sigma;
      sp[x] = static_cast<float>(std::min(s, max_sigma));
    }
  });
  return out;
}

cv::Mat LearnedDisparitySigma(const DisparityNoiseModel& model, const std::string& matcher_name,
                              const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right,
                              const cv::Mat& disparity_px, const std::string& what, cv::Mat* without_jump) {
  RB_CHECK(model.form == NoiseForm::kLearned, what, ": a noise model of form '", NoiseFormName(model.form),
           "' has no per-pixel features (learned form expected)");
  model.CheckApplicable(matcher_name, disparity_px.cols, what);
  DisparityFeatureOptions options;
  options.window_px = model.window_px;
  if (model.image_noise_gray > 0) options.image_noise_gray = model.image_noise_gray;
  const DisparityFeatures f = ComputeDisparityFeatures(left, right, disparity_px, options);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cv::Mat sigma(disparity_px.size(), CV_32F);
  if (without_jump != nullptr) without_jump->create(disparity_px.size(), CV_32F);
  for (int y = 0; y < sigma.rows; ++y) {
    const float* sp = f.sigma_pred_px.ptr<float>(y);
    const float* jp = f.jump_px.ptr<float>(y);
    float* o = sigma.ptr<float>(y);
    float* o0 = without_jump != nullptr ? without_jump->ptr<float>(y) : nullptr;
    for (int x = 0; x < sigma.cols; ++x) {
      o[x] = std::isfinite(sp[x]) ? static_cast<float>(model.Apply(sp[x], jp[x])) : nan;
      if (o0 != nullptr) o0[x] = std::isfinite(sp[x]) ? static_cast<float>(model.Apply(sp[x], 0.0)) : nan;
    }
  }
  return sigma;
}

}  // namespace rangebayes
