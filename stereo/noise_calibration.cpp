#include "stereo/noise_calibration.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "core/error.h"
#include "stereo/disparity_features.h"
#include "stereo/evaluate.h"
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
  RB_CHECK(window_px == 0 || (window_px >= 1 && window_px <= 31),
           "noise calibration: window_px must be in [1, 31] "
           "(0: the matcher's)");
  RB_CHECK(image_noise_gray > 0, "noise calibration: image_noise_gray must be > 0");
  RB_CHECK(stride_px >= 1 && stride_px <= 64, "noise calibration: stride_px must be in [1, 64]");
  RB_CHECK(form != NoiseForm::kLearned,
           "noise calibration: the learned form is fitted from scenes with ground-truth disparity, not a plane");
  if (form == NoiseForm::kFloorPlusScale) {
    RB_CHECK(matcher != NoiseCalibrationMatcher::kSgbm,
             "noise calibration: the floor-plus-scale form needs a matcher that predicts sigma_d (block or "
             "spacetime), not sgbm");
  }
}

namespace {

// Under this share of the disparities on the fitted plane, the model describes mismatches, not the matcher's noise.
constexpr double kMinPlaneInlierShare = 0.7;

// The matcher as its command runs it (`stereo --matcher sgbm` / `block`, `spacetime` over `frames` frames), so
// that the model fits the disparities that command will produce: the space-time preset's Gauss–Newton step and
// window, not the plain block matcher's parabola (whose bias the fit took for a floor, 1.4× too wide σ_d after).
std::unique_ptr<StereoMatcher> MakeMatcher(const NoiseCalibrationOptions& o, int frames) {
  if (o.matcher == NoiseCalibrationMatcher::kSgbm) {
    SgbmMatcherOptions s;
    s.min_disparity_px = o.min_disparity_px;
    s.num_disparities = o.num_disparities;
    s.block_size_px = std::min(o.window_px > 0 ? o.window_px : 5, kSgbmMaxBlockSizePx);
    return std::make_unique<SgbmMatcher>(s);
  }
  SpaceTimeMatcherOptions m = o.matcher == NoiseCalibrationMatcher::kSpaceTime ? SpaceTimeStaticSceneOptions(frames)
                                                                               : SpaceTimeMatcherOptions{};
  m.min_disparity_px = o.min_disparity_px;
  m.num_disparities = o.num_disparities;
  if (o.window_px > 0) m.window_px = o.window_px;
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
    // As `spacetime` does: a window beyond the recording is an error, not a shorter window without a word.
    RB_CHECK(options.frames <= recording.num_frames() - first, "noise calibration: frames ", first, "..",
             first + options.frames - 1, " requested but the recording has ", recording.num_frames());
    count = options.frames > 0 ? options.frames : recording.num_frames() - first;
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
  const DisparityResult match = MakeMatcher(options, count)->Match(left, right);
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
  // A plane that most pixels miss: a search range beside the plane's disparities (the model of a fit to mismatches
  // was written without a word, σ 20x the true one) or a target that is not one plane.
  if (s.plane.ransac_inliers < kMinPlaneInlierShare * s.plane.observations) {
    s.notices.push_back(StrCat("warning: only ", s.plane.ransac_inliers, " of ", s.plane.observations,
                               " disparities lie on the fitted plane: check that the disparity search range (",
                               options.min_disparity_px, " + ", options.num_disparities,
                               ") covers the plane and that the recording shows one plane"));
  }

  const bool has_pred = !match.sigma_disparity_px.empty();
  NoiseFitOptions fit_options;
  fit_options.form = options.form.value_or(has_pred ? NoiseForm::kFloorPlusScale : NoiseForm::kConstant);
  RB_CHECK(fit_options.form != NoiseForm::kFloorPlusScale || has_pred,
           "noise calibration: the floor-plus-scale form needs a matcher that predicts sigma_d");
  if (options.matcher == NoiseCalibrationMatcher::kSgbm) fit_options.quantisation_step_px = kSgbmDisparityStepPx;
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
  // With SGBM the σ includes the rounding to its 1/16-px steps, as the file does (NoiseFitOptions).
  std::snprintf(line, sizeof(line), "constant sigma_d %.4f px%s (robust 1.4826*MAD %.4f px), outlier fraction %.3f\n",
                fit.constant_sigma_px, matcher == NoiseCalibrationMatcher::kSgbm ? " with SGBM's 1/16-px rounding" : "",
                fit.robust_sigma_px, outlier_fraction);
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
  if (std::isfinite(fit.depth_slope_px_per_m)) {
    std::snprintf(line, sizeof(line), " slope %.4f px/m\n", fit.depth_slope_px_per_m);
    out += line;
  } else {
    out += " slope n/a (the plane spans under 2% of its depth)\n";
  }
  return out;
}

void GroundTruthNoiseOptions::Check() const {
  RB_CHECK(matcher == NoiseCalibrationMatcher::kSgbm || matcher == NoiseCalibrationMatcher::kBlock,
           "noise calibration from ground truth: matcher must be sgbm or block (one frame per scene)");
  RB_CHECK(window_px >= 1 && window_px <= 31 && window_px % 2 == 1, "noise calibration: window_px must be odd, 1-31");
  RB_CHECK(image_noise_gray > 0, "noise calibration: image_noise_gray must be > 0");
  RB_CHECK(stride_px >= 1 && stride_px <= 64, "noise calibration: stride_px must be in [1, 64]");
  RB_CHECK(max_samples >= 1000, "noise calibration: max_samples must be at least 1000");
}

std::vector<NoiseSample> GroundTruthNoiseSamples(const MiddleburyScene& scene, const GroundTruthNoiseOptions& options) {
  options.Check();
  RB_CHECK(!scene.gt_disparity_px.empty(), scene.folder, ": scene has no ground-truth disparity");
  const int ndisp = std::max(16, (scene.num_disparities + 15) / 16 * 16);
  std::unique_ptr<StereoMatcher> matcher;
  if (options.matcher == NoiseCalibrationMatcher::kSgbm) {
    SgbmMatcherOptions s;
    s.num_disparities = ndisp;
    matcher = std::make_unique<SgbmMatcher>(s);
  } else {
    SpaceTimeMatcherOptions m;
    m.num_disparities = ndisp;
    m.window_px = options.window_px;
    m.image_noise_gray = options.image_noise_gray;
    matcher = std::make_unique<SpaceTimeMatcher>(m);
  }
  const DisparityResult match = matcher->Match({scene.left}, {scene.right});
  DisparityFeatureOptions fo;
  fo.window_px = options.window_px;
  fo.image_noise_gray = options.image_noise_gray;
  const DisparityFeatures f = ComputeDisparityFeatures({scene.left}, {scene.right}, match.disparity_px, fo);
  // A ground truth stored in whole steps (stereo/evaluate.h) has them fitted out first: residuals against the
  // stored values would carry its rounding, up to half a step.
  const cv::Mat truth = GroundTruthWithoutSteps(scene.gt_disparity_px);
  std::vector<NoiseSample> samples;
  int gt_valid = 0;
  for (int y = 0; y < match.disparity_px.rows; y += options.stride_px) {
    for (int x = 0; x < match.disparity_px.cols; x += options.stride_px) {
      const float gt = truth.at<float>(y, x);
      if (!std::isfinite(gt) || gt <= 0) continue;
      if (!scene.mask_nonocc.empty() && scene.mask_nonocc.at<unsigned char>(y, x) != 255) continue;
      ++gt_valid;
      const float d = match.disparity_px.at<float>(y, x);
      if (!std::isfinite(d)) continue;
      NoiseSample s;
      s.residual_px = d - gt;
      s.sigma_pred_px = f.sigma_pred_px.at<float>(y, x);
      s.jump_px = f.jump_px.at<float>(y, x);
      s.depth_m = std::numeric_limits<double>::quiet_NaN();
      samples.push_back(s);
    }
  }
  RB_CHECK(gt_valid > 0, scene.folder, ": no pixel with a finite, positive ground-truth disparity",
           scene.mask_nonocc.empty() ? "" : " in the non-occluded mask");
  RB_CHECK(!samples.empty(), scene.folder, ": the matcher gives no disparity where the ground truth has one");
  return samples;
}

namespace {
// Stage "scene NAME (k of n)" before scene k of `folders` (0-based), with the share of scenes done.
void ReportScene(const ProgressCallback& progress, const std::vector<std::string>& folders, size_t k) {
  if (!progress) return;
  const std::string name = std::filesystem::path(folders[k]).lexically_normal().filename().string();
  progress(static_cast<double>(k) / static_cast<double>(folders.size()), "scene " + (name.empty() ? folders[k] : name) +
                                                                             " (" + std::to_string(k + 1) + " of " +
                                                                             std::to_string(folders.size()) + ")");
}
}  // namespace

DisparityNoiseModel CalibrateDisparityNoiseFromGroundTruth(const std::vector<std::string>& scene_folders,
                                                           const GroundTruthNoiseOptions& options,
                                                           GroundTruthNoiseSummary* summary) {
  options.Check();
  RB_CHECK(!scene_folders.empty(), "noise calibration: no scene with ground truth given");
  GroundTruthNoiseSummary local;
  GroundTruthNoiseSummary& s = summary != nullptr ? *summary : local;
  s = GroundTruthNoiseSummary{};
  std::vector<NoiseSample> all;
  for (size_t k = 0; k < scene_folders.size(); ++k) {
    ReportScene(options.progress, scene_folders, k);
    const MiddleburyScene scene = ReadMiddleburyScene(scene_folders[k]);
    const std::vector<NoiseSample> samples = GroundTruthNoiseSamples(scene, options);
    all.insert(all.end(), samples.begin(), samples.end());
    const int w = scene.left.cols;
    s.width_min_px = s.scenes == 0 ? w : std::min(s.width_min_px, w);
    s.width_max_px = std::max(s.width_max_px, w);
    ++s.scenes;
  }
  s.samples = static_cast<int>(all.size());
  NoiseFitOptions fit;
  fit.form = NoiseForm::kLearned;
  fit.max_samples = options.max_samples;
  fit.depth_bins = 1;
  if (options.matcher == NoiseCalibrationMatcher::kSgbm) fit.quantisation_step_px = kSgbmDisparityStepPx;
  fit.progress = options.progress;
  if (options.progress) options.progress(0.0, "fit");
  DisparityNoiseModel model = FitDisparityNoiseModel(all, fit, &s.fit);
  model.matcher = NoiseCalibrationMatcherName(options.matcher);
  model.image_noise_gray = options.image_noise_gray;
  model.window_px = options.window_px;
  model.width_min_px = s.width_min_px;
  model.width_max_px = s.width_max_px;
  model.depth_slope_px_per_m = std::numeric_limits<double>::quiet_NaN();
  return model;
}

NoiseModelCheck CheckDisparityNoiseOnGroundTruth(const DisparityNoiseModel& model,
                                                 const std::vector<std::string>& scene_folders, int stride_px,
                                                 const ProgressCallback& progress) {
  RB_CHECK(model.form == NoiseForm::kLearned, "noise check: the model's form is '", NoiseFormName(model.form),
           "'; only a learned model can be checked on ground truth");
  RB_CHECK(!scene_folders.empty(), "noise check: no scene with ground truth given");
  GroundTruthNoiseOptions options;
  options.matcher = ParseNoiseCalibrationMatcher(model.matcher);
  options.window_px = model.window_px;
  if (model.image_noise_gray > 0) options.image_noise_gray = model.image_noise_gray;
  options.stride_px = stride_px;
  std::vector<NoiseSample> all;
  for (size_t k = 0; k < scene_folders.size(); ++k) {
    ReportScene(progress, scene_folders, k);
    const std::string& folder = scene_folders[k];
    const MiddleburyScene scene = ReadMiddleburyScene(folder);
    model.CheckApplicable(model.matcher, scene.left.cols, folder);
    const std::vector<NoiseSample> samples = GroundTruthNoiseSamples(scene, options);
    all.insert(all.end(), samples.begin(), samples.end());
  }
  double range = 0;
  for (const NoiseSample& x : all) range = std::max(range, std::abs(x.residual_px));
  return CheckNoiseModel(all, model, range);
}

std::string GroundTruthNoiseSummary::BriefReport(const DisparityNoiseModel& model) const {
  char line[512];
  std::string out;
  std::snprintf(line, sizeof(line), "ground truth: %d scene(s), %d px wide (min) to %d px (max), %d residuals\n",
                scenes, width_min_px, width_max_px, samples);
  out += line;
  std::snprintf(line, sizeof(line), "constant sigma_d %.4f px (robust 1.4826*MAD %.4f px)\n", fit.constant_sigma_px,
                fit.robust_sigma_px);
  out += line;
  std::snprintf(line, sizeof(line),
                "learned (%s): sigma_d = sqrt(%.4f^2 + (%.3f * sigma_pred)^2 + (%.3f * jump)^2), outlier share "
                "%.4f, log-likelihood %.1f\n",
                model.matcher.c_str(), model.floor_px, model.scale, model.jump_scale, model.outlier_fraction,
                fit.log_likelihood);
  out += line;
  return out;
}

}  // namespace rangebayes
