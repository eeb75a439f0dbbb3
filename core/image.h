// A plain 8-bit RGB image buffer, so that core/ and bayes/ can produce pictures without OpenCV.
#pragma once

#include <cstdint>
#include <vector>

namespace rangebayes {

// Row-major, 3 bytes per pixel (R, G, B), no padding.
struct RgbImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;

  RgbImage() = default;
  RgbImage(int w, int h, std::uint8_t fill = 255)
      : width(w), height(h), rgb(static_cast<size_t>(w) * h * 3, fill) {}
  std::uint8_t* at(int x, int y) { return rgb.data() + (static_cast<size_t>(y) * width + x) * 3; }
  const std::uint8_t* at(int x, int y) const {
    return rgb.data() + (static_cast<size_t>(y) * width + x) * 3;
  }
};

}  // namespace rangebayes
