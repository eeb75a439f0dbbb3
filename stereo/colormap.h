// Colour-mapped pictures of float images (disparity, depth, σ) for people to look at.
#pragma once

#include <opencv2/core.hpp>

#include "core/image.h"

namespace rangebayes {

struct ColorMapOptions {
  double min_value = 0.0;   // value mapped to the first colour
  double max_value = 0.0;   // value mapped to the last colour; max ≤ min: use the 1st–99th percentile
  bool reverse = false;     // true: large values get the first colour (near = warm for depth)
  void Check() const {}
};

// CV_32F image → RGB picture with a perceptual blue–green–yellow–red ramp (Turbo, Mikhailov 2019, polynomial
// approximation); NaN/inf pixels are black.
RgbImage ColorMap(const cv::Mat& image, const ColorMapOptions& options = {});

}  // namespace rangebayes
