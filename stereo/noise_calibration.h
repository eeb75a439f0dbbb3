// Calibration of the disparity noise model (what `rangebayes calibrate noise` runs): match frames of a recording
// of a known plane, fit the plane, and fit σ_d to the disparity residuals about it (calibration/plane_target.h,
// calibration/disparity_noise_model.h; docs/design.md, the noise model).
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "calibration/disparity_noise_model.h"
#include "calibration/plane_target.h"
#include "calibration/stereo_rig.h"
#include "capture/recording.h"
#include "core/progress.h"
#include "stereo/disparity_io.h"

namespace rangebayes {

enum class NoiseCalibrationMatcher {
  kBlock,      // our block matcher on one frame; predicts σ_d
  kSpaceTime,  // our space-time matcher over frames first_frame.. (a static scene); predicts σ_d
  kSgbm,       // OpenCV SGBM on one frame; no prediction (constant form only)
};
NoiseCalibrationMatcher ParseNoiseCalibrationMatcher(const std::string& name);  // block | spacetime | sgbm
const char* NoiseCalibrationMatcherName(NoiseCalibrationMatcher matcher);

struct NoiseCalibrationOptions {
  NoiseCalibrationMatcher matcher = NoiseCalibrationMatcher::kBlock;
  std::optional<NoiseForm> form;  // empty: floor-plus-scale when the matcher predicts σ_d, else constant
  int first_frame = 0;            // index into frames.csv; ≥ 0
  int frames = 0;                 // space-time: frames from first_frame (0: all); ≥ 0
  int min_disparity_px = 0;
  int num_disparities = 64;       // [3, 1024]
  // Odd, [1, 31]; 0: the window the matcher's command uses (block 5; spacetime 7 below 16 frames, else 5, as
  // `spacetime`; sgbm 5). SGBM uses at most 11.
  int window_px = 0;
  double image_noise_gray = 2.0;  // σ_n for the predicted σ_d (grey levels); > 0
  cv::Rect roi;                   // the target in the rectified left image (px); empty: the whole image
  int stride_px = 1;              // every n-th pixel in x and y; [1, 64]
  void Check() const;             // throws Error naming the field
};

struct NoiseCalibrationSummary {
  NoiseCalibrationMatcher matcher = NoiseCalibrationMatcher::kBlock;
  int frames_used = 0;
  int observations = 0;             // valid disparities used
  double valid_fraction = 0.0;      // of the matched pixels
  PlaneTargetSummary plane;
  NoiseFitSummary fit;
  double outlier_fraction = 0.0;    // of the returned model's fit
  std::vector<NoiseSample> samples;  // the residuals the model was fitted to (for NoiseReportFigure)
  // Warnings for the caller to show (the CLI as notes, Python as UserWarnings): a plane that most disparities miss.
  std::vector<std::string> notices;

  // Matcher and valid pixels, the plane, the constant and the fitted model, σ_d by depth, one per line.
  std::string BriefReport(const DisparityNoiseModel& model) const;
};

// Throws Error on a frame outside the recording, a form the matcher cannot support, or too few samples.
DisparityNoiseModel CalibrateDisparityNoise(const Recording& recording, const StereoRig& rig,
                                            const NoiseCalibrationOptions& options,
                                            NoiseCalibrationSummary* summary = nullptr);

// Calibration from scenes with ground-truth disparity (Middlebury layouts, stereo/disparity_io.h): the matcher runs
// as `rangebayes stereo` runs it (its defaults, the scene's search range rounded up to 16), and the learned form
// (σ_d from the cost curvature and the neighbour jump, plus the outlier share) is fitted to d − d_gt on the
// non-occluded pixels with finite ground truth (all finite ones where the scene has no mask).
struct GroundTruthNoiseOptions {
  NoiseCalibrationMatcher matcher = NoiseCalibrationMatcher::kSgbm;  // sgbm or block (one frame per scene)
  int window_px = 5;              // odd, 1–31: the features' SSD window (and the block matcher's window)
  double image_noise_gray = 2.0;  // > 0: σ_n of the features
  int stride_px = 1;              // 1–64: every n-th pixel in x and y (the fit thins to max_samples)
  int max_samples = 200000;       // ≥ 1000: the fit thins larger sets by a regular stride
  // Before each scene (stage "scene NAME (k of n)", the share of scenes done), then the fit's (NoiseFitOptions).
  ProgressCallback progress;
  void Check() const;
};

// The residual samples of one scene (residual, σ_pred, jump; depth NaN), against the ground truth with its
// quantisation steps fitted out where it is stored in whole steps (RemoveQuantisationSteps, stereo/evaluate.h).
// Throws Error naming the folder when the scene has no ground truth or no pixel where both the ground truth and the
// matcher give a disparity.
std::vector<NoiseSample> GroundTruthNoiseSamples(const MiddleburyScene& scene, const GroundTruthNoiseOptions& options);

struct GroundTruthNoiseSummary {
  int scenes = 0;
  int samples = 0;
  int width_min_px = 0, width_max_px = 0;
  NoiseFitSummary fit;
  std::string BriefReport(const DisparityNoiseModel& model) const;  // scenes, samples, the model, one per line
};

// Throws Error on an empty list or any bad scene (GroundTruthNoiseSamples).
DisparityNoiseModel CalibrateDisparityNoiseFromGroundTruth(const std::vector<std::string>& scene_folders,
                                                           const GroundTruthNoiseOptions& options,
                                                           GroundTruthNoiseSummary* summary = nullptr);

// The calibration test of a model on scenes with ground truth (CheckNoiseModel on their samples); the model must
// apply to each scene's matcher and width (DisparityNoiseModel::CheckApplicable).
NoiseModelCheck CheckDisparityNoiseOnGroundTruth(const DisparityNoiseModel& model,
                                                 const std::vector<std::string>& scene_folders, int stride_px = 2,
                                                 const ProgressCallback& progress = {});

}  // namespace rangebayes
