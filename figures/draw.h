// Raster primitives for the project's figures (PNG plots written by the CLI): no text, no anti-aliasing.
#pragma once

#include <array>
#include <cstddef>  // core/image.h uses size_t without including it
#include <cstdint>

#include "core/image.h"

namespace rangebayes {

using Rgb = std::array<std::uint8_t, 3>;

// A straight line from (x0, y0) to (x1, y1) in pixels, 2 pixels thick; parts outside the image are clipped.
void DrawLine(RgbImage* image, double x0, double y0, double x1, double y1, const Rgb& colour);

}  // namespace rangebayes
