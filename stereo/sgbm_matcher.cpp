#include "stereo/sgbm_matcher.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <opencv2/calib3d.hpp>

#include "core/error.h"

namespace rangebayes {

void CheckStereoSequence(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right) {
  RB_CHECK(!left.empty(), "no stereo frames given");
  RB_CHECK(left.size() == right.size(), "left has ", left.size(), " frames but right has ", right.size());
  const cv::Size size = left[0].size();
  const int type = left[0].type();
  for (size_t i = 0; i < left.size(); ++i) {
    RB_CHECK(!left[i].empty() && !right[i].empty(), "frame ", i, ": empty image");
    RB_CHECK(left[i].size() == size && right[i].size() == size, "frame ", i, ": image sizes differ (left ",
             left[i].cols, "x", left[i].rows, ", right ", right[i].cols, "x", right[i].rows, ", frame 0 ",
             size.width, "x", size.height, ")");
    RB_CHECK(left[i].type() == type && right[i].type() == type, "frame ", i, ": image types differ");
    RB_CHECK(left[i].depth() == CV_8U || left[i].depth() == CV_16U, "frame ", i,
             ": images must be 8- or 16-bit");
    RB_CHECK(left[i].channels() == 1 || left[i].channels() == 3, "frame ", i, ": images must have 1 or 3 channels");
  }
}

void SgbmMatcherOptions::Check() const {
  RB_CHECK(num_disparities >= 1 && num_disparities <= 1024, "num_disparities ", num_disparities,
           " is outside 1–1024");
  RB_CHECK(block_size_px >= 1 && block_size_px <= kSgbmMaxBlockSizePx && block_size_px % 2 == 1, "block_size_px ",
           block_size_px, " must be odd and in 1–", kSgbmMaxBlockSizePx);
  RB_CHECK(p1 >= 0 && p2 >= 0 && (p2 == 0 || p2 > p1), "SGBM penalties p1 ", p1, ", p2 ", p2,
           " must satisfy 0 ≤ p1 < p2");
  RB_CHECK(uniqueness_ratio_pct >= 0 && uniqueness_ratio_pct <= 100, "uniqueness_ratio_pct ",
           uniqueness_ratio_pct, " is outside 0–100");
  RB_CHECK(speckle_window_px >= 0 && speckle_range_px >= 0, "speckle parameters must be ≥ 0");
  RB_CHECK(pre_filter_cap >= 1 && pre_filter_cap <= 63, "pre_filter_cap ", pre_filter_cap, " is outside 1–63");
}

SgbmMatcher::SgbmMatcher(const SgbmMatcherOptions& options) : options_(options) { options_.Check(); }

cv::Mat FixedPointDisparityToFloat(const cv::Mat& disparity16, int min_disparity_px) {
  RB_CHECK(disparity16.type() == CV_16S, "fixed-point disparity must be CV_16S");
  cv::Mat out(disparity16.size(), CV_32F);
  // The lower end itself is no measurement either: SGBM interpolates no sub-pixel offset there, and a winner at
  // exactly min_disparity is a tie (a textureless region, where every disparity costs the same: a uniform pair came
  // out 91% valid, one fake plane) or a match beyond the range.
  const int invalid_up_to = min_disparity_px * 16;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int y = 0; y < disparity16.rows; ++y) {
    const short* in = disparity16.ptr<short>(y);
    float* o = out.ptr<float>(y);
    for (int x = 0; x < disparity16.cols; ++x) {
      o[x] = in[x] <= invalid_up_to ? nan : static_cast<float>(in[x] * kSgbmDisparityStepPx);
    }
  }
  return out;
}

DisparityResult SgbmMatcher::Match(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right) {
  CheckStereoSequence(left, right);
  const auto start = std::chrono::steady_clock::now();
  cv::Mat l = left[0], r = right[0];
  if (l.depth() == CV_16U) {
    // SGBM takes 8-bit only; keep the top 8 significant bits of the frame's range.
    double lo = 0, hi = 0;
    cv::minMaxLoc(l, &lo, &hi);
    const double scale = hi > lo ? 255.0 / (hi - lo) : 1.0;
    l.convertTo(l, CV_8U, scale, -lo * scale);
    r.convertTo(r, CV_8U, scale, -lo * scale);
  }
  const int cn = l.channels();
  const int bs = options_.block_size_px;
  const int num = (options_.num_disparities + 15) / 16 * 16;
  // SGBM matches only columns whose whole search range lies inside the image; OpenCV 4.6 aborts the process (an
  // exception from a destructor) on an image with no such column instead of throwing.
  const int need_px = std::max(options_.min_disparity_px + num, 0) - std::min(options_.min_disparity_px, 0);
  RB_CHECK(l.cols > need_px, "the image is ", l.cols,
           " px wide, which leaves no column to match: SGBM needs more than ", need_px, " px (min disparity ",
           options_.min_disparity_px, ", ", num,
           " disparities searched); search fewer disparities or use wider images");
  const int p1 = options_.p1 > 0 ? options_.p1 : 8 * cn * bs * bs;
  const int p2 = options_.p2 > 0 ? options_.p2 : 32 * cn * bs * bs;
  auto sgbm = cv::StereoSGBM::create(options_.min_disparity_px, num, bs, p1, std::max(p2, p1 + 1),
                                     options_.left_right_max_diff_px, options_.pre_filter_cap,
                                     options_.uniqueness_ratio_pct, options_.speckle_window_px,
                                     options_.speckle_range_px,
                                     options_.three_way ? cv::StereoSGBM::MODE_SGBM_3WAY : cv::StereoSGBM::MODE_SGBM);
  cv::Mat disparity16;
  sgbm->compute(l, r, disparity16);
  DisparityResult result;
  result.disparity_px = FixedPointDisparityToFloat(disparity16, options_.min_disparity_px);
  result.frames_used = 1;
  if (num != options_.num_disparities) result.num_disparities_searched = num;
  result.match_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  const cv::Mat valid = result.disparity_px == result.disparity_px;
  result.valid_fraction = static_cast<double>(cv::countNonZero(valid)) / static_cast<double>(valid.total());
  // SGBM interpolates no sub-pixel offset at the ends of its range: a winner there is exactly the end's value. The
  // lower end counts only above 0 (nothing lies beyond disparity 0, the far end of a scene).
  cv::Mat at_end = disparity16 == 16 * (options_.min_disparity_px + num - 1);
  if (options_.min_disparity_px > 0) at_end |= disparity16 == 16 * options_.min_disparity_px;
  result.range_end_fraction = static_cast<double>(cv::countNonZero(at_end)) / static_cast<double>(at_end.total());
  return result;
}

}  // namespace rangebayes
