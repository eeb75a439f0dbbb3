#include "stereo/spacetime_matcher.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "core/error.h"

namespace rangebayes {

void SpaceTimeMatcherOptions::Check() const {
  RB_CHECK(num_disparities >= 3 && num_disparities <= 1024, "num_disparities ", num_disparities,
           " is outside 3–1024");
  RB_CHECK(window_px >= 1 && window_px <= 31 && window_px % 2 == 1, "window_px ", window_px,
           " must be odd and in 1–31");
  RB_CHECK(uniqueness_ratio >= 0.0, "uniqueness_ratio ", uniqueness_ratio, " must be ≥ 0");
  RB_CHECK(image_noise_gray > 0.0, "image_noise_gray ", image_noise_gray, " must be positive");
  RB_CHECK(sigma_floor_px >= 0.0 && sigma_scale > 0.0, "sigma model floor ", sigma_floor_px, " px / scale ",
           sigma_scale, " must be ≥ 0 / > 0");
  RB_CHECK(ambiguity_weight >= 0.0, "ambiguity_weight ", ambiguity_weight, " must be ≥ 0");
  RB_CHECK(max_sigma_disparity_px >= 0.0, "max_sigma_disparity_px must be ≥ 0");
  RB_CHECK(subpixel_iterations >= 0 && subpixel_iterations <= 5, "subpixel_iterations ", subpixel_iterations,
           " is outside 0–5");
  RB_CHECK(doubtful_verify_window_px == 0 ||
               (doubtful_verify_window_px >= 1 && doubtful_verify_window_px <= 31 && doubtful_verify_window_px % 2 == 1),
           "doubtful_verify_window_px ", doubtful_verify_window_px, " must be 0 or odd in 1–31");
  RB_CHECK(doubtful_sigma_px >= 0.0, "doubtful_sigma_px ", doubtful_sigma_px, " must be ≥ 0");
  RB_CHECK(rows_per_task >= 1 && rows_per_task <= 1024, "rows_per_task ", rows_per_task, " is outside 1–1024");
}

SpaceTimeMatcherOptions SpaceTimeStaticSceneOptions(int frames) {
  RB_CHECK(frames >= 1, "space-time preset needs at least one frame, got ", frames);
  SpaceTimeMatcherOptions o;
  o.window_px = frames >= 16 ? 5 : 7;
  o.subpixel_iterations = 1;
  o.sigma_floor_px = kGaussNewtonSigmaFloorPx;
  o.sigma_scale = kGaussNewtonSigmaScale;
  o.doubtful_jump_px = 1.0;
  o.doubtful_verify_window_px = frames >= 16 ? 3 : 5;
  return o;
}

void SetSubpixelIterations(int iterations, SpaceTimeMatcherOptions* options) {
  if (iterations == options->subpixel_iterations) return;
  const SpaceTimeMatcherOptions parabola;
  options->subpixel_iterations = iterations;
  options->sigma_floor_px = iterations > 0 ? kGaussNewtonSigmaFloorPx : parabola.sigma_floor_px;
  options->sigma_scale = iterations > 0 ? kGaussNewtonSigmaScale : parabola.sigma_scale;
}

void ApplyDisparityNoiseModel(const DisparityNoiseModel& model, SpaceTimeMatcherOptions* options) {
  if (model.form == NoiseForm::kLearned) return;  // σ_d comes after matching (stereo/disparity_features.h)
  const bool constant = model.form == NoiseForm::kConstant;
  options->sigma_floor_px = constant ? model.sigma_px : model.floor_px;
  options->sigma_scale =
      constant ? 1e-9
               : model.scale * (model.image_noise_gray > 0 ? model.image_noise_gray / options->image_noise_gray : 1.0);
}

SpaceTimeMatcher::SpaceTimeMatcher(const SpaceTimeMatcherOptions& options) : options_(options) {
  options_.Check();
}

namespace {

// The hot loops are compiled twice, for AVX2 and for the baseline ISA, and picked at load time (GCC
// function multi-versioning): the default build targets plain x86-64 (SSE2), and AVX2 roughly halves the
// time of the cost loops on machines that have it. Not under ThreadSanitizer: the ifunc resolver runs before
// the TSan runtime is initialised and crashes the program at start-up.
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__) && !defined(__SANITIZE_THREAD__)
#define RB_MULTIVERSION __attribute__((target_clones("avx2", "default")))
#else
#define RB_MULTIVERSION
#endif

// Images as float grey levels, interleaved per row as [y][t][x] so that the T rows one cost row needs are
// contiguous.
struct Sequence {
  int width = 0, height = 0, frames = 0;
  std::vector<float> data;
  const float* row(int y) const { return data.data() + static_cast<size_t>(y) * frames * width; }
  float* row(int y) { return data.data() + static_cast<size_t>(y) * frames * width; }
};

cv::Mat ToGreyFloat(const cv::Mat& image) {
  cv::Mat grey = image;
  if (image.channels() == 3) cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  cv::Mat f;
  grey.convertTo(f, CV_32F);
  return f;
}

Sequence Interleave(const std::vector<cv::Mat>& frames) {
  Sequence s;
  s.width = frames[0].cols;
  s.height = frames[0].rows;
  s.frames = static_cast<int>(frames.size());
  s.data.resize(static_cast<size_t>(s.width) * s.height * s.frames);
  for (int t = 0; t < s.frames; ++t) {
    const cv::Mat f = ToGreyFloat(frames[t]);
    for (int y = 0; y < s.height; ++y) std::copy_n(f.ptr<float>(y), s.width, s.row(y) + t * s.width);
  }
  return s;
}

// The same images pixel-major, [y][x][t]: the T samples of one pixel are contiguous, which is what the
// Gauss–Newton refinement reads (per window sample, all T frames at one right-image position).
struct PixelMajor {
  int width = 0, height = 0, frames = 0;
  std::vector<float> data;
  const float* at(int y, int x) const {
    return data.data() + (static_cast<size_t>(y) * width + x) * static_cast<size_t>(frames);
  }
};

PixelMajor ToPixelMajor(const Sequence& s) {
  PixelMajor p;
  p.width = s.width;
  p.height = s.height;
  p.frames = s.frames;
  p.data.resize(s.data.size());
  tbb::parallel_for(0, s.height, [&](int y) {
    const float* in = s.row(y);
    float* out = p.data.data() + static_cast<size_t>(y) * s.width * s.frames;
    for (int t = 0; t < s.frames; ++t)
      for (int x = 0; x < s.width; ++x) out[static_cast<size_t>(x) * s.frames + t] = in[static_cast<size_t>(t) * s.width + x];
  });
  return p;
}

// Replaces each pixel's temporal signal by (I − mean) / sqrt(var + σ_n²): the SSD of two such signals is
// 2T(1 − ZNCC) up to the regulariser, which makes the cost blind to the per-pixel gain and offset that differ
// between the two cameras (albedo seen at different angles, vignetting, exposure). The regulariser σ_n² keeps
// pixels whose signal is below the noise near zero, so they match nothing sharply and get a large σ_d.
// noise_scale (optional) receives 1/sqrt(var + σ_n²): the factor the image noise is scaled by.
void NormaliseTemporally(Sequence* s, double noise_gray, std::vector<float>* noise_scale) {
  const int T = s->frames, W = s->width;
  if (noise_scale) noise_scale->assign(static_cast<size_t>(W) * s->height, 1.0f);
  const float n2 = static_cast<float>(noise_gray * noise_gray);
  tbb::parallel_for(0, s->height, [&](int y) {
    float* r = s->row(y);
    for (int x = 0; x < W; ++x) {
      float mean = 0.0f;
      for (int t = 0; t < T; ++t) mean += r[t * W + x];
      mean /= static_cast<float>(T);
      float var = 0.0f;
      for (int t = 0; t < T; ++t) var += (r[t * W + x] - mean) * (r[t * W + x] - mean);
      var /= static_cast<float>(T);
      const float inv = 1.0f / std::sqrt(var + n2);
      for (int t = 0; t < T; ++t) r[t * W + x] = (r[t * W + x] - mean) * inv;
      if (noise_scale) (*noise_scale)[static_cast<size_t>(y) * W + x] = inv;
    }
  });
}

// Keys cubic convolution weights (a = −½) for samples i−1 … i+2 at fraction f ∈ [0, 1), and the weights of
// the derivative with respect to position.
inline void CubicWeights(float f, float w[4], float g[4]) {
  const float f2 = f * f, f3 = f2 * f;
  w[0] = -0.5f * f3 + f2 - 0.5f * f;
  w[1] = 1.5f * f3 - 2.5f * f2 + 1.0f;
  w[2] = -1.5f * f3 + 2.0f * f2 + 0.5f * f;
  w[3] = 0.5f * f3 - 0.5f * f2;
  g[0] = -1.5f * f2 + 2.0f * f - 0.5f;
  g[1] = 4.5f * f2 - 5.0f * f;
  g[2] = -4.5f * f2 + 4.0f * f + 0.5f;
  g[3] = 1.5f * f2 - f;
}

// Sub-pixel refinement by Gauss–Newton on the window's SSD, starting at *disparity: the parabola through
// three integer costs is biased for any cost curve that is not a parabola (with a w-wide window the
// difference C(d+1) − C(d−1) telescopes to the texture at the window's two edges, ≈ 1/w of the curvature,
// which no temporal averaging removes: 0.07 px on noise-free synthetic planes). Each iteration samples the
// right image at x − d by cubic convolution and solves the linearised problem Δ = −Σ g·e / Σ g² with g the
// LEFT image's central-difference gradient (inverse-compositional Lucas–Kanade; at the match it equals the
// right image's). The right image's interpolated gradient would be the textbook choice, but its noise is
// correlated with the noise of the interpolated value in e (the cubic value and derivative weights
// overlap except at fractions 0 and ½), which pulls the estimate towards integer disparities by an amount
// that grows with σ_n²: on the synthetic scenes at noise 4 grey levels, T = 16, w = 5, the right-gradient
// version left 3.9 mm depth RMS away from edges on `planes`, the left-gradient version 2.6 mm
// (`bench_stereo --quality=synth`). The central difference skips the centre sample, so its noise is
// uncorrelated with that pixel's own e. The same sums give the error propagation
// σ_pred² = Σ g²·(σ_L² + σ_R²) / (Σ g²)² (= 2σ_n²/Σg² = 4σ_n²/C″ for uniform noise, C″ the analytic cost
// curvature). Returns false when the window has no gradient.
// Σ_t g·e and Σ_t g² of one window sample: g = ½(L(x+1) − L(x−1)), e = L(x) − Σ_k w_k R(ir − 1 + k), all at
// frame t; each pointer addresses T contiguous samples (PixelMajor). Eight partial sums, so the compiler
// can keep them in one vector register.
inline __attribute__((always_inline)) void SampleSums(const float* lc, const float* lm, const float* lp, const float* r0, const float* r1,
                                const float* r2, const float* r3, const float* w, int T, float* ge_out,
                                float* gg_out) {
  float ge[8] = {0, 0, 0, 0, 0, 0, 0, 0}, gg[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int t = 0;
  for (; t + 8 <= T; t += 8) {
    for (int k = 0; k < 8; ++k) {
      const float rv = w[0] * r0[t + k] + w[1] * r1[t + k] + w[2] * r2[t + k] + w[3] * r3[t + k];
      const float g = 0.5f * (lp[t + k] - lm[t + k]);
      const float e = lc[t + k] - rv;
      ge[k] += g * e;
      gg[k] += g * g;
    }
  }
  for (; t < T; ++t) {
    const float rv = w[0] * r0[t] + w[1] * r1[t] + w[2] * r2[t] + w[3] * r3[t];
    const float g = 0.5f * (lp[t] - lm[t]);
    const float e = lc[t] - rv;
    ge[0] += g * e;
    gg[0] += g * g;
  }
  *ge_out = ((ge[0] + ge[1]) + (ge[2] + ge[3])) + ((ge[4] + ge[5]) + (ge[6] + ge[7]));
  *gg_out = ((gg[0] + gg[1]) + (gg[2] + gg[3])) + ((gg[4] + gg[5]) + (gg[6] + gg[7]));
}

RB_MULTIVERSION bool RefineGaussNewton(const PixelMajor& L, const PixelMajor& R, const std::vector<float>& noise_left,
                       const std::vector<float>& noise_right, int x, int y, int r, int iterations, double noise,
                       double slope_x, double slope_y, double* disparity, double* sigma_pred) {
  const int W = L.width, H = L.height, T = L.frames;
  double dsub = *disparity;
  double sum_gg = 0.0, sum_var = 0.0;
  int samples = 0;
  for (int iter = 0; iter < iterations; ++iter) {
    double sum_ge = 0.0;
    sum_gg = 0.0;
    sum_var = 0.0;
    samples = 0;
    for (int wy = -r; wy <= r; ++wy) {
      const int yy = std::clamp(y + wy, 0, H - 1);
      for (int wx = -r; wx <= r; ++wx) {
        const int xp = x + wx;
        if (xp < 0 || xp >= W) continue;
        // Planar window: the disparity of the sample follows the local slope, so slanted surfaces are not
        // biased by the window's texture distribution. The left sample stays on its pixel and the right
        // image is interpolated by cubic convolution (Keys, a = −½). Measured on noise-free synthetic planes
        // at fractional disparities: linear interpolation biases the estimate towards half-integers by up to
        // 0.04 px, and interpolating both images half way (symmetric) does not remove it (the interpolation
        // error correlates with the gradient); one-sided cubic leaves 0.01–0.02 px.
        const double pr = xp - (dsub + slope_x * wx + slope_y * wy);
        const int ir = static_cast<int>(std::floor(pr));
        if (ir < 1 || ir + 2 >= W) continue;
        const int xl = std::clamp(xp, 1, W - 2);
        float wr[4], gr[4];
        CubicWeights(static_cast<float>(pr - ir), wr, gr);
        float ge = 0.0f, gg = 0.0f;
        const float* rb = R.at(yy, ir - 1);
        SampleSums(L.at(yy, xp), L.at(yy, xl - 1), L.at(yy, xl + 1), rb, rb + T, rb + 2 * T, rb + 3 * T, wr, T, &ge,
                   &gg);
        sum_ge += ge;
        sum_gg += gg;
        ++samples;
        if (!noise_left.empty() && iter + 1 == iterations) {
          const double sl = noise_left[static_cast<size_t>(yy) * W + xp];
          const double sr = noise_right[static_cast<size_t>(yy) * W + ir];
          sum_var += sl * sl + sr * sr;
        }
      }
    }
    if (!(sum_gg > 0.0)) return false;
    // e(d) = L(x') − R(x' − d) grows with d at rate g = R′, so the Gauss–Newton step is −Σ g·e / Σ g².
    dsub -= sum_ge / sum_gg;
    if (!(std::abs(dsub - *disparity) <= 2.0)) return false;
  }
  *disparity = dsub;
  if (noise_left.empty()) {
    *sigma_pred = std::sqrt(2.0 * noise * noise / sum_gg);
  } else {
    // Temporal normalisation scales each pixel's noise by its own factor; the window's mean of
    // σ_L² + σ_R² stands in for the per-sample weights (Σ over t of g² is not kept per sample).
    const double mean_var = noise * noise * sum_var / std::max(1, samples);
    *sigma_pred = std::sqrt(mean_var / sum_gg);
  }
  return true;
}

// Least-squares slopes ∂d/∂x, ∂d/∂y of the coarse disparity over the window around (x, y), using only
// pixels within 2 px of the centre's disparity (so the fit does not reach across a depth edge).
void WindowSlopes(const cv::Mat& coarse, int x, int y, int r, double* sx, double* sy) {
  const float dc = coarse.at<float>(y, x);
  double sxx = 0, syy = 0, sxd = 0, syd = 0, sxy = 0, sd = 0, sx1 = 0, sy1 = 0;
  int n = 0;
  for (int wy = -r; wy <= r; ++wy) {
    const int yy = y + wy;
    if (yy < 0 || yy >= coarse.rows) continue;
    const float* row = coarse.ptr<float>(yy);
    for (int wx = -r; wx <= r; ++wx) {
      const int xx = x + wx;
      if (xx < 0 || xx >= coarse.cols) continue;
      const float d = row[xx];
      if (!(std::abs(d - dc) < 2.0f)) continue;
      sxx += wx * wx;
      syy += wy * wy;
      sxy += wx * wy;
      sxd += wx * (d - dc);
      syd += wy * (d - dc);
      sd += d - dc;
      sx1 += wx;
      sy1 += wy;
      ++n;
    }
  }
  *sx = *sy = 0.0;
  if (n < 6) return;
  // Plane d = c + a·wx + b·wy through the samples (3×3 normal equations).
  Eigen::Matrix3d A;
  A << n, sx1, sy1, sx1, sxx, sxy, sy1, sxy, syy;
  const Eigen::Vector3d rhs(sd, sxd, syd);
  const Eigen::Vector3d p = A.ldlt().solve(rhs);
  if (!p.allFinite()) return;
  *sx = std::clamp(p(1), -1.0, 1.0);
  *sy = std::clamp(p(2), -1.0, 1.0);
}

// Single frames: each pixel minus the mean of its w×w neighbourhood, divided by sqrt(local variance + σ_n²).
// The SSD of such images behaves like a window ZNCC: blind to the gain and offset differences between the
// two cameras (Middlebury 2014's exposure and lighting variants), at the price of σ_n scaled per pixel.
void NormaliseSpatially(Sequence* s, int window, double noise_gray, std::vector<float>* noise_scale) {
  const int W = s->width, H = s->height;
  noise_scale->assign(static_cast<size_t>(W) * H, 1.0f);
  for (int t = 0; t < s->frames; ++t) {
    cv::Mat image(H, W, CV_32F);
    for (int y = 0; y < H; ++y) std::copy_n(s->row(y) + t * W, W, image.ptr<float>(y));
    cv::Mat mean, mean2;
    cv::boxFilter(image, mean, CV_32F, cv::Size(window, window), cv::Point(-1, -1), true, cv::BORDER_REFLECT);
    cv::boxFilter(image.mul(image), mean2, CV_32F, cv::Size(window, window), cv::Point(-1, -1), true,
                  cv::BORDER_REFLECT);
    const float n2 = static_cast<float>(noise_gray * noise_gray);
    for (int y = 0; y < H; ++y) {
      float* out = s->row(y) + t * W;
      const float* m = mean.ptr<float>(y);
      const float* m2 = mean2.ptr<float>(y);
      for (int x = 0; x < W; ++x) {
        const float inv = 1.0f / std::sqrt(std::max(0.0f, m2[x] - m[x] * m[x]) + n2);
        out[x] = (image.at<float>(y, x) - m[x]) * inv;
        if (t == 0) (*noise_scale)[static_cast<size_t>(y) * W + x] = inv;
      }
    }
  }
}


// Per-pixel temporal cost of one input row at disparity d: e[x] = Σ_t (L_t(x) − R_t(x − d))², for the
// columns whose right pixel exists; the others repeat the nearest such column (so border windows are not
// biased towards disparities that leave the image), all 0 when none exists. e has W + 2r entries: r of
// padding on both sides for the horizontal window sum. Blocks of 16 columns keep the T-frame accumulation in
// registers and vectorise across x (the rows of the T frames are contiguous in Sequence's layout).
RB_MULTIVERSION void TemporalCostRow(const float* lrow, const float* rrow, int W, int T, int d, int r, float* e_pad) {
  float* e = e_pad + r;
  const int xa = std::clamp(d, 0, W);
  const int xb = std::clamp(W + d, 0, W);
  if (xa >= xb) {
    std::fill(e_pad, e_pad + W + 2 * r, 0.0f);
    return;
  }
  constexpr int kBlock = 16;
  int x = xa;
  for (; x + kBlock <= xb; x += kBlock) {
    float acc[kBlock] = {};
    for (int t = 0; t < T; ++t) {
      const float* lt = lrow + static_cast<size_t>(t) * W + x;
      const float* rt = rrow + static_cast<size_t>(t) * W + x - d;
      for (int i = 0; i < kBlock; ++i) {
        const float diff = lt[i] - rt[i];
        acc[i] += diff * diff;
      }
    }
    for (int i = 0; i < kBlock; ++i) e[x + i] = acc[i];
  }
  for (; x < xb; ++x) {
    float acc = 0.0f;
    for (int t = 0; t < T; ++t) {
      const float diff = lrow[static_cast<size_t>(t) * W + x] - rrow[static_cast<size_t>(t) * W + x - d];
      acc += diff * diff;
    }
    e[x] = acc;
  }
  std::fill(e_pad, e + xa, e[xa]);
  std::fill(e + xb, e_pad + W + 2 * r, e[xb - 1]);
}

// Horizontal w-tap sum of the padded temporal costs into hs, then the vertical running sum: col gains the
// new row and loses the one that leaves the window (held in slot, which then takes the new row).
RB_MULTIVERSION void WindowSumRow(const float* e_pad, int W, int w, float* hs, float* slot, float* col) {
  for (int x = 0; x < W; ++x) hs[x] = e_pad[x];
  for (int j = 1; j < w; ++j) {
    const float* ej = e_pad + j;
    for (int x = 0; x < W; ++x) hs[x] += ej[x];
  }
  for (int x = 0; x < W; ++x) {
    col[x] += hs[x] - slot[x];
    slot[x] = hs[x];
  }
}

// Winner-take-all over the D cost slices of one output row (vol: [D][W]) for the left view (best, arg) and
// the right view (best_r, arg_r: right pixel xr sees left pixel xr + d).
RB_MULTIVERSION void WinnerTakeAllRow(const float* vol, int W, int D, int dmin, float* best, int* arg, float* best_r,
                                      int* arg_r) {
  const float inf = std::numeric_limits<float>::infinity();
  std::fill(best, best + W, inf);
  std::fill(arg, arg + W, -1);
  std::fill(best_r, best_r + W, inf);
  std::fill(arg_r, arg_r + W, -1);
  for (int di = 0; di < D; ++di) {
    const int d = dmin + di;
    const float* c = vol + static_cast<size_t>(di) * W;
    const int xa = std::clamp(d, 0, W), xb = std::clamp(W + d, 0, W);
    for (int x = xa; x < xb; ++x) {
      const bool better = c[x] < best[x];
      best[x] = better ? c[x] : best[x];
      arg[x] = better ? di : arg[x];
    }
    const int ra = std::clamp(-d, 0, W), rb = std::clamp(W - d, 0, W);
    const float* cr = c + d;
    for (int xr = ra; xr < rb; ++xr) {
      const bool better = cr[xr] < best_r[xr];
      best_r[xr] = better ? cr[xr] : best_r[xr];
      arg_r[xr] = better ? di : arg_r[xr];
    }
  }
}

// The smallest cost at least 2 disparities away from each pixel's winner (the runner-up minimum that the
// uniqueness test and the ambiguity term of σ_d use), and its disparity index.
RB_MULTIVERSION void RunnerUpRow(const float* vol, int W, int D, int dmin, const int* arg, float* second,
                                 int* arg2) {
  std::fill(second, second + W, std::numeric_limits<float>::infinity());
  std::fill(arg2, arg2 + W, -1);
  for (int di = 0; di < D; ++di) {
    const int d = dmin + di;
    const float* c = vol + static_cast<size_t>(di) * W;
    const int xa = std::clamp(d, 0, W), xb = std::clamp(W + d, 0, W);
    for (int x = xa; x < xb; ++x) {
      const int gap = di - arg[x];
      const bool better = (gap >= 2 || gap <= -2) && c[x] < second[x];
      second[x] = better ? c[x] : second[x];
      arg2[x] = better ? di : arg2[x];
    }
  }
}

// Winner-take-all disparity of pixel (x, y) with a small v×v×T window (v = 2·rv + 1) over the whole search
// range, or INT_MIN when no disparity has the window inside the right image. Checks a doubtful pixel: a
// window that reaches only rv px sees little of the other surface across a depth edge.
int SmallWindowDisparity(const Sequence& L, const Sequence& R, int x, int y, int rv, int dmin, int D) {
  const int W = L.width, H = L.height, T = L.frames;
  double best = std::numeric_limits<double>::infinity();
  int arg = std::numeric_limits<int>::min();
  for (int di = 0; di < D; ++di) {
    const int d = dmin + di;
    if (x - rv - d < 0 || x + rv - d >= W || x - rv < 0 || x + rv >= W) continue;
    double cost = 0.0;
    for (int wy = -rv; wy <= rv; ++wy) {
      const int yy = std::clamp(y + wy, 0, H - 1);
      const float* lr = L.row(yy);
      const float* rr = R.row(yy);
      for (int t = 0; t < T; ++t) {
        const float* lt = lr + static_cast<size_t>(t) * W;
        const float* rt = rr + static_cast<size_t>(t) * W;
        for (int wx = -rv; wx <= rv; ++wx) {
          const double e = lt[x + wx] - rt[x + wx - d];
          cost += e * e;
        }
      }
    }
    if (cost < best) {
      best = cost;
      arg = d;
    }
  }
  return arg;
}

struct BandBuffers {
  std::vector<float> ring;    // [w][D][W]: horizontally summed costs of the last w input rows
  std::vector<float> volume;  // [D][W]: window costs of the current output row (the running column sums)
  std::vector<float> e;       // W + 2r: temporal costs of one input row, padded
  std::vector<float> hs;      // W
  std::vector<float> best_left, best_right, second;
  std::vector<int> arg_left, arg_right, arg_second;
};

}  // namespace

namespace {

// The rejection counts of one match (SpaceTimeMatchSummary).
struct MatchCounts {
  int valid = 0, left_right = 0, flat = 0, range_end = 0, sigma = 0, ambiguous = 0, edge = 0, doubtful = 0;
};

// What pass 1 makes of pixel x of an output row from its window costs `vol` ([D][W]) and the row's winners in
// `b`: a disparity with its σ_d (kValid), the coarse disparity alone when a second pass refines it (kCoarse), or
// the check that rejected it. `noise` is the pixel's image noise σ_n (grey levels).
enum class PixelOutcome { kValid, kCoarse, kNoMatch, kFlat, kRangeEnd, kAmbiguous, kLeftRight, kSigma, kCount };

PixelOutcome DecidePixel(const SpaceTimeMatcherOptions& options_, const BandBuffers& b, const float* vol, int W, int D,
                         int dmin, int x, double noise, double window_samples, bool refine, float* disparity_out,
                         float* sigma_out) {
  const int di = b.arg_left[x];
  if (di < 0) return PixelOutcome::kNoMatch;
  const int d = dmin + di;
  const float c0 = vol[static_cast<size_t>(di) * W + x];
  // The best cost must beat every disparity at least 2 away by the margin, else the match is ambiguous (repeated
  // texture, or none) and its small σ from the curvature would be a lie.
  const bool unique = !(options_.uniqueness_ratio > 0.0) ||
                      !(b.second[x] < c0 * static_cast<float>(1.0 + options_.uniqueness_ratio) + 1e-6f);
  // The parabola needs both neighbours inside the search range and inside the right image. A distinct minimum at
  // an end of the range is most likely a match beyond it (below disparity 0 nothing lies: that end is flat).
  if (di == 0 && dmin <= 0) return unique ? PixelOutcome::kFlat : PixelOutcome::kAmbiguous;
  if (di == 0 || di == D - 1) return unique ? PixelOutcome::kRangeEnd : PixelOutcome::kAmbiguous;
  if (x - (d + 1) < 0 || x - (d - 1) >= W) return PixelOutcome::kFlat;
  if (!unique) return PixelOutcome::kAmbiguous;
  const float cm = vol[static_cast<size_t>(di - 1) * W + x];
  const float cp = vol[static_cast<size_t>(di + 1) * W + x];
  const double curvature = static_cast<double>(cm) - 2.0 * c0 + cp;
  if (!(curvature > 1e-6 * (std::abs(c0) + 1e-3))) return PixelOutcome::kFlat;
  if (options_.left_right_max_diff_px >= 0.0) {
    const int xr = x - d;
    const int dr = b.arg_right[xr] < 0 ? std::numeric_limits<int>::min() / 2 : dmin + b.arg_right[xr];
    if (std::abs(d - dr) > options_.left_right_max_diff_px) return PixelOutcome::kLeftRight;
  }
  const double disparity = d + std::clamp(0.5 * (cm - cp) / curvature, -0.5, 0.5);
  if (refine) {
    *disparity_out = static_cast<float>(disparity);  // coarse: refined in the second pass
    return PixelOutcome::kCoarse;
  }
  // Linearising the right image about the minimum gives var(d̂) = 2σ_n²/Σg² with noise σ_n in both images, and
  // the cost curvature is C″ = 2Σg², so σ_pred² = 4σ_n²/C″ (docs/design.md §2 writes the same relation for a cost
  // scaled by ½). σ_pred² = 4σ_eff²/C″ + p₂/(1 + p₂)·(d₂ − d)², see SpaceTimeMatcherOptions.
  double noise2 = noise * noise;
  if (options_.residual_noise) noise2 = std::max(noise2, c0 / (2.0 * window_samples));
  double var_pred = 4.0 * noise2 / curvature;
  if (options_.ambiguity_weight > 0.0 && b.arg_second[x] >= 0) {
    const double p = std::exp(-(b.second[x] - c0) / (4.0 * noise2));
    const double dd = b.arg_second[x] - di;
    var_pred += options_.ambiguity_weight * p / (1.0 + p) * dd * dd;
  }
  const double sigma_pred = std::sqrt(var_pred);
  const double sigma = std::sqrt(options_.sigma_floor_px * options_.sigma_floor_px +
                                 options_.sigma_scale * options_.sigma_scale * sigma_pred * sigma_pred);
  if (options_.max_sigma_disparity_px > 0.0 && sigma > options_.max_sigma_disparity_px) return PixelOutcome::kSigma;
  *disparity_out = static_cast<float>(disparity);
  *sigma_out = static_cast<float>(sigma);
  return PixelOutcome::kValid;
}

// Pass 1: per band of rows, the w×w×T window costs of every disparity, winner-take-all with the parabola,
// the checks, and σ_d from the curvature (with Gauss–Newton steps the coarse disparity only).
void BlockMatchPass(const SpaceTimeMatcherOptions& options_, const Sequence& L, const Sequence& R,
                    const std::vector<float>& noise_left, int T, DisparityResult* out, MatchCounts* counts) {
  DisparityResult& result = *out;
  const int W = L.width, H = L.height;
  const int D = options_.num_disparities;
  const int dmin = options_.min_disparity_px;
  const int w = options_.window_px;
  const int r = w / 2;
  const int band = options_.rows_per_task;
  const int num_bands = (H + band - 1) / band;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const double window_samples = static_cast<double>(w) * w * T;
  constexpr size_t kOutcomes = static_cast<size_t>(PixelOutcome::kCount);
  std::array<std::atomic<int>, kOutcomes> totals{};  // pixels per outcome, over all bands
  tbb::enumerable_thread_specific<BandBuffers> buffers;
  tbb::parallel_for(tbb::blocked_range<int>(0, num_bands, 1), [&](const tbb::blocked_range<int>& range) {
    BandBuffers& b = buffers.local();
    b.e.resize(static_cast<size_t>(W + 2 * r));
    b.hs.resize(W);
    b.best_left.resize(W);
    b.best_right.resize(W);
    b.second.resize(W);
    b.arg_left.resize(W);
    b.arg_right.resize(W);
    b.arg_second.resize(W);
    for (int band_index = range.begin(); band_index < range.end(); ++band_index) {
      const int y0 = band_index * band;
      const int y1 = std::min(H, y0 + band);
      const int rows = y1 - y0;
      // Rows enter the window one at a time; per input row and disparity: the temporal cost, the w-tap sum
      // along x and the running column sum (each row enters once and leaves once, so the w×w×T window costs
      // O(T + w) per pixel and disparity). Once w rows are in, volume holds all D window costs of one output
      // row: winner-take-all, runner-up and the right view's winners come from it; no band volume is kept.
      b.ring.assign(static_cast<size_t>(w) * D * W, 0.0f);
      b.volume.assign(static_cast<size_t>(D) * W, 0.0f);
      std::array<int, kOutcomes> band_counts{};
      for (int k = 0; k < rows + 2 * r; ++k) {
        const int yc = std::clamp(y0 - r + k, 0, H - 1);
        const float* lrow = L.row(yc);
        const float* rrow = R.row(yc);
        float* ring_row = b.ring.data() + static_cast<size_t>(k % w) * D * W;
        for (int di = 0; di < D; ++di) {
          TemporalCostRow(lrow, rrow, W, T, dmin + di, r, b.e.data());
          WindowSumRow(b.e.data(), W, w, b.hs.data(), ring_row + static_cast<size_t>(di) * W,
                       b.volume.data() + static_cast<size_t>(di) * W);
        }
        if (k < 2 * r) continue;
        const int y = y0 + k - 2 * r;
        const float* vol = b.volume.data();
        WinnerTakeAllRow(vol, W, D, dmin, b.best_left.data(), b.arg_left.data(), b.best_right.data(),
                         b.arg_right.data());
        const bool unique_test = options_.uniqueness_ratio > 0.0;
        if (unique_test || options_.ambiguity_weight > 0.0) {
          RunnerUpRow(vol, W, D, dmin, b.arg_left.data(), b.second.data(), b.arg_second.data());
        }
        float* out_d = result.disparity_px.ptr<float>(y);
        float* out_s = result.sigma_disparity_px.ptr<float>(y);
        const bool refine = options_.subpixel_iterations > 0;
        for (int x = 0; x < W; ++x) {
          out_d[x] = nan;
          out_s[x] = nan;
          const double noise =
              options_.image_noise_gray * (noise_left.empty() ? 1.0 : noise_left[static_cast<size_t>(y) * W + x]);
          const PixelOutcome outcome =
              DecidePixel(options_, b, vol, W, D, dmin, x, noise, window_samples, refine, &out_d[x], &out_s[x]);
          ++band_counts[static_cast<size_t>(outcome)];
        }
      }
      for (size_t k = 0; k < kOutcomes; ++k) totals[k] += band_counts[k];
    }
  });
  auto total = [&](PixelOutcome o) { return totals[static_cast<size_t>(o)].load(); };
  counts->valid = total(PixelOutcome::kValid);
  counts->left_right = total(PixelOutcome::kLeftRight);
  counts->flat = total(PixelOutcome::kFlat);
  counts->range_end = total(PixelOutcome::kRangeEnd);
  counts->sigma = total(PixelOutcome::kSigma);
  counts->ambiguous = total(PixelOutcome::kAmbiguous);
}

// Pass 2 (subpixel_iterations > 0): Gauss–Newton steps from the coarse disparity, with their σ_d.
void RefineSubpixelPass(const SpaceTimeMatcherOptions& options_, const Sequence& L, const Sequence& R,
                        const std::vector<float>& noise_left, const std::vector<float>& noise_right,
                        DisparityResult* out, MatchCounts* counts) {
  DisparityResult& result = *out;
  const int W = L.width, H = L.height;
  const int r = options_.window_px / 2;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const cv::Mat coarse = result.disparity_px.clone();
  const PixelMajor Lp = ToPixelMajor(L), Rp = ToPixelMajor(R);
  std::atomic<int> refined{0}, failed{0}, too_uncertain{0};
  tbb::parallel_for(0, H, [&](int y) {
    float* out_d = result.disparity_px.ptr<float>(y);
    float* out_s = result.sigma_disparity_px.ptr<float>(y);
    const float* c = coarse.ptr<float>(y);
    int row_ok = 0, row_failed = 0, row_sigma = 0;
    for (int x = 0; x < W; ++x) {
      if (!std::isfinite(c[x])) continue;
      double slope_x = 0.0, slope_y = 0.0;
      WindowSlopes(coarse, x, y, r, &slope_x, &slope_y);
      double disparity = c[x], sigma_pred = 0.0;
      if (!RefineGaussNewton(Lp, Rp, noise_left, noise_right, x, y, r, options_.subpixel_iterations,
                             options_.image_noise_gray, slope_x, slope_y, &disparity, &sigma_pred) ||
          std::abs(disparity - c[x]) > 1.0) {
        out_d[x] = nan;
        ++row_failed;
        continue;
      }
      const double sigma = std::sqrt(options_.sigma_floor_px * options_.sigma_floor_px +
                                     options_.sigma_scale * options_.sigma_scale * sigma_pred * sigma_pred);
      if (options_.max_sigma_disparity_px > 0.0 && sigma > options_.max_sigma_disparity_px) {
        out_d[x] = nan;
        ++row_sigma;
        continue;
      }
      out_d[x] = static_cast<float>(disparity);
      out_s[x] = static_cast<float>(sigma);
      ++row_ok;
    }
    refined += row_ok;
    failed += row_failed;
    too_uncertain += row_sigma;
  });
  counts->valid = refined.load();
  counts->flat += failed.load();
  counts->sigma += too_uncertain.load();
}

// Pass 3: the neighbour term of σ_d and the edge test (dropped, or kept as doubtful with an inflated σ_d).
void NeighbourPass(const SpaceTimeMatcherOptions& options_, const Sequence& L, const Sequence& R,
                   DisparityResult* out, MatchCounts* counts) {
  DisparityResult& result = *out;
  const int W = L.width, H = L.height;
  const int r = options_.window_px / 2;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const int D = options_.num_disparities;
  const int dmin = options_.min_disparity_px;
  const bool edge_reject = options_.edge_reject_jump_px >= 0.0;
  const bool doubt = !edge_reject && options_.doubtful_jump_px >= 0.0;
  // σ_d² += J: the mean over the valid w×w neighbours of (d_n − d − g·Δ)² for the differences beyond
  // neighbour_jump_px (window straddling a depth edge, isolated mismatches), g the disparity's slope at the
  // pixel (the median forward difference in x and in y over the window, which a depth edge crossing it does not
  // move): a slanted surface is not a doubt (a sphere's parts beyond 0.25 px/px had σ_d ~1.5× its errors,
  // measured with the raw differences). A pixel within r + 1 of a hole
  // or of a neighbour more than the edge threshold per pixel of distance away straddles a depth edge or an
  // occlusion (its cost mixes two surfaces): with edge_reject_jump_px it is dropped, with doubtful_jump_px
  // it is kept and σ_d² gains doubtful_sigma_px² plus the largest such jump squared.
  const cv::Mat d = result.disparity_px.clone();
  const double jump = options_.neighbour_jump_px;
  const double edge_jump = edge_reject ? options_.edge_reject_jump_px : options_.doubtful_jump_px;
  const bool edge_test = edge_reject || doubt;
  const bool add_j = options_.neighbour_jump_px >= 0.0;
  const double doubt_var = options_.doubtful_sigma_px * options_.doubtful_sigma_px;
  const int verify_r = options_.doubtful_verify_window_px > 0 ? options_.doubtful_verify_window_px / 2 : -1;
  std::atomic<int> dropped{0}, dropped_edge{0}, doubtful{0};
  // The median of the finite forward differences d(p + step) − d(p) over the inner window around (x, y); 0 when
  // there is none.
  const auto median_slope = [&](int x, int y, int sx, int sy, std::vector<float>* scratch) {
    scratch->clear();
    for (int yy = std::max(0, y - r); yy <= std::min(H - 1 - sy, y + r); ++yy) {
      const float* row = d.ptr<float>(yy);
      const float* next = d.ptr<float>(yy + sy);
      for (int xx = std::max(0, x - r); xx <= std::min(W - 1 - sx, x + r); ++xx) {
        const float diff = next[xx + sx] - row[xx];
        if (std::isfinite(diff)) scratch->push_back(diff);
      }
    }
    if (scratch->empty()) return 0.0;
    const auto mid = scratch->begin() + static_cast<std::ptrdiff_t>(scratch->size() / 2);
    std::nth_element(scratch->begin(), mid, scratch->end());
    return static_cast<double>(*mid);
  };
  tbb::parallel_for(0, H, [&](int y) {
    float* out_d = result.disparity_px.ptr<float>(y);
    float* out_s = result.sigma_disparity_px.ptr<float>(y);
    const float* dr = d.ptr<float>(y);
    int row_dropped = 0, row_edge = 0, row_doubtful = 0;
    std::vector<float> scratch;
    for (int x = 0; x < W; ++x) {
      const float dc = dr[x];
      if (!std::isfinite(dc)) continue;
      double j2 = 0.0, max_jump2 = 0.0;
      int n = 0;
      bool straddles = false;
      // The edge test looks one ring beyond the window: a band of wrong disparities can be r pixels wide
      // (the window's reach into the other surface) plus the mixed pixel on the edge itself (measured on
      // the box's grazing top face in bench_stereo --quality=synth: radius r left such pixels 6 px off).
      const int re = edge_test ? r + 1 : r;
      // A neighbour counts when its difference and its departure from the plane of slope (gx, gy) both exceed
      // the threshold; the slope is estimated only where a difference does (its median costs what the rest of
      // the pass does).
      const auto scan = [&](double gx, double gy) {
        j2 = max_jump2 = 0.0;
        n = 0;
        straddles = false;
        for (int yy = std::max(0, y - re); yy <= std::min(H - 1, y + re); ++yy) {
          const float* row = d.ptr<float>(yy);
          for (int xx = std::max(0, x - re); xx <= std::min(W - 1, x + re); ++xx) {
            const double diff = row[xx] - dc;
            const bool inner = std::abs(xx - x) <= r && std::abs(yy - y) <= r;
            if (!std::isfinite(diff)) {
              straddles = true;
              continue;
            }
            const double off_plane = diff - gx * (xx - x) - gy * (yy - y);
            if (inner) {
              ++n;
              j2 += std::abs(diff) > jump && std::abs(off_plane) > jump ? off_plane * off_plane : 0.0;
            }
            const double edge = edge_jump * std::max(std::abs(xx - x), std::abs(yy - y));
            if (edge_test && std::abs(diff) > edge && std::abs(off_plane) > edge) {
              straddles = true;
              max_jump2 = std::max(max_jump2, off_plane * off_plane);
            }
          }
        }
      };
      scan(0.0, 0.0);
      if (j2 > 0.0 || max_jump2 > 0.0) scan(median_slope(x, y, 1, 0, &scratch), median_slope(x, y, 0, 1, &scratch));
      if (edge_reject && straddles) {
        out_d[x] = out_s[x] = nan;
        ++row_edge;
        continue;
      }
      double var = static_cast<double>(out_s[x]) * out_s[x];
      if (add_j) var += j2 / n;
      if (doubt && straddles) {
        if (verify_r >= 0) {
          const int ds = SmallWindowDisparity(L, R, x, y, verify_r, dmin, D);
          if (!(std::abs(static_cast<double>(ds) - dc) <= 1.0)) {
            out_d[x] = out_s[x] = nan;
            ++row_edge;
            continue;
          }
        }
        var += doubt_var + max_jump2;
        ++row_doubtful;
      }
      const double sigma = std::sqrt(var);
      out_s[x] = static_cast<float>(sigma);
      if (options_.max_sigma_disparity_px > 0.0 && sigma > options_.max_sigma_disparity_px) {
        out_d[x] = out_s[x] = nan;
        ++row_dropped;
      }
    }
    dropped += row_dropped;
    dropped_edge += row_edge;
    doubtful += row_doubtful;
  });
  counts->valid -= dropped.load() + dropped_edge.load();
  counts->sigma += dropped.load();
  counts->edge = dropped_edge.load();
  counts->doubtful = doubtful.load();
}

}  // namespace

DisparityResult SpaceTimeMatcher::Match(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right) {
  CheckStereoSequence(left, right);
  const auto start = std::chrono::steady_clock::now();
  summary_ = {};
  const int T = static_cast<int>(left.size());
  SpaceTimeCost cost = options_.cost;
  if (cost == SpaceTimeCost::kAuto) cost = T >= 3 ? SpaceTimeCost::kZnccTime : SpaceTimeCost::kSsd;
  RB_CHECK(!(cost == SpaceTimeCost::kZnccTime && T < 2), "ZNCC over time needs at least 2 frames, got ", T);
  summary_.cost_used = cost;
  summary_.frames = T;

  Sequence L = Interleave(left);
  Sequence R = Interleave(right);
  std::vector<float> noise_left, noise_right;
  if (cost == SpaceTimeCost::kZnccSpace) {
    NormaliseSpatially(&L, options_.window_px, options_.image_noise_gray, &noise_left);
    NormaliseSpatially(&R, options_.window_px, options_.image_noise_gray, &noise_right);
  }
  if (cost == SpaceTimeCost::kZnccTime) {
    NormaliseTemporally(&L, options_.image_noise_gray, &noise_left);
    NormaliseTemporally(&R, options_.image_noise_gray, &noise_right);
  }

  DisparityResult result;
  result.disparity_px.create(L.height, L.width, CV_32F);
  result.sigma_disparity_px.create(L.height, L.width, CV_32F);
  result.frames_used = T;
  MatchCounts counts;
  BlockMatchPass(options_, L, R, noise_left, T, &result, &counts);
  if (options_.subpixel_iterations > 0) RefineSubpixelPass(options_, L, R, noise_left, noise_right, &result, &counts);
  const bool edge_reject = options_.edge_reject_jump_px >= 0.0;
  const bool doubt = !edge_reject && options_.doubtful_jump_px >= 0.0;
  if (options_.neighbour_jump_px >= 0.0 || edge_reject || doubt) NeighbourPass(options_, L, R, &result, &counts);
  summary_.valid_pixels = counts.valid;
  summary_.rejected_left_right = counts.left_right;
  summary_.rejected_flat = counts.flat;
  summary_.rejected_range_end = counts.range_end;
  summary_.rejected_sigma = counts.sigma;
  summary_.rejected_ambiguous = counts.ambiguous;
  summary_.rejected_edge = counts.edge;
  summary_.doubtful = counts.doubtful;
  result.valid_fraction = static_cast<double>(counts.valid) / (static_cast<double>(L.width) * L.height);
  result.range_end_fraction = static_cast<double>(counts.range_end) / (static_cast<double>(L.width) * L.height);
  result.match_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace rangebayes
