// The disparity-noise model of docs/design.md §2 (σ_d of a disparity measurement, pixels), its YAML file (noise.yaml,
// OpenCV FileStorage) and its maximum-likelihood fit from residuals about a known target.
#pragma once

#include <string>
#include <vector>

namespace rangebayes {

enum class NoiseForm {
  kConstant,        // σ_d = sigma_px for every pixel
  kFloorPlusScale,  // σ_d = sqrt(floor_px² + (scale · σ_pred)²), σ_pred the matcher's predicted σ_d
};

struct DisparityNoiseModel {
  NoiseForm form = NoiseForm::kConstant;
  double sigma_px = 0.5;   // constant form; > 0
  double floor_px = 0.15;  // floor-plus-scale form; ≥ 0
  double scale = 2.0;      // floor-plus-scale form (k); ≥ 0

  // Provenance, written to and read from noise.yaml (informational).
  std::string matcher;                    // e.g. "sgbm", "block", "spacetime"
  int samples = 0;                        // residuals the fit used
  double outlier_fraction = 0.0;          // mixture weight of the uniform outlier component
  double depth_slope_px_per_m = 0.0;      // slope of σ_d (constant form, per depth bin) against depth; NaN: n/a
  // σ_pred scales with the image noise σ_n the matcher assumed; the fit's σ_n (0: unknown) lets a user of the
  // model with another σ_n rescale: scale' = scale · fit σ_n / own σ_n.
  double image_noise_gray = 0.0;

  // σ_d in pixels for a pixel whose matcher predicted σ_pred (pixels). The constant form ignores σ_pred;
  // the floor-plus-scale form returns NaN for a non-finite σ_pred (no prediction: the caller decides).
  double Apply(double sigma_pred_px) const;
  void Check() const;
};

// Throws Error naming the file and the field on a missing file or a malformed/missing field.
DisparityNoiseModel ReadDisparityNoiseModel(const std::string& path);
void WriteDisparityNoiseModel(const DisparityNoiseModel& model, const std::string& path);
NoiseForm ParseNoiseForm(const std::string& name);  // "constant" | "floor-plus-scale"; throws otherwise
const char* NoiseFormName(NoiseForm form);

// One disparity residual about the target: measured − target disparity along the pixel's ray (pixels),
// the matcher's predicted σ_d (NaN when it has none) and the depth (metres, for the depth check).
struct NoiseSample {
  double residual_px = 0.0;
  double sigma_pred_px = 0.0;
  double depth_m = 0.0;
};

struct NoiseFitOptions {
  NoiseForm form = NoiseForm::kConstant;
  // Outliers (mismatches) are modelled as uniform on [−outlier_range_px, outlier_range_px]; 0 = the largest
  // |residual| of the samples. The fit is ML of the mixture (1 − ε)·N(0, σ_d²) + ε·U, ε fitted too.
  double outlier_range_px = 0.0;  // ≥ 0
  int depth_bins = 6;             // depth bins (equal counts) for the depth check; [1, 50]
  int min_samples = 50;           // fewer samples is an error; ≥ 10
  int max_samples = 60000;        // larger sets are thinned by a regular stride (speed); ≥ min_samples
  // Lower bound on the fitted σ (constant) and floor (floor-plus-scale), e.g. the quantisation of a matcher's
  // output (1/16 px steps: 0.018 px); ≥ 0.
  double min_sigma_px = 0.0;
  void Check() const;
};

struct NoiseDepthBin {
  double depth_m = 0.0;  // median depth of the bin
  double sigma_px = 0.0; // constant-form σ_d fitted on the bin alone
  int count = 0;
};

struct NoiseFitSummary {
  double constant_sigma_px = 0.0;   // constant-form fit (always computed)
  double robust_sigma_px = 0.0;     // 1.4826 · median |residual|, for comparison
  double log_likelihood = 0.0;      // of the returned model, summed over samples
  double outlier_fraction = 0.0;
  std::vector<NoiseDepthBin> depth_bins;
  double depth_slope_px_per_m = 0.0;  // least-squares slope of the bins' σ against depth; NaN when the bins
                                      // span under 2% of the median depth (nothing to measure)
  int iterations = 0;                 // Nelder–Mead iterations of the main fit
};

// Maximum-likelihood fit of the model's parameters and the outlier fraction (Nelder–Mead on log-parameters).
// Throws Error when there are fewer than min_samples finite samples, or (floor-plus-scale) no finite σ_pred.
DisparityNoiseModel FitDisparityNoiseModel(const std::vector<NoiseSample>& samples, const NoiseFitOptions& options,
                                           NoiseFitSummary* summary = nullptr);

}  // namespace rangebayes
