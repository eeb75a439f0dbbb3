#include "stereo/matcher.h"

#include <cstdio>

namespace rangebayes {

std::string DisparityResult::BriefReport() const {
  char line[160];
  std::snprintf(line, sizeof(line), "disparity: %dx%d, %.1f%% valid, matched in %.0f ms over %d frame(s)",
                disparity_px.cols, disparity_px.rows, 100.0 * valid_fraction, match_ms, frames_used);
  return line;
}

std::string RangeEndAdvice() {
  return "part of the scene may lie outside that range; widen it with --num-disparities or --min-disparity";
}

}  // namespace rangebayes
