// The figure `rangebayes learn-prior` writes beside prior.yaml: a learned potential against the square root.
#pragma once

#include "bayes/spline_potential.h"
#include "core/image.h"

namespace rangebayes {

// 720×560 pixels. Top: φ_θ (blue, knots as dots) beside its square-root base (grey). Bottom: φ_θ − sqrt (blue)
// around zero (grey). A dashed red line at d = √2 (orthogonal normals); light grid lines every 0.25 in d.
// No text: the axes run d = 0..2 from left to right, each panel scaled to its own range.
RgbImage PlotPotential(const SplinePotential& learned);

}  // namespace rangebayes
