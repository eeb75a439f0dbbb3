#include "figures/draw.h"

#include <algorithm>
#include <cmath>

namespace rangebayes {

void DrawLine(RgbImage* image, double x0, double y0, double x1, double y1, const Rgb& colour) {
  const int steps = static_cast<int>(std::max(std::abs(x1 - x0), std::abs(y1 - y0))) + 1;
  for (int i = 0; i <= steps; ++i) {
    const double t = static_cast<double>(i) / steps;
    const int x = static_cast<int>(std::lround(x0 + t * (x1 - x0)));
    const int y = static_cast<int>(std::lround(y0 + t * (y1 - y0)));
    for (int dx = 0; dx <= 1; ++dx) {
      for (int dy = 0; dy <= 1; ++dy) {
        if (x + dx < 0 || y + dy < 0 || x + dx >= image->width || y + dy >= image->height) continue;
        std::copy(colour.begin(), colour.end(), image->at(x + dx, y + dy));
      }
    }
  }
}

}  // namespace rangebayes
