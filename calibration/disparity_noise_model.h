// The disparity-noise model of docs/design.md §2 (σ_d of a disparity measurement, pixels), its YAML file (noise.yaml,
// OpenCV FileStorage) and its maximum-likelihood fit from residuals about a known target.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "core/progress.h"

namespace rangebayes {

enum class NoiseForm {
  kConstant,        // σ_d = sigma_px for every pixel
  kFloorPlusScale,  // σ_d = sqrt(floor_px² + (scale · σ_pred)²), σ_pred the matcher's predicted σ_d
  // σ_d = sqrt(floor_px² + (scale · σ_pred)² + (jump_scale · jump)²): σ_pred the cost-curvature σ_d at the
  // chosen disparity (stereo/disparity_features.h), jump the largest disparity step to a 4-neighbour (px).
  // Fitted from ground-truth disparity, per matcher, for images of a stated width range.
  kLearned,
};

struct DisparityNoiseModel {
  NoiseForm form = NoiseForm::kConstant;
  double sigma_px = 0.5;   // constant form; > 0
  double floor_px = 0.15;  // floor-plus-scale form; ≥ 0
  double scale = 2.0;      // floor-plus-scale and learned forms (k); ≥ 0
  double jump_scale = 0.0;  // learned form: weight of the neighbour jump; ≥ 0

  // Provenance, written to and read from noise.yaml (informational).
  std::string matcher;                    // e.g. "sgbm", "block", "spacetime"
  int samples = 0;                        // residuals the fit used
  double outlier_fraction = 0.0;          // mixture weight of the uniform outlier component
  // Slope of σ_d (constant form, per depth bin) against depth; NaN: not measured (ground-truth fits, a plane at
  // one depth), and then absent from noise.yaml.
  double depth_slope_px_per_m = std::numeric_limits<double>::quiet_NaN();
  // σ_pred scales with the image noise σ_n the matcher assumed; the fit's σ_n (0: unknown) lets a user of the
  // model with another σ_n rescale: scale' = scale · fit σ_n / own σ_n.
  double image_noise_gray = 0.0;
  // Widths (px) of the images the model was fitted on (0: not recorded; required for the learned form) and the
  // matcher window used for the learned form's σ_pred (px, odd; 0: not recorded).
  int width_min_px = 0;
  int width_max_px = 0;
  int window_px = 0;

  // σ_d in pixels for a pixel whose matcher predicted σ_pred (pixels) and whose largest neighbour jump is
  // jump_px. The constant form ignores both, floor-plus-scale ignores the jump; both non-constant forms return
  // NaN for a non-finite σ_pred (no prediction: the caller decides).
  double Apply(double sigma_pred_px, double jump_px = 0.0) const;
  void Check() const;
  // Throws Error unless the model may be used for `matcher` on images `width_px` wide: a model that names a
  // matcher must name this one; a learned model must have been fitted on widths within 25% of width_px.
  // `what` names the file in the message.
  void CheckApplicable(const std::string& matcher_name, int width_px, const std::string& what) const;
};

// Throws Error naming the file and the field on a missing file or a malformed/missing field.
DisparityNoiseModel ReadDisparityNoiseModel(const std::string& path);
void WriteDisparityNoiseModel(const DisparityNoiseModel& model, const std::string& path);
NoiseForm ParseNoiseForm(const std::string& name);  // "constant" | "floor-plus-scale" | "learned"; throws otherwise
const char* NoiseFormName(NoiseForm form);

// One disparity residual about the target: measured − target disparity along the pixel's ray (pixels),
// the matcher's predicted σ_d (NaN when it has none) and the depth (metres, for the depth check).
struct NoiseSample {
  double residual_px = 0.0;
  double sigma_pred_px = 0.0;
  double depth_m = 0.0;
  double jump_px = 0.0;  // learned form: the largest disparity step to a 4-neighbour (px)
};

struct NoiseFitOptions {
  NoiseForm form = NoiseForm::kConstant;
  // Outliers (mismatches) are modelled as uniform on [−outlier_range_px, outlier_range_px]; 0 = the largest
  // |residual| of the samples. The fit is ML of the mixture (1 − ε)·N(0, σ_d²) + ε·U, ε fitted too.
  double outlier_range_px = 0.0;  // ≥ 0
  int depth_bins = 6;             // depth bins (equal counts) for the depth check; [1, 50]
  int min_samples = 50;           // fewer samples is an error; ≥ 10
  int max_samples = 60000;        // larger sets are thinned by a regular stride (speed); ≥ min_samples
  // The step of the matcher's output (SGBM: 1/16 px; 0: continuous). The Gaussian part is then fitted as the
  // error before rounding to the step: its density convolved with the rounding's uniform on ±step/2, so that
  // residuals one step apart are not taken for outliers where the error is below a step. The written σ
  // (constant) and floor (other forms) include the rounding's variance step²/12, so that σ_d is the whole error.
  double quantisation_step_px = 0.0;  // ≥ 0
  // The non-constant forms: after each of the fit's starts (stage "fit", the share of starts done).
  ProgressCallback progress;
  void Check() const;
};

struct NoiseDepthBin {
  double depth_m = 0.0;  // median depth of the bin
  double sigma_px = 0.0; // constant-form σ_d fitted on the bin alone
  int count = 0;
};

struct NoiseFitSummary {
  double constant_sigma_px = 0.0;   // constant-form fit (always computed; with the rounding, as written)
  double robust_sigma_px = 0.0;     // 1.4826 · median |residual|, for comparison
  double log_likelihood = 0.0;      // of the returned model, summed over samples
  double outlier_fraction = 0.0;
  std::vector<NoiseDepthBin> depth_bins;
  double depth_slope_px_per_m = 0.0;  // least-squares slope of the bins' σ against depth; NaN when the bins
                                      // span under 2% of the median depth (nothing to measure)
  int iterations = 0;                 // Nelder–Mead iterations of the main fit
};

// The calibration test of a model on held-out samples: the normalised residuals z = r / σ_d should follow the
// model's mixture (1 − ε)·N(0, 1) + ε·uniform. Reports the observed and predicted shares of |z| ≤ 1, 2, 3 and
// the RMS of z among |z| ≤ 3 (a truncated unit normal gives 0.9866; the few outliers inside add a little).
struct NoiseModelCheck {
  int samples = 0;
  double observed_within[3] = {0, 0, 0};   // share of samples with |z| ≤ 1, 2, 3
  double predicted_within[3] = {0, 0, 0};  // the same under the model's mixture
  double rms_within3 = 0.0;                // RMS of z over |z| ≤ 3
  double predicted_rms_within3 = 0.0;      // the same under the model's mixture
  double outlier_share = 0.0;              // observed share of |z| > 3 (model: about ε + 0.0027)
  // Passes when every observed share is within max_share_error of its prediction and the RMS within
  // max_rms_error of its prediction.
  bool Passes(double max_share_error = 0.03, double max_rms_error = 0.1) const;
  std::string BriefReport() const;  // one line per quantity
};
// Throws Error when fewer than 10 samples have a finite residual and σ_d. outlier_range_px as in NoiseFitOptions
// (0: the largest |residual|).
NoiseModelCheck CheckNoiseModel(const std::vector<NoiseSample>& samples, const DisparityNoiseModel& model,
                                double outlier_range_px = 0.0);

// Maximum-likelihood fit of the model's parameters and the outlier fraction (Nelder–Mead on log-parameters).
// Throws Error when there are fewer than min_samples finite samples, or (floor-plus-scale) no finite σ_pred.
DisparityNoiseModel FitDisparityNoiseModel(const std::vector<NoiseSample>& samples, const NoiseFitOptions& options,
                                           NoiseFitSummary* summary = nullptr);

}  // namespace rangebayes
