#include "stereo/matcher.h"

#include <cstdio>
#include <limits>

#include "core/error.h"

namespace rangebayes {

std::string DisparityResult::BriefReport() const {
  char line[160];
  std::snprintf(line, sizeof(line), "disparity: %dx%d, %.1f%% valid, matched in %.0f ms over %d frame(s)",
                disparity_px.cols, disparity_px.rows, 100.0 * valid_fraction, match_ms, frames_used);
  return line;
}

void DropAboveSigma(double max_sigma_px, DisparityResult* result) {
  RB_CHECK(max_sigma_px > 0, "DropAboveSigma: max_sigma_px must be > 0, got ", max_sigma_px);
  cv::Mat& d = result->disparity_px;
  cv::Mat& s = result->sigma_disparity_px;
  RB_CHECK(d.type() == CV_32F && s.type() == CV_32F && s.size() == d.size(),
           "DropAboveSigma: needs float disparity and sigma maps of one size");
  const float nan = std::numeric_limits<float>::quiet_NaN();
  int valid = 0;
  for (int y = 0; y < d.rows; ++y) {
    float* dr = d.ptr<float>(y);
    float* sr = s.ptr<float>(y);
    for (int x = 0; x < d.cols; ++x) {
      if (!(sr[x] <= max_sigma_px)) dr[x] = sr[x] = nan;  // a NaN σ_d has no measurement either
      if (dr[x] == dr[x]) ++valid;
    }
  }
  result->valid_fraction = d.total() > 0 ? static_cast<double>(valid) / static_cast<double>(d.total()) : 0.0;
}

std::string RangeEndAdvice() {
  return "part of the scene may lie outside that range; widen it with --num-disparities or --min-disparity";
}

}  // namespace rangebayes
