// Stereo, space-time stereo and triangulation: speed (Google Benchmark) and quality on Middlebury, the
// Gray-code plane sequence and synthetic scenes. See BENCHMARKS.md for the commands and numbers.
//
//   bench_stereo [google benchmark flags]          speed: space-time 640×480 T=8, SGBM, triangulation
//   bench_stereo --quality=v2 [--data=DIR]          Middlebury v2: our SGBM path vs cv::StereoSGBM, bad-1.0 nonocc
//   bench_stereo --quality=2014 [--data=DIR]        Middlebury 2014 quarter: bad-2.0, σ_d ranking
//   bench_stereo --quality=graycode [--data=DIR]    Gray-code plane: disparity noise about a fitted plane
//   bench_stereo --quality=synth                    synthetic scenes: space-time vs SGBM depth RMS
//   bench_stereo --quality=sigmafit                 σ_d model (floor, scale) fitted on synthetic scenes
// DIR defaults to ../shared/data/stereo (relative to the repository root).
#include <benchmark/benchmark.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <tbb/global_control.h>
#include <vector>

#include "reconstruction/triangulate.h"
#include "stereo/depth_frame.h"
#include "stereo/disparity_io.h"
#include "stereo/evaluate.h"
#include "stereo/sgbm_matcher.h"
#include "stereo/spacetime_matcher.h"
#include "stereo/synth.h"

namespace rb = rangebayes;

namespace {

// ---------------------------------------------------------------- speed

const rb::SynthRecording& Scene640(int frames) {
  static rb::SynthRecording rec = [] {
    rb::SynthOptions o;
    o.scene = rb::SynthScene::kPlanes;
    o.width = 640;
    o.height = 480;
    o.frames = 16;
    o.supersample = 2;
    return rb::RenderSynthetic(o);
  }();
  static std::vector<rb::SynthRecording> cache;
  (void)frames;
  return rec;
}

rb::SpaceTimeMatcherOptions Options640() {
  rb::SpaceTimeMatcherOptions m;
  m.min_disparity_px = 16;
  m.num_disparities = 64;
  m.window_px = 5;
  return m;
}

void BM_SpaceTime640(benchmark::State& state) {
  const int T = static_cast<int>(state.range(0));
  const rb::SynthRecording& rec = Scene640(T);
  const std::vector<cv::Mat> left(rec.left.begin(), rec.left.begin() + T);
  const std::vector<cv::Mat> right(rec.right.begin(), rec.right.begin() + T);
  rb::SpaceTimeMatcherOptions m = Options640();
  m.subpixel_iterations = static_cast<int>(state.range(1));
  rb::SpaceTimeMatcher matcher(m);
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, static_cast<size_t>(state.range(2)));
  double valid = 0;
  for (auto _ : state) {
    const rb::DisparityResult r = matcher.Match(left, right);
    valid = r.valid_fraction;
    benchmark::DoNotOptimize(r.disparity_px.data);
  }
  state.counters["valid"] = valid;
}
// Args: frames T, Gauss–Newton sub-pixel iterations (0: parabola only), threads.
BENCHMARK(BM_SpaceTime640)
    ->ArgNames({"T", "gn", "threads"})
    ->Args({8, 0, 1})
    ->Args({8, 0, 2})
    ->Args({8, 2, 1})
    ->Args({8, 2, 2})
    ->Args({16, 0, 2})
    ->Args({1, 0, 2})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime();

void BM_Sgbm640(benchmark::State& state) {
  const rb::SynthRecording& rec = Scene640(1);
  rb::SgbmMatcherOptions o;
  o.min_disparity_px = 16;
  o.num_disparities = 64;
  rb::SgbmMatcher matcher(o);
  for (auto _ : state) {
    const rb::DisparityResult r = matcher.Match({rec.left[0]}, {rec.right[0]});
    benchmark::DoNotOptimize(r.disparity_px.data);
  }
}
BENCHMARK(BM_Sgbm640)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

void BM_Triangulate640(benchmark::State& state) {
  const rb::SynthRecording& rec = Scene640(8);
  const cv::Mat sigma(rec.disparity_px.size(), CV_32F, cv::Scalar(0.1));
  const rb::DepthFrame frame =
      rb::DepthFromDisparity(rec.disparity_px, sigma, rec.intrinsics, rec.rig.baseline_m(), 0.0);
  rb::TriangulateOptions o;
  o.downsample = static_cast<int>(state.range(0));
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, static_cast<size_t>(state.range(1)));
  int faces = 0;
  for (auto _ : state) {
    rb::TriangulateSummary s;
    const rb::NoisyMesh mesh = rb::TriangulateDepth(frame, o, &s);
    faces = s.faces;
    benchmark::DoNotOptimize(mesh.mesh.V.data());
  }
  state.counters["faces"] = faces;
}
// Args: downsample factor, threads.
BENCHMARK(BM_Triangulate640)
    ->ArgNames({"downsample", "threads"})
    ->Args({1, 1})
    ->Args({1, 2})
    ->Args({4, 2})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->MeasureProcessCPUTime();

// ---------------------------------------------------------------- quality helpers

struct Spread {
  double rms = 0, robust_sigma = 0;
  size_t n = 0;
};

Spread SpreadOf(std::vector<double> e) {
  Spread s;
  s.n = e.size();
  if (e.empty()) return s;
  double sum2 = 0;
  for (double v : e) sum2 += v * v;
  s.rms = std::sqrt(sum2 / e.size());
  std::vector<double> a(e.size());
  std::nth_element(e.begin(), e.begin() + e.size() / 2, e.end());
  const double med = e[e.size() / 2];
  for (size_t i = 0; i < e.size(); ++i) a[i] = std::abs(e[i] - med);
  std::nth_element(a.begin(), a.begin() + a.size() / 2, a.end());
  s.robust_sigma = 1.4826 * a[a.size() / 2];
  return s;
}

void QualityV2(const std::string& data) {
  std::printf("Middlebury v2, non-occluded, bad-1.0 (holes as errors / excluded, coverage)\n");
  std::printf("%-8s %28s %28s\n", "scene", "rangebayes SgbmMatcher", "cv::StereoSGBM 3-way");
  for (const char* name : {"tsukuba", "venus", "teddy", "cones"}) {
    const rb::MiddleburyScene s = rb::ReadMiddleburyScene(data + "/middlebury_v2_2001_2003/" + name);
    rb::SgbmMatcherOptions o;
    o.num_disparities = s.num_disparities;
    rb::SgbmMatcher ours(o);
    const rb::DisparityResult r = ours.Match({s.left}, {s.right});
    const auto ev = rb::EvaluateDisparity(r.disparity_px, s.gt_disparity_px, s.mask_nonocc);
    // OpenCV's own, used the way its stereo_match sample does (same parameters), converted here only for
    // scoring: negative fixed-point values are its "invalid".
    const int num = (s.num_disparities + 15) / 16 * 16, bs = 5, cn = s.left.channels();
    auto sgbm = cv::StereoSGBM::create(0, num, bs, 8 * cn * bs * bs, 32 * cn * bs * bs, 1, 63, 10, 100, 2,
                                       cv::StereoSGBM::MODE_SGBM_3WAY);
    cv::Mat d16, d;
    sgbm->compute(s.left, s.right, d16);
    d16.convertTo(d, CV_32F, 1.0 / 16);
    d.setTo(std::numeric_limits<float>::quiet_NaN(), d16 < 0);
    const auto ev_cv = rb::EvaluateDisparity(d, s.gt_disparity_px, s.mask_nonocc);
    std::printf("%-8s %8.2f%% / %6.2f%% (%5.1f%%)  %8.2f%% / %6.2f%% (%5.1f%%)\n", name, 100 * ev.bad_with_holes[1],
                100 * ev.bad_valid_only[1], 100 * ev.coverage, 100 * ev_cv.bad_with_holes[1],
                100 * ev_cv.bad_valid_only[1], 100 * ev_cv.coverage);
  }
}

void Quality2014(const std::string& data) {
  std::printf("Middlebury 2014 quarter (trainingQ), non-occluded, bad-2.0 (holes as errors / excluded, coverage)\n");
  std::printf("%-12s %26s %26s %22s\n", "scene", "SGBM 3-way", "block T=1 (w=9, sigma)", "sigma top/bottom decile");
  double sum_sgbm = 0, sum_block = 0, sum_block_valid = 0, sum_sgbm_valid = 0, sum_zncc = 0, sum_zncc_valid = 0;
  std::vector<double> all_err;
  std::vector<float> all_sigma;
  int n = 0;
  const std::string root = data + "/middlebury_2014_trainingQ";
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(root)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  for (const auto& name : names) {
    const rb::MiddleburyScene s = rb::ReadMiddleburyScene(root + "/" + name);
    rb::SgbmMatcherOptions so;
    so.num_disparities = s.num_disparities;
    const auto rs = rb::SgbmMatcher(so).Match({s.left}, {s.right});
    const auto es = rb::EvaluateDisparity(rs.disparity_px, s.gt_disparity_px, s.mask_nonocc);
    rb::SpaceTimeMatcherOptions bo;
    bo.num_disparities = std::max(3, s.num_disparities);
    bo.window_px = 9;
    bo.image_noise_gray = 2.0;
    const auto rb_ = rb::SpaceTimeMatcher(bo).Match({s.left}, {s.right});
    const auto eb = rb::EvaluateDisparity(rb_.disparity_px, s.gt_disparity_px, s.mask_nonocc);
    rb::SpaceTimeMatcherOptions zo = bo;
    zo.cost = rb::SpaceTimeCost::kZnccSpace;
    const auto rz = rb::SpaceTimeMatcher(zo).Match({s.left}, {s.right});
    const auto ez = rb::EvaluateDisparity(rz.disparity_px, s.gt_disparity_px, s.mask_nonocc);
    sum_zncc += ez.bad_with_holes[2];
    sum_zncc_valid += ez.bad_valid_only[2];
    // σ ranking within the scene.
    std::vector<std::pair<float, double>> se;
    for (int y = 0; y < s.left.rows; ++y)
      for (int x = 0; x < s.left.cols; ++x) {
        const float d = rb_.disparity_px.at<float>(y, x), g = s.gt_disparity_px.at<float>(y, x);
        if (!std::isfinite(d) || !std::isfinite(g) || s.mask_nonocc.at<uchar>(y, x) == 0) continue;
        se.push_back({rb_.sigma_disparity_px.at<float>(y, x), d - g});
        all_sigma.push_back(se.back().first);
        all_err.push_back(se.back().second);
      }
    std::sort(se.begin(), se.end(), [](auto& a, auto& b) { return a.first < b.first; });
    std::vector<double> lo, hi;
    const size_t dec = se.size() / 10;
    for (size_t i = 0; i < dec; ++i) lo.push_back(se[i].second);
    for (size_t i = se.size() - dec; i < se.size(); ++i) hi.push_back(se[i].second);
    const Spread sl = SpreadOf(lo), sh = SpreadOf(hi);
    std::printf("%-12s %8.2f%% / %6.2f%% (%4.1f%%) %8.2f%% / %6.2f%% (%4.1f%%) rms %5.1fx robust %5.1fx\n",
                name.c_str(), 100 * es.bad_with_holes[2], 100 * es.bad_valid_only[2], 100 * es.coverage,
                100 * eb.bad_with_holes[2], 100 * eb.bad_valid_only[2], 100 * eb.coverage, sh.rms / sl.rms,
                sh.robust_sigma / sl.robust_sigma);
    sum_sgbm += es.bad_with_holes[2];
    sum_sgbm_valid += es.bad_valid_only[2];
    sum_block += eb.bad_with_holes[2];
    sum_block_valid += eb.bad_valid_only[2];
    ++n;
  }
  std::vector<size_t> order(all_err.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return all_sigma[a] < all_sigma[b]; });
  std::vector<double> lo, hi;
  const size_t dec = order.size() / 10;
  for (size_t i = 0; i < dec; ++i) lo.push_back(all_err[order[i]]);
  for (size_t i = order.size() - dec; i < order.size(); ++i) hi.push_back(all_err[order[i]]);
  const Spread sl = SpreadOf(lo), sh = SpreadOf(hi);
  std::printf("mean bad-2.0: SGBM %.2f%% (holes excluded %.2f%%), block T=1 %.2f%% (holes excluded %.2f%%)\n",
              100 * sum_sgbm / n, 100 * sum_sgbm_valid / n, 100 * sum_block / n, 100 * sum_block_valid / n);
  std::printf("mean bad-2.0: block T=1 with --cost zncc-space %.2f%% (holes excluded %.2f%%)\n", 100 * sum_zncc / n,
              100 * sum_zncc_valid / n);
  std::printf("sigma_d ranking, all scenes pooled: bottom decile rms %.3f px (robust %.3f), top decile rms %.3f px "
              "(robust %.3f): ratio %.1fx (robust %.1fx)\n",
              sl.rms, sl.robust_sigma, sh.rms, sh.robust_sigma, sh.rms / sl.rms, sh.robust_sigma / sl.robust_sigma);
}

// NumPy v1 .npy, little-endian float32, C order, 2-D.
cv::Mat ReadNpyFloat(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char magic[6];
  in.read(magic, 6);
  if (std::memcmp(magic, "\x93NUMPY", 6) != 0) throw std::runtime_error(path + ": not a .npy file");
  unsigned char ver[2];
  in.read(reinterpret_cast<char*>(ver), 2);
  unsigned short hlen = 0;
  in.read(reinterpret_cast<char*>(&hlen), 2);
  std::string header(hlen, ' ');
  in.read(header.data(), hlen);
  if (header.find("'<f4'") == std::string::npos || header.find("False") == std::string::npos) {
    throw std::runtime_error(path + ": expected little-endian float32 in C order");
  }
  const auto p = header.find("shape");
  int h = 0, w = 0;
  std::sscanf(header.c_str() + header.find('(', p), "(%d, %d)", &h, &w);
  cv::Mat m(h, w, CV_32F);
  in.read(reinterpret_cast<char*>(m.data), static_cast<std::streamsize>(m.total() * 4));
  return m;
}

// Robust plane fit d = a·u + b·v + c (iteratively reweighted by a 3σ cut on the robust residual σ).
Spread PlaneResiduals(const cv::Mat& d, const cv::Mat& mask) {
  std::vector<Eigen::Vector3d> pts;
  for (int y = 0; y < d.rows; ++y)
    for (int x = 0; x < d.cols; ++x)
      if (mask.at<uchar>(y, x) && std::isfinite(d.at<float>(y, x))) pts.push_back({double(x), double(y), d.at<float>(y, x)});
  std::vector<bool> in(pts.size(), true);
  Eigen::Vector3d p(0, 0, 0);
  std::vector<double> res;
  for (int iter = 0; iter < 6; ++iter) {
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    for (size_t i = 0; i < pts.size(); ++i) {
      if (!in[i]) continue;
      const Eigen::Vector3d row(pts[i].x(), pts[i].y(), 1.0);
      A += row * row.transpose();
      b += row * pts[i].z();
    }
    p = A.ldlt().solve(b);
    res.clear();
    for (const auto& q : pts) res.push_back(q.z() - (p(0) * q.x() + p(1) * q.y() + p(2)));
    const Spread s = SpreadOf(res);
    for (size_t i = 0; i < pts.size(); ++i) in[i] = std::abs(res[i]) < 3.0 * s.robust_sigma;
  }
  std::vector<double> inliers;
  for (size_t i = 0; i < pts.size(); ++i)
    if (in[i]) inliers.push_back(res[i]);
  Spread all = SpreadOf(res), trimmed = SpreadOf(inliers);
  all.rms = trimmed.rms;  // rms of the 3σ inliers; robust σ from all
  all.n = inliers.size();
  return all;
}

void QualityGrayCode(const std::string& data) {
  const std::string dir = data + "/graycode_stereo_d435_zengzhik";
  const auto load = [&](int i, const char* side) {
    char name[64];
    std::snprintf(name, sizeof name, "/frames/%02d-%s.png", i, side);
    cv::Mat m = cv::imread(dir + name, cv::IMREAD_GRAYSCALE);
    if (m.empty()) throw std::runtime_error(dir + name + ": unreadable");
    return m;
  };
  const cv::Mat gt = ReadNpyFloat(dir + "/disparity_graycode.npy");
  // Evaluate on the projection surface: the pixels the authors decoded (pseudo ground truth > 0), eroded so
  // that windows do not reach its border.
  cv::Mat mask = gt > 0;
  cv::erode(mask, mask, cv::Mat::ones(9, 9, CV_8U));
  const Spread gt_spread = PlaneResiduals(gt, mask);
  std::printf("Gray-code plane (1280x720), %d evaluated pixels; pseudo ground truth about its own plane: robust "
              "sigma %.3f px\n", cv::countNonZero(mask), gt_spread.robust_sigma);
  std::printf("%-40s %10s %12s %10s %9s\n", "method", "robust s", "rms(3s in)", "coverage", "time ms");
  const auto report = [&](const char* name, const rb::DisparityResult& r) {
    const Spread s = PlaneResiduals(r.disparity_px, mask);
    int valid = 0;
    for (int y = 0; y < mask.rows; ++y)
      for (int x = 0; x < mask.cols; ++x) valid += mask.at<uchar>(y, x) && std::isfinite(r.disparity_px.at<float>(y, x));
    std::printf("%-40s %10.3f %12.3f %9.1f%% %9.0f\n", name, s.robust_sigma, s.rms,
                100.0 * valid / cv::countNonZero(mask), r.match_ms);
  };
  {
    rb::SgbmMatcherOptions o;
    o.min_disparity_px = 48;
    o.num_disparities = 64;
    report("SGBM 3-way, frame 00 (wallpaper)", rb::SgbmMatcher(o).Match({load(0, "left")}, {load(0, "right")}));
  }
  for (int T : {1, 8, 16, 24}) {
    std::vector<cv::Mat> l, r;
    for (int i = 3; i < 3 + T; ++i) {
      // Finest bits last: a window of T frames takes the last T of frames 03-26.
      const int f = 26 - T + 1 + (i - 3);
      l.push_back(load(f, "left"));
      r.push_back(load(f, "right"));
    }
    if (T == 1) {
      l = {load(0, "left")};
      r = {load(0, "right")};
    }
    for (int gn : {0, 2}) {
      rb::SpaceTimeMatcherOptions o;
      o.min_disparity_px = 56;
      o.num_disparities = 48;
      o.window_px = T == 1 ? 9 : 5;
      o.subpixel_iterations = gn;
      char name[64];
      if (T == 1) {
        std::snprintf(name, sizeof name, "block T=1 w=9, frame 00, %s", gn ? "GN" : "parabola");
      } else {
        std::snprintf(name, sizeof name, "space-time T=%d w=5, frames %02d-26, %s", T, 26 - T + 1,
                      gn ? "GN" : "parabola");
      }
      report(name, rb::SpaceTimeMatcher(o).Match(l, r));
    }
  }
}

void QualitySynth() {
  std::printf("Synthetic scenes 320x240, f = 320 px, B = 0.1 m, random pattern; depth and disparity RMS over pixels\n"
              "both methods measured (depth-edge pixels included), frame 0 for SGBM\n");
  std::printf("%-9s %5s %6s %22s %22s %8s %10s %10s %8s\n", "scene", "noise", "T", "SGBM rms d / Z (mm)",
              "space-time d / Z (mm)", "ratio Z", "SGBM Z*", "ST Z*", "ratio*");
  std::printf("(* = pixels at least 3 px from a depth edge)\n");
  for (double noise : {2.0, 4.0}) {
    for (const auto scene : {rb::SynthScene::kPlanes, rb::SynthScene::kBox, rb::SynthScene::kSphere,
                             rb::SynthScene::kCylinder, rb::SynthScene::kStairs}) {
      for (int T : {8, 16}) {
        rb::SynthOptions so;
        so.scene = scene;
        so.frames = T;
        so.image_noise_gray = noise;
        so.seed = 5;
        const rb::SynthRecording rec = rb::RenderSynthetic(so);
        rb::SgbmMatcherOptions go;
        go.min_disparity_px = 8;
        go.num_disparities = 48;
        const auto rs = rb::SgbmMatcher(go).Match({rec.left[0]}, {rec.right[0]});
        rb::SpaceTimeMatcherOptions mo;
        mo.min_disparity_px = 8;
        mo.num_disparities = 48;
        mo.image_noise_gray = noise;
        const auto rt = rb::SpaceTimeMatcher(mo).Match(rec.left, rec.right);
        double sd_s = 0, sd_t = 0, sz_s = 0, sz_t = 0, ez_s = 0, ez_t = 0;
        int n = 0, ne = 0;
        const double fb = rec.intrinsics.fx_px * so.baseline_m;
        for (int y = 0; y < rec.depth_m.rows; ++y)
          for (int x = 0; x < rec.depth_m.cols; ++x) {
            const float a = rs.disparity_px.at<float>(y, x), b = rt.disparity_px.at<float>(y, x);
            const float g = rec.disparity_px.at<float>(y, x);
            if (!std::isfinite(a) || !std::isfinite(b) || !std::isfinite(g)) continue;
            sd_s += (a - g) * (a - g);
            sd_t += (b - g) * (b - g);
            const double z = fb / g;
            sz_s += std::pow(fb / a - z, 2);
            sz_t += std::pow(fb / b - z, 2);
            ++n;
            // Away from depth edges: no ground-truth disparity jump > 0.5 px within 3 px.
            bool edge = false;
            for (int k = -3; k <= 3 && !edge; ++k)
              for (int l = -3; l <= 3 && !edge; ++l) {
                const int yy = std::clamp(y + k, 0, rec.depth_m.rows - 1), xx = std::clamp(x + l, 0, rec.depth_m.cols - 1);
                edge = std::abs(rec.disparity_px.at<float>(yy, xx) - g) > 0.5 + 0.3 * (std::abs(k) + std::abs(l));
              }
            if (!edge) {
              ez_s += std::pow(fb / a - z, 2);
              ez_t += std::pow(fb / b - z, 2);
              ++ne;
            }
          }
        std::printf("%-9s %5.1f %6d %10.3f / %8.2f %10.3f / %8.2f %8.2f %10.2f %10.2f %8.2f\n",
                    rb::ToString(scene).c_str(), noise, T, std::sqrt(sd_s / n), 1000 * std::sqrt(sz_s / n),
                    std::sqrt(sd_t / n), 1000 * std::sqrt(sz_t / n), std::sqrt(sz_t / sz_s),
                    1000 * std::sqrt(ez_s / ne), 1000 * std::sqrt(ez_t / ne), std::sqrt(ez_t / ez_s));
      }
    }
  }
}

// Fits the σ_d model σ² = floor² + (k·σ_pred)² to the disparity errors of the space-time matcher on the
// synthetic scenes (planes, sphere, box, cylinder, stairs; 320×240, seeds 5 and 6, image noise 2), per T:
// maximum likelihood over a grid of floor and k, residuals beyond 5σ left out as outliers (re-cut after
// each fit). Prints the fit and the mean normalised squared residual per σ_pred quintile.
void QualitySigmaFit() {
  std::printf("sigma_d model fit: sigma^2 = floor^2 + (k*pred)^2, synthetic scenes 320x240, noise 2, seeds 5-6\n");
  for (int T : {1, 8, 16}) {
    std::vector<double> pred, err;
    for (const auto scene : {rb::SynthScene::kPlanes, rb::SynthScene::kSphere, rb::SynthScene::kBox,
                             rb::SynthScene::kCylinder, rb::SynthScene::kStairs}) {
      for (std::uint64_t seed : {5u, 6u}) {
        rb::SynthOptions so;
        so.scene = scene;
        so.frames = T;
        so.image_noise_gray = 2.0;
        so.seed = seed;
        const rb::SynthRecording rec = rb::RenderSynthetic(so);
        rb::SpaceTimeMatcherOptions mo;
        mo.min_disparity_px = 8;
        mo.num_disparities = 48;
        mo.image_noise_gray = 2.0;
        mo.sigma_floor_px = 0.0;
        mo.sigma_scale = 1.0;
        mo.neighbour_jump_px = -1.0;  // J is added outside the floor-plus-scale form
        const auto r = rb::SpaceTimeMatcher(mo).Match(rec.left, rec.right);
        for (int y = 0; y < rec.depth_m.rows; ++y)
          for (int x = 0; x < rec.depth_m.cols; ++x) {
            const float d = r.disparity_px.at<float>(y, x), g = rec.disparity_px.at<float>(y, x);
            if (!std::isfinite(d) || !std::isfinite(g)) continue;
            pred.push_back(r.sigma_disparity_px.at<float>(y, x));
            err.push_back(d - g);
          }
      }
    }
    std::vector<bool> in(err.size(), true);
    double best_f = 0, best_k = 1;
    for (int round = 0; round < 4; ++round) {
      double best_nll = std::numeric_limits<double>::infinity();
      for (double f = 0.0; f <= 0.3001; f += 0.01)
        for (double k = 0.5; k <= 6.0001; k += 0.1) {
          double nll = 0;
          for (size_t i = 0; i < err.size(); i += 7) {  // every 7th pixel: the grid search stays quick
            if (!in[i]) continue;
            const double s2 = f * f + k * k * pred[i] * pred[i];
            nll += std::log(s2) + err[i] * err[i] / s2;
          }
          if (nll < best_nll) {
            best_nll = nll;
            best_f = f;
            best_k = k;
          }
        }
      for (size_t i = 0; i < err.size(); ++i) {
        const double s2 = best_f * best_f + best_k * best_k * pred[i] * pred[i];
        in[i] = err[i] * err[i] <= 25.0 * s2;
      }
    }
    size_t outliers = 0;
    for (bool b : in) outliers += !b;
    std::vector<size_t> order;
    for (size_t i = 0; i < err.size(); ++i)
      if (in[i]) order.push_back(i);
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return pred[a] < pred[b]; });
    std::printf("T=%2d: floor %.3f px, scale %.2f; %zu pixels, %.2f%% beyond 5 sigma; mean z2 per pred quintile:", T,
                best_f, best_k, err.size(), 100.0 * outliers / err.size());
    for (int q = 0; q < 5; ++q) {
      double z2 = 0;
      const size_t a = order.size() * q / 5, b = order.size() * (q + 1) / 5;
      for (size_t i = a; i < b; ++i) {
        const size_t j = order[i];
        z2 += err[j] * err[j] / (best_f * best_f + best_k * best_k * pred[j] * pred[j]);
      }
      std::printf(" %.2f", z2 / (b - a));
    }
    std::printf("\n");
  }
}

}  // namespace

int main(int argc, char** argv) {
  std::string quality, data = "../shared/data/stereo";
  std::vector<char*> rest;
  for (int i = 0; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.rfind("--quality=", 0) == 0) {
      quality = a.substr(10);
    } else if (a.rfind("--data=", 0) == 0) {
      data = a.substr(7);
    } else {
      rest.push_back(argv[i]);
    }
  }
  try {
    if (quality == "v2") QualityV2(data);
    if (quality == "2014") Quality2014(data);
    if (quality == "graycode") QualityGrayCode(data);
    if (quality == "synth") QualitySynth();
    if (quality == "sigmafit") QualitySigmaFit();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_stereo: error: %s\n", e.what());
    return 1;
  }
  if (!quality.empty()) return 0;
  int n = static_cast<int>(rest.size());
  benchmark::Initialize(&n, rest.data());
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
