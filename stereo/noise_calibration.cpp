#include "stereo/noise_calibration.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include "core/error.h"
#include "stereo/matcher.h"
#include "stereo/rectify.h"
#include "stereo/sgbm_matcher.h"
#include "stereo/spacetime_matcher.h"

namespace rangebayes {

NoiseCalibrationMatcher ParseNoiseCalibrationMatcher(const std::string& name) {
  if (name == "block") return NoiseCalibrationMatcher::kBlock;
  if (name == "spacetime") return NoiseCalibrationMatcher::kSpaceTime;
  if (name == "sgbm") return NoiseCalibrationMatcher::kSgbm;
  RB_FAIL("noise calibration: matcher must be block, spacetime or sgbm, not '", name, "'");
}

const char* NoiseCalibrationMatcherName(NoiseCalibrationMatcher matcher) {
  switch (matcher) {
    case NoiseCalibrationMatcher::kBlock: return "block";
    case NoiseCalibrationMatcher::kSpaceTime: return "spacetime";
    case NoiseCalibrationMatcher::kSgbm: return "sgbm";
  }
  return "?";
}

void NoiseCalibrationOptions::Check() const {
  RB_CHECK(first_frame >= 0, "noise calibration: first_frame must be >= 0");
  RB_CHECK(frames >= 0, "noise calibration: frames must be >= 0");
  RB_CHECK(num_disparities >= 3 && num_disparities <= 1024, "noise calibration: num_disparities must be in [3, 1024]");
  RB_CHECK(window_px >= 1 && window_px <= 31, "noise calibration: window_px must be in [1, 31]");
  RB_CHECK(image_noise_gray > 0, "noise calibration: image_noise_gray must be > 0");
  RB_CHECK(stride_px >= 1 && stride_px <= 64, "noise calibration: stride_px must be in [1, 64]");
  if (form == NoiseForm::kFloorPlusScale) {
    RB_CHECK(matcher != NoiseCalibrationMatcher::kSgbm,
             "noise calibration: the floor-plus-scale form needs a matcher that predicts sigma_d (block or "
             "spacetime), not sgbm");
  }
}

namespace {

std::unique_ptr<StereoMatcher> MakeMatcher(const NoiseCalibrationOptions& o) {
  if (o.matcher == NoiseCalibrationMatcher::kSgbm) {
    SgbmMatcherOptions s;
    s.min_disparity_px = o.min_disparity_px;
    s.num_disparities = o.num_disparities;
    s.block_size_px = std::min(o.window_px, 11);
    return std::make_unique<SgbmMatcher>(s);
  }
  SpaceTimeMatcherOptions m;
  m.min_disparity_px = o.min_disparity_px;
  m.num_disparities = o.num_disparities;
  m.window_px = o.window_px;
  m.image_noise_gray = o.image_noise_gray;
  // The raw curvature prediction: the fit supplies floor and scale.
  m.sigma_floor_px = 0.0;
  m.sigma_scale = 1.0;
  m.max_sigma_disparity_px = 0.0;
  return std::make_unique<SpaceTimeMatcher>(m);
}

}  // namespace

DisparityNoiseModel CalibrateDisparityNoise(const Recording& recording, const StereoRig& rig,
                                            const NoiseCalibrationOptions& options,
                                            NoiseCalibrationSummary* summary) {
  options.Check();
  NoiseCalibrationSummary local;
  NoiseCalibrationSummary& s = summary != nullptr ? *summary : local;
  s = NoiseCalibrationSummary{};
  s.matcher = options.matcher;
  const int first = options.first_frame;
  RB_CHECK(first < recording.num_frames(), "noise calibration: frame ", first, " not in [0, ",
           recording.num_frames(), ")");
  int count = 1;
  if (options.matcher == NoiseCalibrationMatcher::kSpaceTime) {
    count = options.frames > 0 ? std::min(options.frames, recording.num_frames() - first)
                               : recording.num_frames() - first;
  }
  s.frames_used = count;
  const Rectifier rectifier(rig);
  std::vector<cv::Mat> left, right;
  for (int i = first; i < first + count; ++i) {
    const StereoFrame f = LoadRecordingFrame(recording, i);
    cv::Mat l, r;
    rectifier.Rectify(f.left, f.right, &l, &r);
    left.push_back(l);
    right.push_back(r);
  }
  const DisparityResult match = MakeMatcher(options)->Match(left, right);
  s.valid_fraction = match.valid_fraction;

  ObservationSelection selection;
  selection.roi = options.roi;
  selection.stride_px = options.stride_px;
  const std::vector<DisparityObservation> obs =
      ObservationsFromDisparity(match.disparity_px, match.sigma_disparity_px, selection);
  s.observations = static_cast<int>(obs.size());
  DisparityGeometry geometry;
  geometry.camera = rectifier.intrinsics();
  geometry.baseline_m = rectifier.baseline_m();
  geometry.doffs_px = rectifier.doffs_px();
  s.samples = PlaneDisparityResiduals(obs, geometry, {}, &s.plane);

  const bool has_pred = !match.sigma_disparity_px.empty();
  NoiseFitOptions fit_options;
  fit_options.form = options.form.value_or(has_pred ? NoiseForm::kFloorPlusScale : NoiseForm::kConstant);
  RB_CHECK(fit_options.form != NoiseForm::kFloorPlusScale || has_pred,
           "noise calibration: the floor-plus-scale form needs a matcher that predicts sigma_d");
  // SGBM reports disparities in 1/16 px steps: its error cannot be resolved below the step's own σ.
  if (options.matcher == NoiseCalibrationMatcher::kSgbm) fit_options.min_sigma_px = 1.0 / 16.0 / std::sqrt(12.0);
  DisparityNoiseModel model = FitDisparityNoiseModel(s.samples, fit_options, &s.fit);
  s.outlier_fraction = fit_options.form == NoiseForm::kConstant ? s.fit.outlier_fraction : model.outlier_fraction;
  model.matcher = NoiseCalibrationMatcherName(options.matcher);
  if (options.matcher != NoiseCalibrationMatcher::kSgbm) model.image_noise_gray = options.image_noise_gray;
  return model;
}

std::string NoiseCalibrationSummary::BriefReport(const DisparityNoiseModel& model) const {
  std::string out;
  char line[512];
  std::snprintf(line, sizeof(line), "matcher %s over %d frame(s): %d valid disparities (%.1f%%)\n",
                NoiseCalibrationMatcherName(matcher), frames_used, observations, 100.0 * valid_fraction);
  out += line;
  std::snprintf(line, sizeof(line),
                "plane: normal (%.4f, %.4f, %.4f), offset %.4f m; RANSAC %d of %d inliers, least-squares %d "
                "inliers, inlier RMS %.3f px\n",
                plane.plane[0], plane.plane[1], plane.plane[2], plane.plane[3], plane.ransac_inliers,
                plane.observations, plane.inliers, plane.inlier_rms_px);
  out += line;
  std::snprintf(line, sizeof(line), "constant sigma_d %.4f px (robust 1.4826*MAD %.4f px), outlier fraction %.3f\n",
                fit.constant_sigma_px, fit.robust_sigma_px, outlier_fraction);
  out += line;
  if (model.form == NoiseForm::kFloorPlusScale) {
    std::snprintf(line, sizeof(line),
                  "floor-plus-scale: sigma_d = sqrt(%.4f^2 + (%.3f * sigma_pred)^2), outlier fraction %.3f\n",
                  model.floor_px, model.scale, model.outlier_fraction);
    out += line;
  }
  out += "sigma_d by depth:";
  for (const NoiseDepthBin& b : fit.depth_bins) {
    std::snprintf(line, sizeof(line), " %.3f m: %.4f px;", b.depth_m, b.sigma_px);
    out += line;
  }
  std::snprintf(line, sizeof(line), " slope %.4f px/m\n", fit.depth_slope_px_per_m);
  out += line;
  return out;
}

}  // namespace rangebayes
