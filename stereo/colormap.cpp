#include "stereo/colormap.h"

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"

namespace rangebayes {
namespace {

// Polynomial fit of Google's Turbo colormap (Apache-2.0 licensed coefficients published with it).
void Turbo(double t, std::uint8_t* rgb) {
  t = std::clamp(t, 0.0, 1.0);
  const double r = 0.13572138 + t * (4.61539260 + t * (-42.66032258 + t * (132.13108234 + t * (-152.94239396 + t * 59.28637943))));
  const double g = 0.09140261 + t * (2.19418839 + t * (4.84296658 + t * (-14.18503333 + t * (4.27729857 + t * 2.82956604))));
  const double b = 0.10667330 + t * (12.64194608 + t * (-60.58204836 + t * (110.36276771 + t * (-89.90310912 + t * 27.34824973))));
  rgb[0] = static_cast<std::uint8_t>(std::clamp(r, 0.0, 1.0) * 255.0 + 0.5);
  rgb[1] = static_cast<std::uint8_t>(std::clamp(g, 0.0, 1.0) * 255.0 + 0.5);
  rgb[2] = static_cast<std::uint8_t>(std::clamp(b, 0.0, 1.0) * 255.0 + 0.5);
}

}  // namespace

RgbImage ColorMap(const cv::Mat& image, const ColorMapOptions& options) {
  RB_CHECK(image.type() == CV_32F && !image.empty(), "colour map needs a non-empty float image");
  double lo = options.min_value, hi = options.max_value;
  if (!(hi > lo)) {
    std::vector<float> values;
    values.reserve(image.total());
    for (int y = 0; y < image.rows; ++y) {
      const float* p = image.ptr<float>(y);
      for (int x = 0; x < image.cols; ++x) {
        if (std::isfinite(p[x])) values.push_back(p[x]);
      }
    }
    lo = 0.0;
    hi = 1.0;
    if (!values.empty()) {
      const size_t a = values.size() / 100, b = values.size() - 1 - values.size() / 100;
      std::nth_element(values.begin(), values.begin() + a, values.end());
      lo = values[a];
      std::nth_element(values.begin(), values.begin() + b, values.end());
      hi = values[b];
      if (!(hi > lo)) hi = lo + 1e-6;
    }
  }
  RgbImage out(image.cols, image.rows, 0);
  for (int y = 0; y < image.rows; ++y) {
    const float* p = image.ptr<float>(y);
    for (int x = 0; x < image.cols; ++x) {
      std::uint8_t* o = out.at(x, y);
      if (!std::isfinite(p[x])) {
        o[0] = o[1] = o[2] = 0;
        continue;
      }
      double t = (p[x] - lo) / (hi - lo);
      if (options.reverse) t = 1.0 - t;
      Turbo(t, o);
    }
  }
  return out;
}

}  // namespace rangebayes
