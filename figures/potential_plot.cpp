#include "figures/potential_plot.h"

#include <algorithm>
#include <cmath>

#include "figures/draw.h"

namespace rangebayes {

RgbImage PlotPotential(const SplinePotential& learned) {
  const int width = 720, height = 560, margin = 30;
  RgbImage image(width, height, 255);
  const Rgb grey = {150, 150, 150}, blue = {20, 70, 200}, red = {210, 40, 40}, black = {0, 0, 0},
            light = {225, 225, 225};
  const int top_height = 340, bottom_top = 380, bottom_height = height - margin - bottom_top;
  const double x_scale = (width - 2.0 * margin) / 2.0;
  double y_max = 0, residual_max = 1e-3;
  for (double d = 0; d <= 2.0; d += 0.005) {
    y_max = std::max({y_max, learned.Value(d), learned.Base(d)});
    residual_max = std::max(residual_max, std::abs(learned.Value(d) - learned.Base(d)));
  }
  auto px = [&](double d) { return margin + d * x_scale; };
  auto top_y = [&](double v) { return margin + top_height - v / y_max * (top_height - 10); };
  auto bottom_y = [&](double v) {
    return bottom_top + bottom_height / 2.0 - v / residual_max * (bottom_height / 2.0 - 5);
  };
  for (int i = 0; i <= 8; ++i) DrawLine(&image, px(0.25 * i), margin, px(0.25 * i), height - margin, light);
  DrawLine(&image, px(0), top_y(0), px(2), top_y(0), black);
  DrawLine(&image, px(0), margin, px(0), top_y(0), black);
  DrawLine(&image, px(0), bottom_y(0), px(2), bottom_y(0), grey);
  DrawLine(&image, px(0), bottom_top, px(0), height - margin, black);
  for (double y = margin; y < height - margin; y += 12)
    DrawLine(&image, px(std::sqrt(2.0)), y, px(std::sqrt(2.0)), y + 5, red);
  const double step = 0.005;
  for (double d = 0; d + step <= 2.0 + 1e-9; d += step) {
    DrawLine(&image, px(d), top_y(learned.Base(d)), px(d + step), top_y(learned.Base(d + step)), grey);
  }
  for (double d = 0; d + step <= 2.0 + 1e-9; d += step) {
    DrawLine(&image, px(d), top_y(learned.Value(d)), px(d + step), top_y(learned.Value(d + step)), blue);
    DrawLine(&image, px(d), bottom_y(learned.Value(d) - learned.Base(d)), px(d + step),
             bottom_y(learned.Value(d + step) - learned.Base(d + step)), blue);
  }
  for (int j = 0; j < learned.num_knots(); ++j) {
    const double x = px(learned.KnotPosition(j)), y = top_y(learned.theta()[j]);
    for (int a = -3; a <= 3; ++a) DrawLine(&image, x - 3, y + a, x + 3, y + a, blue);
  }
  return image;
}

}  // namespace rangebayes
