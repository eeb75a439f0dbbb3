#include "calibration/disparity_noise_model.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <limits>
#include <numeric>
#include <opencv2/core.hpp>
#include <utility>

#include "calibration/opencv_yaml.h"
#include "core/error.h"
#include "core/files.h"

namespace rangebayes {
namespace {

constexpr double kLogTwoPi = 1.8378770664093453;
// Log-parameters are kept in a range where exp() neither under- nor overflows the likelihood.
constexpr double kMinLog = -14.0;
constexpr double kMaxLog = 8.0;

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(m), v.end());
  return v[m];
}

template <size_t N>
using Vec = std::array<double, N>;

// Plain Nelder–Mead (reflection 1, expansion 2, contraction ½, shrink ½); enough for 2–3 smooth parameters.
template <size_t N>
Vec<N> NelderMead(const std::function<double(const Vec<N>&)>& f, Vec<N> start, double step, int max_iterations,
                  int* iterations, double* best_value) {
  std::array<Vec<N>, N + 1> x;
  std::array<double, N + 1> fx;
  x[0] = start;
  for (size_t i = 0; i < N; ++i) {
    x[i + 1] = start;
    x[i + 1][i] += step;
  }
  for (size_t i = 0; i <= N; ++i) fx[i] = f(x[i]);
  int it = 0;
  for (; it < max_iterations; ++it) {
    std::array<size_t, N + 1> order;
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return fx[a] < fx[b]; });
    auto xs = x;
    auto fs = fx;
    for (size_t i = 0; i <= N; ++i) {
      x[i] = xs[order[i]];
      fx[i] = fs[order[i]];
    }
    if (std::abs(fx[N] - fx[0]) <= 1e-10 * (1.0 + std::abs(fx[0]))) {
      double spread = 0;
      for (size_t i = 1; i <= N; ++i)
        for (size_t j = 0; j < N; ++j) spread = std::max(spread, std::abs(x[i][j] - x[0][j]));
      if (spread < 1e-7) break;
    }
    Vec<N> centroid{};
    for (size_t i = 0; i < N; ++i)
      for (size_t j = 0; j < N; ++j) centroid[j] += x[i][j] / static_cast<double>(N);
    auto along = [&](double t) {
      Vec<N> p;
      for (size_t j = 0; j < N; ++j) p[j] = centroid[j] + t * (x[N][j] - centroid[j]);
      return p;
    };
    const Vec<N> xr = along(-1.0);
    const double fr = f(xr);
    if (fr < fx[0]) {
      const Vec<N> xe = along(-2.0);
      const double fe = f(xe);
      if (fe < fr) {
        x[N] = xe;
        fx[N] = fe;
      } else {
        x[N] = xr;
        fx[N] = fr;
      }
    } else if (fr < fx[N - 1]) {
      x[N] = xr;
      fx[N] = fr;
    } else {
      const Vec<N> xc = fr < fx[N] ? along(-0.5) : along(0.5);
      const double fc = f(xc);
      if (fc < std::min(fr, fx[N])) {
        x[N] = xc;
        fx[N] = fc;
      } else {
        for (size_t i = 1; i <= N; ++i) {
          for (size_t j = 0; j < N; ++j) x[i][j] = x[0][j] + 0.5 * (x[i][j] - x[0][j]);
          fx[i] = f(x[i]);
        }
      }
    }
  }
  const size_t best = static_cast<size_t>(std::min_element(fx.begin(), fx.end()) - fx.begin());
  if (iterations) *iterations = it;
  if (best_value) *best_value = fx[best];
  return x[best];
}

// NelderMead (step 0.4) from each start; the end point with the lowest value, which goes to *nll. Each run's
// iterations are added to *iterations; progress (stage "fit") after each start.
template <size_t N, size_t S>
Vec<N> BestOfStarts(const std::function<double(const Vec<N>&)>& f, const std::array<Vec<N>, S>& starts,
                    int max_iterations, const ProgressCallback& progress, int* iterations, double* nll) {
  *nll = std::numeric_limits<double>::infinity();
  Vec<N> best{};
  for (size_t k = 0; k < S; ++k) {
    int it = 0;
    double value = 0;
    const Vec<N> p = NelderMead<N>(f, starts[k], 0.4, max_iterations, &it, &value);
    *iterations += it;
    if (value < *nll) {
      *nll = value;
      best = p;
    }
    if (progress) progress(static_cast<double>(k + 1) / static_cast<double>(S), "fit");
  }
  return best;
}

double Clamp(double v) { return std::clamp(v, kMinLog, kMaxLog); }
double Logistic(double v) { return 1.0 / (1.0 + std::exp(-v)); }

// Density at r of an error N(0, s²) rounded to steps of q (q = 0: not rounded): the normal convolved with the
// uniform on ±q/2. Exact (the normal's mass over [r − q/2, r + q/2], over q) where s is under four steps; above,
// the normal with Sheppard's variance s² + q²/12, which differs from it by under 1e-4 and costs one exp.
double RoundedNormalDensity(double r, double s, double q) {
  if (q > 0 && s < 4 * q) {
    const double a = std::abs(r) - 0.5 * q, b = std::abs(r) + 0.5 * q;  // the upper tail keeps far masses exact
    return 0.5 * (std::erfc(a / (s * M_SQRT2)) - std::erfc(b / (s * M_SQRT2))) / q;
  }
  const double v = s * s + q * q / 12.0;
  return std::exp(-0.5 * r * r / v - 0.5 * std::log(v) - 0.5 * kLogTwoPi);
}

// The σ of the whole error of a matcher with output step q whose error before rounding has σ s.
double WithRounding(double s, double q) { return std::sqrt(s * s + q * q / 12.0); }

// −log-likelihood of residuals r_i under (1 − ε)·N(0, s_i²) rounded to steps of q, + ε/(2R).
double MixtureNll(const std::vector<double>& r, const std::function<double(size_t)>& sigma, double eps, double range,
                  double q) {
  const double uniform = eps / (2.0 * range);
  double nll = 0;
  for (size_t i = 0; i < r.size(); ++i) {
    const double s = std::max(sigma(i), 1e-9);
    nll -= std::log((1.0 - eps) * RoundedNormalDensity(r[i], s, q) + uniform + 1e-300);
  }
  return nll;
}

struct ConstantFit {
  double sigma = 0, eps = 0, nll = 0;
  int iterations = 0;
};

// σ of the error before rounding to steps of q (see RoundedNormalDensity) and the outlier share.
ConstantFit FitConstant(const std::vector<double>& r, double range, double q) {
  double s0 = 1.4826 * Median([&] {
                std::vector<double> a;
                for (double v : r) a.push_back(std::abs(v));
                return a;
              }());
  // Not below the rounding's own σ: where most residuals are equal (an error under a step) the robust σ is 0, and
  // from far below a step the likelihood is flat in σ (the simplex never saw the one-step residuals as noise).
  s0 = std::max({s0, q / std::sqrt(12.0), 1e-4});
  const auto f = [&](const Vec<2>& p) {
    const double s = std::exp(Clamp(p[0]));
    return MixtureNll(
        r, [s](size_t) { return s; }, Logistic(p[1]), range, q);
  };
  ConstantFit fit;
  const Vec<2> best = NelderMead<2>(f, {std::log(s0), std::log(0.05 / 0.95)}, 0.3, 500, &fit.iterations, &fit.nll);
  fit.sigma = std::exp(Clamp(best[0]));
  fit.eps = Logistic(best[1]);
  return fit;
}

}  // namespace

double DisparityNoiseModel::Apply(double sigma_pred_px, double jump_px) const {
  if (form == NoiseForm::kConstant) return sigma_px;
  if (!std::isfinite(sigma_pred_px)) return std::numeric_limits<double>::quiet_NaN();
  const double k = scale * sigma_pred_px;
  if (form == NoiseForm::kFloorPlusScale) return std::sqrt(floor_px * floor_px + k * k);
  const double j = jump_scale * (std::isfinite(jump_px) ? jump_px : 0.0);
  return std::sqrt(floor_px * floor_px + k * k + j * j);
}

void DisparityNoiseModel::CheckApplicable(const std::string& matcher_name, int width_px,
                                          const std::string& what) const {
  RB_CHECK(matcher.empty() || matcher == matcher_name, what, ": the noise model was fitted for matcher '", matcher,
           "', not '", matcher_name, "'",
           matcher == "spacetime" && matcher_name == "block"
               ? " ('spacetime' models describe the static-scene preset of `rangebayes spacetime`; replay's and "
                 "live's space-time matcher is the block matcher over the window's frames: fit one with "
                 "`calibrate noise --matcher block`)"
               : "");
  if (form != NoiseForm::kLearned) return;
  RB_CHECK(width_px >= 0.75 * width_min_px && width_px <= 1.25 * width_max_px, what,
           ": the noise model was fitted on images ", width_min_px, "-", width_max_px, " px wide, not ", width_px,
           " px (disparity noise is in pixels of that resolution: fit one for this resolution)");
}

void DisparityNoiseModel::Check() const {
  // σ_d is stored in float maps: a finite double beyond them (floor_px 1e300 in a hand-edited file) made every σ
  // infinite. No disparity σ, and no weight of one, is meaningful beyond kMaxNoiseValue.
  constexpr double kMaxNoiseValue = 1e4;
  if (form == NoiseForm::kConstant) {
    RB_CHECK(sigma_px > 0 && sigma_px <= kMaxNoiseValue, "noise model: sigma_px ", sigma_px, " must be in (0, ",
             kMaxNoiseValue, "] px");
  } else {
    RB_CHECK(floor_px >= 0 && floor_px <= kMaxNoiseValue, "noise model: floor_px ", floor_px, " must be in [0, ",
             kMaxNoiseValue, "] px");
    RB_CHECK(scale >= 0 && scale <= kMaxNoiseValue, "noise model: scale ", scale, " must be in [0, ", kMaxNoiseValue,
             "]");
    RB_CHECK(floor_px > 0 || scale > 0, "noise model: floor_px and scale are both 0");
  }
  if (form == NoiseForm::kLearned) {
    RB_CHECK(jump_scale >= 0 && jump_scale <= kMaxNoiseValue, "noise model: jump_scale ", jump_scale,
             " must be in [0, ", kMaxNoiseValue, "]");
    RB_CHECK(!matcher.empty(), "noise model: the learned form needs the matcher it was fitted for");
    RB_CHECK(width_min_px > 0 && width_max_px >= width_min_px, "noise model: the learned form needs the widths it "
             "was fitted on (width_min_px ", width_min_px, ", width_max_px ", width_max_px, ")");
    RB_CHECK(window_px >= 1 && window_px % 2 == 1, "noise model: the learned form needs an odd window_px, not ",
             window_px);
  }
}

const char* NoiseFormName(NoiseForm form) {
  switch (form) {
    case NoiseForm::kConstant: return "constant";
    case NoiseForm::kFloorPlusScale: return "floor-plus-scale";
    case NoiseForm::kLearned: return "learned";
  }
  return "?";
}

NoiseForm ParseNoiseForm(const std::string& name) {
  if (name == "constant") return NoiseForm::kConstant;
  if (name == "floor-plus-scale") return NoiseForm::kFloorPlusScale;
  if (name == "learned") return NoiseForm::kLearned;
  RB_FAIL("noise model form '", name, "' is not 'constant', 'floor-plus-scale' or 'learned'");
}

void NoiseFitOptions::Check() const {
  RB_CHECK(outlier_range_px >= 0 && std::isfinite(outlier_range_px), "outlier_range_px ", outlier_range_px,
           " must be ≥ 0");
  RB_CHECK(depth_bins >= 1 && depth_bins <= 50, "depth_bins ", depth_bins, " not in [1, 50]");
  RB_CHECK(min_samples >= 10, "min_samples ", min_samples, " must be at least 10");
  RB_CHECK(quantisation_step_px >= 0 && std::isfinite(quantisation_step_px), "quantisation_step_px ",
           quantisation_step_px, " must be ≥ 0");
  RB_CHECK(max_samples >= min_samples, "max_samples ", max_samples, " must be at least min_samples ", min_samples);
}

DisparityNoiseModel ReadDisparityNoiseModel(const std::string& path) {
  CheckFileToRead(path, "noise model file");
  CheckOpenCvYamlSubset(path, "noise model");
  cv::FileStorage fs;
  try {
    fs.open(path, cv::FileStorage::READ);
  } catch (const cv::Exception& e) {
    RB_FAIL(path, ": not a readable OpenCV YAML noise model (", e.err, ")");
  } catch (const std::exception& e) {
    // OpenCV's YAML parser lets std::length_error out on some malformed files (fuzz_rig_yaml).
    RB_FAIL(path, ": not a readable OpenCV YAML noise model (", e.what(), ")");
  }
  RB_CHECK(fs.isOpened(), path, ": not a readable OpenCV YAML noise model");
  DisparityNoiseModel m;
  try {
    RB_CHECK(!fs["form"].empty(), path, ": field 'form' is missing");
    m.form = ParseNoiseForm(static_cast<std::string>(fs["form"]));
    const auto read = [&](const char* name, double* out, bool required) {
      const cv::FileNode n = fs[name];
      if (n.empty()) {
        RB_CHECK(!required, path, ": field '", name, "' is missing");
        return;
      }
      RB_CHECK(n.isReal() || n.isInt(), path, ": field '", name, "' is not a number");
      *out = static_cast<double>(n);
    };
    const bool constant = m.form == NoiseForm::kConstant;
    read("sigma_px", &m.sigma_px, constant);
    read("floor_px", &m.floor_px, !constant);
    read("scale", &m.scale, !constant);
    read("outlier_fraction", &m.outlier_fraction, false);
    read("depth_slope_px_per_m", &m.depth_slope_px_per_m, false);
    read("image_noise_gray", &m.image_noise_gray, false);
    const bool learned = m.form == NoiseForm::kLearned;
    read("jump_scale", &m.jump_scale, learned);
    double w0 = 0, w1 = 0, win = 0;
    read("width_min_px", &w0, learned);
    read("width_max_px", &w1, learned);
    read("window_px", &win, learned);
    // Whole numbers of pixels within any image's size, before the cast (window_px 1e10 read as -2147483648).
    for (const auto& [name, value] : {std::pair{"width_min_px", w0}, {"width_max_px", w1}, {"window_px", win}}) {
      RB_CHECK(value >= 0 && value <= 1 << 20 && value == std::floor(value), path, ": ", name, " ", value,
               " is not a whole number of pixels in [0, 1048576]");
    }
    m.width_min_px = static_cast<int>(w0);
    m.width_max_px = static_cast<int>(w1);
    m.window_px = static_cast<int>(win);
    RB_CHECK(!learned || !fs["matcher"].empty(), path, ": field 'matcher' is missing");
    if (!fs["matcher"].empty()) m.matcher = static_cast<std::string>(fs["matcher"]);
    if (!fs["samples"].empty()) m.samples = static_cast<int>(fs["samples"]);
  } catch (const cv::Exception& e) {
    RB_FAIL(path, ": malformed noise model (", e.err, ")");
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    RB_FAIL(path, ": malformed noise model (", e.what(), ")");
  }
  try {
    m.Check();
  } catch (const Error& e) {
    RB_FAIL(path, ": ", e.what());
  }
  return m;
}

void WriteDisparityNoiseModel(const DisparityNoiseModel& model, const std::string& path) {
  model.Check();
  cv::FileStorage fs(path, cv::FileStorage::WRITE);
  RB_CHECK(fs.isOpened(), path, ": cannot open for writing");
  fs << "form" << NoiseFormName(model.form);
  fs << "sigma_px" << model.sigma_px << "floor_px" << model.floor_px << "scale" << model.scale;
  fs << "matcher" << model.matcher << "samples" << model.samples;
  fs << "outlier_fraction" << model.outlier_fraction;
  if (std::isfinite(model.depth_slope_px_per_m)) fs << "depth_slope_px_per_m" << model.depth_slope_px_per_m;
  fs << "image_noise_gray" << model.image_noise_gray;
  if (model.form == NoiseForm::kLearned || model.jump_scale > 0) fs << "jump_scale" << model.jump_scale;
  if (model.width_max_px > 0) fs << "width_min_px" << model.width_min_px << "width_max_px" << model.width_max_px;
  if (model.window_px > 0) fs << "window_px" << model.window_px;
}

namespace {

// The samples a fit of options.form can use (finite residual; for the richer forms a predicted σ too),
// thinned evenly to options.max_samples.
std::vector<NoiseSample> UsableSamples(const std::vector<NoiseSample>& samples, const NoiseFitOptions& options) {
  std::vector<NoiseSample> valid;
  for (const NoiseSample& s : samples) {
    if (!std::isfinite(s.residual_px)) continue;
    if (options.form != NoiseForm::kConstant && !(std::isfinite(s.sigma_pred_px) && s.sigma_pred_px >= 0))
      continue;
    valid.push_back(s);
  }
  RB_CHECK(static_cast<int>(valid.size()) >= options.min_samples, "noise fit: only ", valid.size(),
           " usable residual samples", options.form != NoiseForm::kConstant ? " with a predicted sigma" : "",
           " (at least ", options.min_samples, " needed)");
  if (static_cast<int>(valid.size()) > options.max_samples) {
    std::vector<NoiseSample> thinned;
    const double step = static_cast<double>(valid.size()) / options.max_samples;
    for (int i = 0; i < options.max_samples; ++i) thinned.push_back(valid[static_cast<size_t>(i * step)]);
    valid.swap(thinned);
  }
  return valid;
}

// The residuals of the usable samples and what the richer forms scale with.
struct NoiseColumns {
  std::vector<double> r, pred, jump;
};

// The learned form, σ = sqrt(floor² + (scale·σ_pred)² + (jump_scale·jump)²) plus outliers: the best of three
// starts, which begin at s0 (the constant fit's σ) and e0 (its outlier share, as a logit).
void FitLearned(const NoiseColumns& columns, double range, double q, double s0, double e0,
                const ProgressCallback& progress, DisparityNoiseModel* model, NoiseFitSummary* sum) {
  const std::vector<double>& r = columns.r;
  const std::vector<double>& pred = columns.pred;
  const std::vector<double>& jump = columns.jump;
  const double med_pred = std::max(Median(pred), 1e-6);
  double mean_jump = 0;
  for (double j : jump) mean_jump += j / static_cast<double>(jump.size());
  mean_jump = std::max(mean_jump, 1e-3);
  const auto f = [&](const Vec<4>& p) {
    const double fl = std::exp(Clamp(p[0])), k = std::exp(Clamp(p[1])), c = std::exp(Clamp(p[2]));
    return MixtureNll(
        r, [&](size_t i) { return std::sqrt(fl * fl + k * k * pred[i] * pred[i] + c * c * jump[i] * jump[i]); },
        Logistic(p[3]), range, q);
  };
  const std::array<Vec<4>, 3> starts = {
      Vec<4>{std::log(0.9 * s0), std::log(0.3 * s0 / med_pred), std::log(0.1 * s0 / mean_jump), e0},
      Vec<4>{std::log(0.5 * s0), std::log(0.7 * s0 / med_pred), std::log(0.5 * s0 / mean_jump), e0},
      Vec<4>{std::log(0.2 * s0), std::log(0.95 * s0 / med_pred), std::log(0.2 * s0 / mean_jump), e0}};
  double best_nll = 0;
  const Vec<4> best = BestOfStarts<4>(f, starts, 2500, progress, &sum->iterations, &best_nll);
  model->floor_px = WithRounding(std::exp(Clamp(best[0])), q);
  model->scale = std::exp(Clamp(best[1]));
  model->jump_scale = std::exp(Clamp(best[2]));
  model->outlier_fraction = Logistic(best[3]);
  sum->log_likelihood = -best_nll;
}

// The floor-and-scale form, σ = sqrt(floor² + (scale·σ_pred)²) plus outliers; s0 and e0 as in FitLearned.
void FitFloorAndScale(const NoiseColumns& columns, double range, double q, double s0, double e0,
                      const ProgressCallback& progress, DisparityNoiseModel* model, NoiseFitSummary* sum) {
  const std::vector<double>& r = columns.r;
  const std::vector<double>& pred = columns.pred;
  const double med_pred = std::max(Median(pred), 1e-6);
  const auto f = [&](const Vec<3>& p) {
    const double fl = std::exp(Clamp(p[0])), k = std::exp(Clamp(p[1]));
    return MixtureNll(
        r, [&](size_t i) { return std::sqrt(fl * fl + k * k * pred[i] * pred[i]); }, Logistic(p[2]), range, q);
  };
  // Three starts: mostly floor, balanced, mostly scale; the likelihood can have a shallow second basin.
  const std::array<Vec<3>, 3> starts = {Vec<3>{std::log(0.9 * s0), std::log(0.3 * s0 / med_pred), e0},
                                        Vec<3>{std::log(0.7 * s0), std::log(0.7 * s0 / med_pred), e0},
                                        Vec<3>{std::log(0.2 * s0), std::log(0.95 * s0 / med_pred), e0}};
  double best_nll = 0;
  const Vec<3> best = BestOfStarts<3>(f, starts, 1500, progress, &sum->iterations, &best_nll);
  model->floor_px = WithRounding(std::exp(Clamp(best[0])), q);
  model->scale = std::exp(Clamp(best[1]));
  model->outlier_fraction = Logistic(best[2]);
  sum->log_likelihood = -best_nll;
}

// Depth check: constant σ per equal-count depth bin, then a least-squares line through the bins.
void FitDepthTrend(const std::vector<NoiseSample>& valid, double range, const NoiseFitOptions& options,
                   NoiseFitSummary* summary) {
  NoiseFitSummary& sum = *summary;
  std::vector<size_t> order;
  for (size_t i = 0; i < valid.size(); ++i)
    if (std::isfinite(valid[i].depth_m)) order.push_back(i);
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return valid[a].depth_m < valid[b].depth_m; });
  const int bins = std::min<int>(options.depth_bins, static_cast<int>(order.size()) / std::max(1, options.min_samples / 2));
  for (int b = 0; b < bins; ++b) {
    const size_t lo = order.size() * static_cast<size_t>(b) / static_cast<size_t>(bins);
    const size_t hi = order.size() * static_cast<size_t>(b + 1) / static_cast<size_t>(bins);
    std::vector<double> rb, db;
    for (size_t i = lo; i < hi; ++i) {
      rb.push_back(valid[order[i]].residual_px);
      db.push_back(valid[order[i]].depth_m);
    }
    NoiseDepthBin bin;
    bin.depth_m = Median(db);
    bin.sigma_px =
        WithRounding(FitConstant(rb, range, options.quantisation_step_px).sigma, options.quantisation_step_px);
    bin.count = static_cast<int>(rb.size());
    sum.depth_bins.push_back(bin);
  }
  // A slope needs depths that differ: bins spanning under 2% of the median depth leave it NaN.
  sum.depth_slope_px_per_m = std::numeric_limits<double>::quiet_NaN();
  const bool spread = sum.depth_bins.size() >= 2 &&
                      sum.depth_bins.back().depth_m - sum.depth_bins.front().depth_m >
                          0.02 * sum.depth_bins[sum.depth_bins.size() / 2].depth_m;
  if (spread) {
    double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
    for (const NoiseDepthBin& b : sum.depth_bins) {
      const double w = b.count;
      sw += w;
      sx += w * b.depth_m;
      sy += w * b.sigma_px;
      sxx += w * b.depth_m * b.depth_m;
      sxy += w * b.depth_m * b.sigma_px;
    }
    const double den = sw * sxx - sx * sx;
    sum.depth_slope_px_per_m = den > 1e-12 * sw * sw ? (sw * sxy - sx * sy) / den : 0.0;
  }
}

}  // namespace

DisparityNoiseModel FitDisparityNoiseModel(const std::vector<NoiseSample>& samples, const NoiseFitOptions& options,
                                           NoiseFitSummary* summary) {
  options.Check();
  NoiseFitSummary local;
  NoiseFitSummary& sum = summary ? *summary : local;
  sum = NoiseFitSummary{};
  const std::vector<NoiseSample> valid = UsableSamples(samples, options);
  NoiseColumns columns;
  std::vector<double> absr;
  for (const NoiseSample& s : valid) {
    columns.r.push_back(s.residual_px);
    columns.pred.push_back(s.sigma_pred_px);
    columns.jump.push_back(std::isfinite(s.jump_px) ? s.jump_px : 0.0);
    absr.push_back(std::abs(s.residual_px));
  }
  double range = options.outlier_range_px;
  if (range <= 0) range = *std::max_element(absr.begin(), absr.end());
  range = std::max(range, 1e-6);
  sum.robust_sigma_px = 1.4826 * Median(absr);

  const double q = options.quantisation_step_px;
  const ConstantFit constant = FitConstant(columns.r, range, q);
  sum.constant_sigma_px = WithRounding(constant.sigma, q);

  DisparityNoiseModel model;
  model.form = options.form;
  model.samples = static_cast<int>(valid.size());
  model.sigma_px = sum.constant_sigma_px;
  const double s0 = std::max(constant.sigma, 1e-4);
  const double e0 = std::log(std::max(constant.eps, 1e-3) / (1 - std::max(constant.eps, 1e-3)));
  if (options.form == NoiseForm::kConstant) {
    model.outlier_fraction = constant.eps;
    sum.log_likelihood = -constant.nll;
    sum.iterations = constant.iterations;
  } else if (options.form == NoiseForm::kLearned) {
    FitLearned(columns, range, q, s0, e0, options.progress, &model, &sum);
  } else {
    FitFloorAndScale(columns, range, q, s0, e0, options.progress, &model, &sum);
  }
  sum.outlier_fraction = model.outlier_fraction;
  FitDepthTrend(valid, range, options, &sum);
  model.depth_slope_px_per_m = sum.depth_slope_px_per_m;
  return model;
}

bool NoiseModelCheck::Passes(double max_share_error, double max_rms_error) const {
  for (int k = 0; k < 3; ++k)
    if (std::abs(observed_within[k] - predicted_within[k]) > max_share_error) return false;
  return std::abs(rms_within3 - predicted_rms_within3) <= max_rms_error;
}

std::string NoiseModelCheck::BriefReport() const {
  char line[512];
  std::snprintf(line, sizeof(line),
                "calibration check on %d residuals, z = (d - d_gt) / sigma_d:\n"
                "share |z| <= 1, 2, 3: observed %.3f %.3f %.3f, model %.3f %.3f %.3f\n"
                "RMS of z over |z| <= 3: observed %.3f, model %.3f; share |z| > 3: %.3f\n"
                "%s\n",
                samples, observed_within[0], observed_within[1], observed_within[2], predicted_within[0],
                predicted_within[1], predicted_within[2], rms_within3, predicted_rms_within3, outlier_share,
                Passes() ? "calibrated (shares within 0.03, RMS within 0.1)" : "NOT calibrated (shares within 0.03, RMS "
                                                                             "within 0.1 required)");
  return line;
}

NoiseModelCheck CheckNoiseModel(const std::vector<NoiseSample>& samples, const DisparityNoiseModel& model,
                                double outlier_range_px) {
  model.Check();
  std::vector<double> r, s;
  for (const NoiseSample& x : samples) {
    const double sigma = model.Apply(x.sigma_pred_px, x.jump_px);
    if (!std::isfinite(x.residual_px) || !std::isfinite(sigma) || sigma <= 0) continue;
    r.push_back(x.residual_px);
    s.push_back(sigma);
  }
  RB_CHECK(r.size() >= 10, "noise check: only ", r.size(), " residuals with a finite sigma_d (at least 10 needed)");
  double range = outlier_range_px;
  if (range <= 0)
    for (double v : r) range = std::max(range, std::abs(v));
  range = std::max(range, 1e-6);
  const double eps = model.outlier_fraction;
  // Unit normal: P(|z| ≤ t) and E[z²; |z| ≤ 3].
  const double normal_within[3] = {std::erf(1 / std::sqrt(2.0)), std::erf(2 / std::sqrt(2.0)),
                                   std::erf(3 / std::sqrt(2.0))};
  const double normal_second3 = normal_within[2] - 6.0 * std::exp(-4.5) / std::sqrt(2 * M_PI);
  NoiseModelCheck c;
  c.samples = static_cast<int>(r.size());
  double second = 0, count3 = 0, pred_second = 0;
  for (size_t i = 0; i < r.size(); ++i) {
    const double z = std::abs(r[i] / s[i]);
    for (int k = 0; k < 3; ++k) {
      if (z <= k + 1) c.observed_within[k] += 1;
      c.predicted_within[k] += (1 - eps) * normal_within[k] + eps * std::min(1.0, (k + 1) * s[i] / range);
    }
    if (z <= 3) {
      second += z * z;
      count3 += 1;
    }
    // Uniform r on [−R, R]: E[z²; |r| ≤ 3σ] = 9σ/R, or R²/(3σ²) when 3σ ≥ R.
    pred_second += (1 - eps) * normal_second3 +
                   eps * (3 * s[i] < range ? 9.0 * s[i] / range : range * range / (3.0 * s[i] * s[i]));
  }
  const double n = static_cast<double>(r.size());
  for (int k = 0; k < 3; ++k) {
    c.observed_within[k] /= n;
    c.predicted_within[k] /= n;
  }
  c.rms_within3 = count3 > 0 ? std::sqrt(second / count3) : 0.0;
  c.predicted_rms_within3 = std::sqrt(pred_second / (c.predicted_within[2] * n));
  c.outlier_share = 1.0 - c.observed_within[2];
  return c;
}

}  // namespace rangebayes
