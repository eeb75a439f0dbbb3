// Stereo, space-time stereo and triangulation: speed (Google Benchmark) and quality on Middlebury, the
// Gray-code plane sequence and synthetic scenes. See BENCHMARKS.md for the commands and numbers.
//
//   bench_stereo [google benchmark flags]          speed: space-time 640×480 T=8, SGBM, triangulation
//   bench_stereo --quality=v2 [--data=DIR]          Middlebury v2: our SGBM path vs cv::StereoSGBM, bad-1.0 nonocc
//   bench_stereo --quality=2014 [--data=DIR]        Middlebury 2014 quarter: bad-2.0, σ_d ranking
//   bench_stereo --quality=graycode [--data=DIR]    Gray-code plane: disparity noise about a fitted plane
//   bench_stereo --quality=synth                    synthetic scenes: space-time vs SGBM depth RMS
//   bench_stereo --quality=sigmafit                 σ_d model (floor, scale) fitted on synthetic scenes
//   bench_stereo --quality=coverage                 space-time coverage: bad-1.0 with holes vs brute-force SSD
// DIR defaults to ../shared/data/stereo (relative to the repository root).
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "bench/bench_main.h"
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
  if (state.range(3) > 0) m.edge_reject_jump_px = 1.0;
  m.window_px = static_cast<int>(state.range(4));
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
// Args: frames T, Gauss–Newton sub-pixel iterations (0: parabola only), threads, edge rejection (1: on, as
// `rangebayes spacetime`), window w. The last three rows are the configurations of `rangebayes spacetime`.
BENCHMARK(BM_SpaceTime640)
    ->ArgNames({"T", "gn", "threads", "edge", "w"})
    ->Args({8, 0, 1, 0, 5})
    ->Args({8, 0, 2, 0, 5})
    ->Args({8, 2, 1, 0, 5})
    ->Args({8, 2, 2, 0, 5})
    ->Args({16, 0, 2, 0, 5})
    ->Args({1, 0, 2, 0, 5})
    ->Args({8, 1, 2, 1, 7})
    ->Args({16, 1, 1, 1, 5})
    ->Args({16, 1, 2, 1, 5})
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

// Matcher configuration of the synthetic-scene table (command-line overrides, see main()).
// Defaults: the configuration of `rangebayes spacetime` (1 Gauss–Newton step, edge rejection 1 px/px, window
// by T).
struct SynthConfig {
  std::vector<int> frames = {8, 16};
  std::vector<int> windows = {0};  // 0: w = 7 for T < 16, 5 for T ≥ 16 (as `rangebayes spacetime`)
  std::vector<double> noises = {2.0, 4.0};
  int gn = 1;              // Gauss–Newton steps (−1: matcher default, parabola only)
  double lr = -2.0;        // left-right max diff (−2: default)
  double jump = -2.0;      // neighbour_jump_px (−2: default)
  double max_sigma = -1;   // max_sigma_disparity_px (−1: default)
  std::string scenes = "planes,box,sphere,cylinder,stairs";
  double noise_free = -1;  // if ≥ 0: rendered noise override (the matcher still assumes `noise`)
  std::string cost = "auto";  // auto, ssd, zncc-time, zncc-space
  double edge = 1.0;          // edge_reject_jump_px (−2: matcher default, off)
  std::uint64_t seed = 5;     // renderer seed of the table
  int verify = -1;            // --quality=coverage: the preset's doubtful_verify_window_px (−1: its default)
  int sigmafit_gn = 0;        // Gauss–Newton steps of the σ_d fit (--quality=sigmafit); > 0: also edge
                              // rejection and the window by T, as `rangebayes spacetime`
};
SynthConfig g_synth;

std::vector<std::string> SplitCommas(const std::string& s) {
  std::vector<std::string> out;
  size_t a = 0;
  while (a <= s.size()) {
    const size_t b = std::min(s.find(',', a), s.size());
    if (b > a) out.push_back(s.substr(a, b - a));
    a = b + 1;
  }
  return out;
}

void QualitySynth() {
  const SynthConfig& c = g_synth;
  std::printf("Synthetic scenes 320x240, f = 320 px, B = 0.1 m, random pattern, seed %llu; depth and disparity RMS over\n"
              "pixels both methods measured (depth-edge pixels included), frame 0 for SGBM; coverage = valid share of\n"
              "pixels with ground truth; bias = mean signed disparity error (measured - true) away from edges\n",
              static_cast<unsigned long long>(c.seed));
  std::printf("%-9s %5s %3s %2s %20s %20s %7s %9s %9s %7s %7s %7s %8s %8s\n", "scene", "noise", "T", "w",
              "SGBM rms d / Z (mm)", "ST rms d / Z (mm)", "ratioZ", "SGBM Z*", "ST Z*", "ratio*", "cov SG", "cov ST",
              "bias SG", "bias ST");
  std::printf("(* = pixels at least 3 px from a depth edge)\n");
  std::map<std::pair<int, int>, std::pair<double, double>> worst;  // (T, w) → worst ratio Z, Z*
  std::printf("space-time: Gauss-Newton steps %d, edge rejection %.2f px/px, cost %s\n", c.gn, c.edge, c.cost.c_str());
  for (double noise : c.noises) {
    for (const std::string& scene_name : SplitCommas(c.scenes)) {
      const rb::SynthScene scene = rb::ParseSynthScene(scene_name);
      for (int T : c.frames) {
        rb::SynthOptions so;
        so.scene = scene;
        so.frames = T;
        so.image_noise_gray = c.noise_free >= 0 ? c.noise_free : noise;
        so.seed = c.seed;
        const rb::SynthRecording rec = rb::RenderSynthetic(so);
        rb::SgbmMatcherOptions go;
        go.min_disparity_px = 8;
        go.num_disparities = 48;
        const auto rs = rb::SgbmMatcher(go).Match({rec.left[0]}, {rec.right[0]});
        for (int window : c.windows) {
          const int w = window > 0 ? window : (T >= 16 ? 5 : 7);  // 0: the rule of `rangebayes spacetime`
          rb::SpaceTimeMatcherOptions mo;
          mo.min_disparity_px = 8;
          mo.num_disparities = 48;
          mo.image_noise_gray = noise;
          mo.window_px = w;
          if (c.gn >= 0) mo.subpixel_iterations = c.gn;
          if (c.cost == "ssd") mo.cost = rb::SpaceTimeCost::kSsd;
          if (c.cost == "zncc-time") mo.cost = rb::SpaceTimeCost::kZnccTime;
          if (c.cost == "zncc-space") mo.cost = rb::SpaceTimeCost::kZnccSpace;
          if (c.lr > -2) mo.left_right_max_diff_px = c.lr;
          if (c.jump > -2) mo.neighbour_jump_px = c.jump;
          if (c.max_sigma >= 0) mo.max_sigma_disparity_px = c.max_sigma;
          if (c.edge > -2) mo.edge_reject_jump_px = c.edge;
          const auto rt = rb::SpaceTimeMatcher(mo).Match(rec.left, rec.right);
          double sd_s = 0, sd_t = 0, sz_s = 0, sz_t = 0, ez_s = 0, ez_t = 0, bias_s = 0, bias_t = 0;
          int n = 0, ne = 0, gt_n = 0, cov_s = 0, cov_t = 0;
          const double fb = rec.intrinsics.fx_px * so.baseline_m;
          for (int y = 0; y < rec.depth_m.rows; ++y)
            for (int x = 0; x < rec.depth_m.cols; ++x) {
              const float a = rs.disparity_px.at<float>(y, x), b = rt.disparity_px.at<float>(y, x);
              const float g = rec.disparity_px.at<float>(y, x);
              if (!std::isfinite(g)) continue;
              ++gt_n;
              cov_s += std::isfinite(a);
              cov_t += std::isfinite(b);
              if (!std::isfinite(a) || !std::isfinite(b)) continue;
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
                bias_s += a - g;
                bias_t += b - g;
                ++ne;
              }
            }
          const double ratio = std::sqrt(sz_t / sz_s), ratio_star = std::sqrt(ez_t / ez_s);
          auto& wr = worst[{T, w}];
          wr.first = std::max(wr.first, ratio);
          wr.second = std::max(wr.second, ratio_star);
          std::printf("%-9s %5.1f %3d %2d %8.3f / %8.2f %8.3f / %8.2f %7.2f %9.2f %9.2f %7.2f %6.1f%% %6.1f%% %8.3f %8.3f\n",
                      rb::ToString(scene).c_str(), noise, T, w, std::sqrt(sd_s / n), 1000 * std::sqrt(sz_s / n),
                      std::sqrt(sd_t / n), 1000 * std::sqrt(sz_t / n), ratio, 1000 * std::sqrt(ez_s / ne),
                      1000 * std::sqrt(ez_t / ne), ratio_star, 100.0 * cov_s / gt_n, 100.0 * cov_t / gt_n,
                      bias_s / ne, bias_t / ne);
          std::fflush(stdout);
        }
      }
    }
  }
  for (const auto& [key, value] : worst) {
    std::printf("T=%2d w=%d: worst ratio Z %.3f, worst ratio Z* %.3f over all rows (target <= 0.333: %s)\n", key.first,
                key.second, value.first, value.second, value.first <= 1.0 / 3.0 ? "met" : "missed");
  }
}

// Non-occluded ground-truth pixels of a synthetic left view: finite disparity, the right pixel inside the
// image, and no pixel further right on the row that lands at or left of it in the right view (a closer
// surface hides it).
cv::Mat NonOccludedMask(const cv::Mat& gt) {
  cv::Mat mask(gt.size(), CV_8U, cv::Scalar(0));
  for (int y = 0; y < gt.rows; ++y) {
    const float* g = gt.ptr<float>(y);
    float reach = -std::numeric_limits<float>::infinity();  // max over x' > x of x - (x' - d(x'))
    for (int x = gt.cols - 1; x >= 0; --x) {
      const bool ok = std::isfinite(g[x]) && x - g[x] >= 0.0f && !(reach > g[x]);
      mask.at<unsigned char>(y, x) = ok ? 255 : 0;
      reach -= 1.0f;  // moving one pixel left shifts every x' − x by one
      if (std::isfinite(g[x])) reach = std::max(reach, g[x]);
    }
  }
  return mask;
}

// Space-time coverage on the synthetic scenes: bad-1.0 with holes counted and the RMS over valid pixels
// (non-occluded ground truth), for the configuration `rangebayes spacetime` ran before the coverage change
// (edge rejection drops doubtful pixels), the same with the rejection off, a brute-force w×w×T SSD (winner
// take all with parabola, no checks), and the library's static-scene preset (doubtful pixels kept with an
// inflated σ_d). Also the normalised residual of the pixels the preset keeps but the old configuration
// dropped.
void QualityCoverage() {
  const SynthConfig& c = g_synth;
  std::printf("Space-time coverage, synthetic scenes 320x240, random pattern, seed %llu, non-occluded pixels; bad-1 "
              "= share off by > 1 px or missing; rms over valid pixels (px)\n",
              static_cast<unsigned long long>(c.seed));
  std::printf("%-9s %5s %3s | %14s | %14s | %14s | %14s | %22s\n", "scene", "noise", "T", "old bad1/rms",
              "edge-off b1/rms", "brute b1/rms", "preset b1/rms", "kept: n, >1px, rms err, rms z");
  double worst_margin = -1e9, worst_rms_ratio = 0;
  for (double noise : c.noises) {
    for (const std::string& scene_name : SplitCommas(c.scenes)) {
      for (int T : c.frames) {
        rb::SynthOptions so;
        so.scene = rb::ParseSynthScene(scene_name);
        so.frames = T;
        so.image_noise_gray = noise;
        so.seed = c.seed;
        const rb::SynthRecording rec = rb::RenderSynthetic(so);
        const cv::Mat mask = NonOccludedMask(rec.disparity_px);
        auto base = [&] {
          rb::SpaceTimeMatcherOptions m = rb::SpaceTimeStaticSceneOptions(T);
          m.min_disparity_px = 8;
          m.num_disparities = 48;
          m.image_noise_gray = noise;
          return m;
        };
        rb::SpaceTimeMatcherOptions old = base();
        old.doubtful_jump_px = -1.0;
        old.edge_reject_jump_px = 1.0;
        rb::SpaceTimeMatcherOptions off = old;
        off.edge_reject_jump_px = -1.0;
        rb::SpaceTimeMatcherOptions brute = base();
        brute.window_px = 5;
        brute.cost = rb::SpaceTimeCost::kSsd;
        brute.uniqueness_ratio = 0.0;
        brute.left_right_max_diff_px = -1.0;
        brute.neighbour_jump_px = -1.0;
        brute.subpixel_iterations = 0;
        brute.edge_reject_jump_px = -1.0;
        brute.doubtful_jump_px = -1.0;
        rb::SpaceTimeMatcherOptions preset = base();
        if (c.verify >= 0) preset.doubtful_verify_window_px = c.verify;
        double b1[4], rms[4];
        cv::Mat dd[4], ss[4];
        int i = 0;
        for (const auto& m : {old, off, brute, preset}) {
          const rb::DisparityResult r = rb::SpaceTimeMatcher(m).Match(rec.left, rec.right);
          const rb::DisparityEvaluation ev = rb::EvaluateDisparity(r.disparity_px, rec.disparity_px, mask);
          b1[i] = ev.bad_with_holes[1];
          rms[i] = ev.rms_px;
          dd[i] = r.disparity_px;
          ss[i] = r.sigma_disparity_px;
          ++i;
        }
        double se = 0, sz = 0;
        int n = 0, gross = 0;
        for (int y = 0; y < mask.rows; ++y)
          for (int x = 0; x < mask.cols; ++x) {
            if (!mask.at<unsigned char>(y, x) || std::isfinite(dd[0].at<float>(y, x))) continue;
            const float d = dd[3].at<float>(y, x);
            if (!std::isfinite(d)) continue;
            const double e = d - rec.disparity_px.at<float>(y, x);
            se += e * e;
            sz += e * e / std::pow(ss[3].at<float>(y, x), 2);
            gross += std::abs(e) > 1.0;
            ++n;
          }
        worst_margin = std::max(worst_margin, b1[3] - b1[2]);
        worst_rms_ratio = std::max(worst_rms_ratio, rms[3] / rms[0]);
        std::printf("%-9s %5.1f %3d | %6.2f%% %6.3f | %6.2f%% %6.3f | %6.2f%% %6.3f | %6.2f%% %6.3f | %6d %5.1f%% %6.3f %7.2f\n",
                    scene_name.c_str(), noise, T, 100 * b1[0], rms[0], 100 * b1[1], rms[1], 100 * b1[2], rms[2],
                    100 * b1[3], rms[3], n, n ? 100.0 * gross / n : 0.0, n ? std::sqrt(se / n) : 0.0, n ? std::sqrt(sz / n) : 0.0);
        std::fflush(stdout);
      }
    }
  }
  std::printf("worst bad-1 preset minus brute force: %+.2f points (target <= 0: %s); worst rms preset / old: %.3f "
              "(target <= 1: %s)\n",
              100 * worst_margin, worst_margin <= 0 ? "met" : "missed", worst_rms_ratio,
              worst_rms_ratio <= 1.0 ? "met" : "missed");
}

// Fits the σ_d model σ² = floor² + (k·σ_pred)² to the disparity errors of the space-time matcher on the
// synthetic scenes (planes, sphere, box, cylinder, stairs; 320×240, seeds 5 and 6, image noise 2), per T:
// maximum likelihood over a grid of floor and k, residuals beyond 5σ left out as outliers (re-cut after
// each fit). Prints the fit and the mean normalised squared residual per σ_pred quintile.
void QualitySigmaFit() {
  std::printf("sigma_d model fit: sigma^2 = floor^2 + (k*pred)^2, synthetic scenes 320x240, noise 2, seeds 5-6, "
              "Gauss-Newton steps %d\n", g_synth.sigmafit_gn);
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
        mo.subpixel_iterations = g_synth.sigmafit_gn;
        if (g_synth.sigmafit_gn > 0) {  // the configuration of `rangebayes spacetime`
          mo.edge_reject_jump_px = 1.0;
          mo.window_px = T >= 16 ? 5 : 7;
        }
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

int RunBench(int argc, char** argv) {
  std::string quality, data = "../shared/data/stereo";
  std::vector<char*> rest;
  for (int i = 0; i < argc; ++i) {
    const std::string a = argv[i];
    if (a.rfind("--quality=", 0) == 0) {
      quality = a.substr(10);
    } else if (a.rfind("--data=", 0) == 0) {
      data = a.substr(7);
    } else if (a.rfind("--synth-", 0) == 0 && a.find('=') != std::string::npos) {
      // --synth-frames=8,16 --synth-windows=3,5 --synth-noises=2,4 --synth-scenes=box,... --synth-gn=2
      // --synth-lr=1 --synth-jump=1 --synth-max-sigma=0 --synth-render-noise=0
      const std::string key = a.substr(8, a.find('=') - 8), value = a.substr(a.find('=') + 1);
      auto ints = [&] { std::vector<int> v; for (const auto& t : SplitCommas(value)) v.push_back(std::stoi(t)); return v; };
      if (key == "frames") g_synth.frames = ints();
      else if (key == "windows") g_synth.windows = ints();
      else if (key == "noises") { g_synth.noises.clear(); for (const auto& t : SplitCommas(value)) g_synth.noises.push_back(std::stod(t)); }
      else if (key == "scenes") g_synth.scenes = value;
      else if (key == "gn") g_synth.gn = std::stoi(value);
      else if (key == "cost") g_synth.cost = value;
      else if (key == "edge") g_synth.edge = std::stod(value);
      else if (key == "sigmafit-gn") g_synth.sigmafit_gn = std::stoi(value);
      else if (key == "verify") g_synth.verify = std::stoi(value);
      else if (key == "seed") g_synth.seed = std::stoull(value);
      else if (key == "lr") g_synth.lr = std::stod(value);
      else if (key == "jump") g_synth.jump = std::stod(value);
      else if (key == "max-sigma") g_synth.max_sigma = std::stod(value);
      else if (key == "render-noise") g_synth.noise_free = std::stod(value);
      else { std::fprintf(stderr, "bench_stereo: unknown option %s\n", a.c_str()); return 2; }
    } else {
      rest.push_back(argv[i]);
    }
  }
  if (quality == "v2") QualityV2(data);
  if (quality == "2014") Quality2014(data);
  if (quality == "graycode") QualityGrayCode(data);
  if (quality == "synth") QualitySynth();
  if (quality == "sigmafit") QualitySigmaFit();
  if (quality == "coverage") QualityCoverage();
  if (!quality.empty()) return 0;
  int n = static_cast<int>(rest.size());
  benchmark::Initialize(&n, rest.data());
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return rangebayes::bench::Main("bench_stereo", RunBench, argc, argv); }
