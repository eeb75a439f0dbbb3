// The picture `rangebayes calibrate noise --png` writes: how well the fitted disparity noise model explains the
// residuals about the target.
#pragma once

#include <vector>

#include "calibration/disparity_noise_model.h"
#include "core/image.h"

namespace rangebayes {

// 960×360 pixels. Left: histogram of the residuals (grey) against the fitted model's density (red: the chosen
// form, blue: the constant form). Right: σ_d fitted per depth bin (dots) against depth, the constant fit (blue
// line) and the least-squares line (red).
RgbImage NoiseReportFigure(const std::vector<NoiseSample>& samples, const DisparityNoiseModel& model,
                           const NoiseFitSummary& fit);

}  // namespace rangebayes
