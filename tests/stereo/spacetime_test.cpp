// Our space-time / block matcher on synthetic scenes with exact ground truth.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "core/error.h"
#include "stereo/depth_frame.h"
#include "stereo/sgbm_matcher.h"
#include "stereo/spacetime_matcher.h"
#include "stereo/synth.h"

namespace rangebayes {
namespace {

struct Errors {
  double rms = 0, median_abs = 0, coverage = 0, mean_z2 = 0;
  double sigma_rank_correlation = 0;  // Spearman's rank correlation between σ and |error| (with σ given)
  int n = 0;
};

// Ranks 0..n−1 of `values`, ties given their mean rank.
std::vector<double> Ranks(const std::vector<double>& values) {
  std::vector<size_t> order(values.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return values[a] < values[b]; });
  std::vector<double> rank(values.size());
  for (size_t i = 0; i < order.size();) {
    size_t j = i;
    while (j + 1 < order.size() && values[order[j + 1]] == values[order[i]]) ++j;
    for (size_t k = i; k <= j; ++k) rank[order[k]] = 0.5 * (i + j);
    i = j + 1;
  }
  return rank;
}

double RankCorrelation(const std::vector<double>& a, const std::vector<double>& b) {
  const std::vector<double> ra = Ranks(a), rb = Ranks(b);
  const double n = static_cast<double>(a.size()), mean = 0.5 * (n - 1);
  double ab = 0, aa = 0, bb = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    ab += (ra[i] - mean) * (rb[i] - mean);
    aa += (ra[i] - mean) * (ra[i] - mean);
    bb += (rb[i] - mean) * (rb[i] - mean);
  }
  return aa > 0 && bb > 0 ? ab / std::sqrt(aa * bb) : 0.0;
}

// Disparity errors against ground truth over pixels at least `margin` px from a ground-truth depth edge
// (windows straddling an edge are biased by design, not by noise).
Errors Score(const cv::Mat& d, const cv::Mat& sigma, const cv::Mat& gt, int margin = 3) {
  std::vector<double> abs_err, sigma_abs_err, sigmas;
  double sum2 = 0, z2 = 0;
  int total = 0, nz = 0;
  for (int y = margin; y < gt.rows - margin; ++y) {
    for (int x = margin + 60; x < gt.cols - margin; ++x) {
      bool smooth = true;
      for (int k = -margin; k <= margin && smooth; ++k) {
        smooth = std::abs(gt.at<float>(y, x + k) - gt.at<float>(y, x)) < 0.5 * margin &&
                 std::abs(gt.at<float>(y + k, x) - gt.at<float>(y, x)) < 0.5 * margin;
      }
      if (!smooth) continue;
      ++total;
      const float v = d.at<float>(y, x);
      if (!std::isfinite(v)) continue;
      const double e = v - gt.at<float>(y, x);
      abs_err.push_back(std::abs(e));
      sum2 += e * e;
      if (!sigma.empty()) {
        const double s = sigma.at<float>(y, x);
        z2 += e * e / (s * s);
        ++nz;
        sigma_abs_err.push_back(std::abs(e));
        sigmas.push_back(s);
      }
    }
  }
  Errors out;
  out.n = static_cast<int>(abs_err.size());
  if (abs_err.empty()) return out;
  std::nth_element(abs_err.begin(), abs_err.begin() + abs_err.size() / 2, abs_err.end());
  out.median_abs = abs_err[abs_err.size() / 2];
  out.rms = std::sqrt(sum2 / out.n);
  out.coverage = static_cast<double>(out.n) / total;
  out.mean_z2 = nz ? z2 / nz : 0.0;
  if (nz > 1) out.sigma_rank_correlation = RankCorrelation(sigmas, sigma_abs_err);
  return out;
}

SynthOptions Scene(SynthScene scene, int frames, double noise, std::uint64_t seed = 1) {
  SynthOptions o;
  o.scene = scene;
  o.frames = frames;
  o.image_noise_gray = noise;
  o.seed = seed;
  return o;
}

SpaceTimeMatcherOptions MatcherFor(int window = 5) {
  SpaceTimeMatcherOptions m;
  m.min_disparity_px = 8;
  m.num_disparities = 48;
  m.window_px = window;
  m.image_noise_gray = 2.0;
  return m;
}

TEST(SpaceTime, FrontoParallelPlaneGivesItsDepth) {
  const SynthRecording rec = RenderSynthetic(Scene(SynthScene::kPlane, 8, 2.0));
  SpaceTimeMatcher matcher(MatcherFor());
  const DisparityResult r = matcher.Match(rec.left, rec.right);
  const DepthFrame frame =
      DepthFromDisparity(r.disparity_px, r.sigma_disparity_px, rec.intrinsics, rec.rig.baseline_m(), 0.0);
  std::vector<float> z;
  for (int y = 0; y < frame.height(); ++y)
    for (int x = 0; x < frame.width(); ++x)
      if (std::isfinite(frame.depth_m.at<float>(y, x))) z.push_back(frame.depth_m.at<float>(y, x));
  // Pixels left of the smallest visible disparity have no partner in the right image.
  EXPECT_GT(z.size(), 0.85 * frame.width() * frame.height());
  std::nth_element(z.begin(), z.begin() + z.size() / 2, z.end());
  EXPECT_NEAR(z[z.size() / 2], 1.0, 1e-3);  // the plane is at 1.000 m
  const Errors e = Score(r.disparity_px, r.sigma_disparity_px, rec.disparity_px);
  std::printf("plane T=8: rms %.4f px, median %.4f px, coverage %.3f, mean z2 %.3f\n", e.rms, e.median_abs, e.coverage,
              e.mean_z2);
  EXPECT_LT(e.rms, 0.1);
}

TEST(SpaceTime, TemporalWindowBeatsSingleFrame) {
  for (const auto scene : {SynthScene::kPlanes, SynthScene::kSphere, SynthScene::kStairs}) {
    const SynthRecording rec = RenderSynthetic(Scene(scene, 8, 3.0));
    SpaceTimeMatcher single(MatcherFor());
    const std::vector<cv::Mat> l1 = {rec.left[0]}, r1 = {rec.right[0]};
    const Errors e1 = Score(single.Match(l1, r1).disparity_px, {}, rec.disparity_px);
    SpaceTimeMatcher multi(MatcherFor());
    const DisparityResult rm = multi.Match(rec.left, rec.right);
    const Errors e8 = Score(rm.disparity_px, rm.sigma_disparity_px, rec.disparity_px);
    SgbmMatcherOptions so;
    so.min_disparity_px = 8;
    so.num_disparities = 48;
    SgbmMatcher sgbm(so);
    const Errors es = Score(sgbm.Match(l1, r1).disparity_px, {}, rec.disparity_px);
    std::printf("%s: T=1 rms %.3f cov %.3f | T=8 rms %.3f cov %.3f z2 %.2f | sgbm rms %.3f cov %.3f\n",
                ToString(scene).c_str(), e1.rms, e1.coverage, e8.rms, e8.coverage, e8.mean_z2, es.rms, es.coverage);
    EXPECT_LT(e8.rms, 0.5 * e1.rms) << ToString(scene);
    EXPECT_GE(e8.coverage, e1.coverage - 0.02) << ToString(scene);
  }
}

// σ_d is a per-pixel standard deviation of the disparity error: the normalised residuals e/σ_d have an RMS near 1
// (within a factor 2 either way) and pixels with a larger σ_d have larger errors (a positive rank correlation
// between σ_d and |e|), on the pixels away from depth edges.
TEST(SpaceTime, SigmaMatchesTheErrors) {
  for (const auto scene : {SynthScene::kSphere, SynthScene::kBox}) {
    for (int frames : {1, 8}) {
      const SynthRecording rec = RenderSynthetic(Scene(scene, frames, 2.0, 7));
      SpaceTimeMatcher m(MatcherFor());
      const DisparityResult r = m.Match(rec.left, rec.right);
      const Errors e = Score(r.disparity_px, r.sigma_disparity_px, rec.disparity_px);
      const double rms_z = std::sqrt(e.mean_z2);
      std::printf("%s T=%d: rms %.4f, rms z %.3f, rank correlation %.3f, coverage %.3f\n", ToString(scene).c_str(),
                  frames, e.rms, rms_z, e.sigma_rank_correlation, e.coverage);
      SCOPED_TRACE(ToString(scene) + " T=" + std::to_string(frames));
      ASSERT_GT(e.n, 1000);
      // Measured (seed 7): RMS of e/σ_d 0.73–1.32, rank correlation 0.175–0.374 over the four cases; the bounds
      // leave about 1.5× room on the RMS and 2× on the correlation.
      EXPECT_GT(rms_z, 0.5);
      EXPECT_LT(rms_z, 2.0);
      EXPECT_GT(e.sigma_rank_correlation, 0.08);
    }
  }
}

// A slanted surface is not a doubt: σ_d's neighbour term and the doubtful-pixel test read the neighbours' departure
// from the local slope, not their raw difference. On the sphere (T = 8, `rangebayes spacetime`'s configuration,
// away from depth edges) the RMS of e/σ_d where the ground truth slopes by 0.2–1 px/px, over that where it is
// flat, was 0.63 (seeds 3, 7) with the raw differences and is 0.73 with the slope taken out (the library's
// defaults: 0.93–0.96 → 0.98–1.02). What remains is the matching σ itself (the cost's curvature is lower on a
// slant, the Gauss–Newton step's error is not), an open finding.
TEST(SpaceTime, SigmaDoesNotGrowWithTheSlope) {
  for (const std::uint64_t seed : {3u, 7u}) {
    const SynthRecording rec = RenderSynthetic(Scene(SynthScene::kSphere, 8, 2.0, seed));
    SpaceTimeMatcherOptions options = SpaceTimeStaticSceneOptions(8);  // what `rangebayes spacetime` runs
    options.min_disparity_px = 8;
    options.num_disparities = 48;
    options.image_noise_gray = 2.0;
    SpaceTimeMatcher m(options);
    const DisparityResult r = m.Match(rec.left, rec.right);
    const cv::Mat& gt = rec.disparity_px;
    const int margin = 5;
    double z2[2] = {0, 0};
    int n[2] = {0, 0};
    for (int y = margin; y < gt.rows - margin; ++y) {
      for (int x = margin + 60; x < gt.cols - margin; ++x) {
        bool smooth = true;  // no ground-truth jump (beyond the slope) within the margin
        const double gx = 0.5 * (gt.at<float>(y, x + 1) - gt.at<float>(y, x - 1));
        const double gy = 0.5 * (gt.at<float>(y + 1, x) - gt.at<float>(y - 1, x));
        for (int k = -margin; k <= margin && smooth; ++k) {
          smooth = std::abs(gt.at<float>(y, x + k) - gt.at<float>(y, x) - k * gx) < 0.5 &&
                   std::abs(gt.at<float>(y + k, x) - gt.at<float>(y, x) - k * gy) < 0.5;
        }
        const float d = r.disparity_px.at<float>(y, x), s = r.sigma_disparity_px.at<float>(y, x);
        if (!smooth || !std::isfinite(d)) continue;
        const double slope = std::hypot(gx, gy);
        const int part = slope < 0.1 ? 0 : slope >= 0.2 && slope <= 1.0 ? 1 : -1;
        if (part < 0) continue;
        const double e = d - gt.at<float>(y, x);
        z2[part] += e * e / (static_cast<double>(s) * s);
        ++n[part];
      }
    }
    ASSERT_GT(n[0], 1000);
    ASSERT_GT(n[1], 300);
    const double flat = std::sqrt(z2[0] / n[0]), steep = std::sqrt(z2[1] / n[1]);
    std::printf("seed %d: rms z flat %.3f (%d px), steep %.3f (%d px), ratio %.3f\n", static_cast<int>(seed), flat,
                n[0], steep, n[1], steep / flat);
    EXPECT_GT(steep / flat, 0.68) << "seed " << seed;
    EXPECT_LT(steep / flat, 1.2) << "seed " << seed;
  }
}

// The configuration of `rangebayes spacetime` (one Gauss–Newton step, edge rejection) against the library
// default (parabola, no edge rejection) on the box scene, every pixel with ground truth counted: the
// rejection removes the pixels whose window mixes two surfaces (the gross errors at the box's edges and its
// grazing top face), at a small cost in coverage, and the refinement lowers the error away from edges.
TEST(SpaceTime, EdgeRejectionAndGaussNewtonRemoveGrossAndSubPixelErrors) {
  const SynthRecording rec = RenderSynthetic(Scene(SynthScene::kBox, 8, 2.0, 5));
  const auto all_pixels = [&](const cv::Mat& d, double* rms, double* coverage, double* gross) {
    double sum2 = 0;
    int n = 0, total = 0, big = 0;
    for (int y = 0; y < d.rows; ++y)
      for (int x = 60; x < d.cols; ++x) {
        ++total;
        const float v = d.at<float>(y, x);
        if (!std::isfinite(v)) continue;
        const double e = v - rec.disparity_px.at<float>(y, x);
        sum2 += e * e;
        big += std::abs(e) > 1.0;
        ++n;
      }
    *rms = std::sqrt(sum2 / n);
    *coverage = static_cast<double>(n) / total;
    *gross = static_cast<double>(big) / n;
  };
  SpaceTimeMatcherOptions plain = MatcherFor();
  SpaceTimeMatcherOptions cli = MatcherFor();
  cli.subpixel_iterations = 1;
  cli.edge_reject_jump_px = 1.0;
  SpaceTimeMatcher a(plain), b(cli);
  const DisparityResult ra = a.Match(rec.left, rec.right), rb = b.Match(rec.left, rec.right);
  double rms_a, cov_a, gross_a, rms_b, cov_b, gross_b;
  all_pixels(ra.disparity_px, &rms_a, &cov_a, &gross_a);
  all_pixels(rb.disparity_px, &rms_b, &cov_b, &gross_b);
  const Errors ea = Score(ra.disparity_px, {}, rec.disparity_px), eb = Score(rb.disparity_px, {}, rec.disparity_px);
  std::printf("box T=8: library default rms %.3f px (away from edges %.4f), coverage %.3f, gross %.4f%% | "
              "spacetime CLI rms %.3f px (%.4f), coverage %.3f, gross %.4f%%, %d rejected near edges\n",
              rms_a, ea.rms, cov_a, 100 * gross_a, rms_b, eb.rms, cov_b, 100 * gross_b,
              b.last_summary().rejected_edge);
  // Measured (seed 5): rms 0.599 → 0.041 px, pixels off by > 1 px 0.86% → 0%, away from edges 0.073 →
  // 0.037 px, coverage 0.989 → 0.954; the bounds leave about 2× room.
  EXPECT_LT(rms_b, 0.15 * rms_a);
  EXPECT_LT(gross_b, 0.1 * gross_a);
  EXPECT_GT(cov_b, cov_a - 0.07);
  EXPECT_LT(eb.rms, 0.75 * ea.rms);
  EXPECT_GT(b.last_summary().rejected_edge, 0);
}

// The static-scene preset (what `rangebayes spacetime` runs) keeps the doubtful pixels that the edge
// rejection drops when a 3×3×T window confirms them, with σ_d inflated: against the same configuration with
// the rejection, more pixels right to 1 px (bad-1.0 with holes counted goes down), the pixels both keep
// are identical, and every kept doubtful pixel says so with σ_d ≥ doubtful_sigma_px.
TEST(SpaceTime, StaticPresetKeepsConfirmedDoubtfulPixelsWithLargerSigma) {
  const SynthRecording rec = RenderSynthetic(Scene(SynthScene::kPlanes, 8, 2.0, 5));
  SpaceTimeMatcherOptions preset = SpaceTimeStaticSceneOptions(8);
  preset.min_disparity_px = 8;
  preset.num_disparities = 48;
  EXPECT_EQ(preset.window_px, 7);
  EXPECT_EQ(SpaceTimeStaticSceneOptions(16).window_px, 5);
  EXPECT_EQ(preset.subpixel_iterations, 1);
  EXPECT_DOUBLE_EQ(preset.sigma_floor_px, kGaussNewtonSigmaFloorPx);
  SpaceTimeMatcherOptions rejecting = preset;
  rejecting.edge_reject_jump_px = 1.0;
  SpaceTimeMatcher a(rejecting), b(preset);
  const DisparityResult ra = a.Match(rec.left, rec.right), rb = b.Match(rec.left, rec.right);
  int bad_a = 0, bad_b = 0, total = 0, kept = 0, kept_right = 0, differ = 0, small_sigma = 0;
  for (int y = 0; y < rec.disparity_px.rows; ++y)
    for (int x = 60; x < rec.disparity_px.cols; ++x) {
      const float g = rec.disparity_px.at<float>(y, x);
      if (!std::isfinite(g)) continue;
      ++total;
      const float da = ra.disparity_px.at<float>(y, x), db = rb.disparity_px.at<float>(y, x);
      bad_a += !(std::abs(da - g) <= 1.0f);
      bad_b += !(std::abs(db - g) <= 1.0f);
      if (std::isfinite(da)) {
        differ += !(da == db) || !(ra.sigma_disparity_px.at<float>(y, x) == rb.sigma_disparity_px.at<float>(y, x));
      } else if (std::isfinite(db)) {
        ++kept;
        kept_right += std::abs(db - g) <= 1.0f;
        small_sigma += rb.sigma_disparity_px.at<float>(y, x) < preset.doubtful_sigma_px;
      }
    }
  std::printf("planes T=8: bad-1 with holes %.2f%% (rejecting) -> %.2f%% (preset); %d doubtful kept, %.1f%% right to "
              "1 px; summary: %d doubtful, %d rejected\n",
              100.0 * bad_a / total, 100.0 * bad_b / total, kept, 100.0 * kept_right / std::max(kept, 1),
              b.last_summary().doubtful, b.last_summary().rejected_edge);
  // Measured (seed 5): bad-1 7.2% -> 0.5% over the scene (bench_stereo --quality=coverage), 99% of the kept
  // pixels right to 1 px; the bounds leave room.
  EXPECT_LT(bad_b, 0.3 * bad_a);
  EXPECT_GT(kept, 0);
  EXPECT_GT(kept_right, 0.9 * kept);
  EXPECT_EQ(differ, 0);
  EXPECT_EQ(small_sigma, 0);
  EXPECT_GE(b.last_summary().doubtful, kept);
}

TEST(SpaceTime, BadInputThrows) {
  SpaceTimeMatcher m(MatcherFor());
  const cv::Mat a(40, 60, CV_8U, cv::Scalar(10)), b(40, 61, CV_8U, cv::Scalar(10));
  EXPECT_THROW(m.Match({a}, {b}), Error);
  EXPECT_THROW(m.Match({a, a}, {a}), Error);
  EXPECT_THROW(m.Match({}, {}), Error);
  EXPECT_THROW(m.Match({cv::Mat()}, {cv::Mat()}), Error);
  EXPECT_THROW(m.Match({cv::Mat(40, 60, CV_32F, cv::Scalar(0))}, {cv::Mat(40, 60, CV_32F, cv::Scalar(0))}), Error);
  SpaceTimeMatcherOptions o;
  o.window_px = 4;
  EXPECT_THROW(SpaceTimeMatcher{o}, Error);
  SpaceTimeMatcherOptions v;
  v.doubtful_verify_window_px = 2;
  EXPECT_THROW(SpaceTimeMatcher{v}, Error);
  EXPECT_THROW(SpaceTimeStaticSceneOptions(0), Error);
  SpaceTimeMatcherOptions z;
  z.cost = SpaceTimeCost::kZnccTime;
  SpaceTimeMatcher zncc(z);
  EXPECT_THROW(zncc.Match({a}, {a}), Error);
}

TEST(SpaceTime, FlatImagesGiveNoDisparity) {
  SpaceTimeMatcher m(MatcherFor());
  const cv::Mat a(40, 80, CV_8U, cv::Scalar(100));
  const DisparityResult r = m.Match({a, a, a}, {a, a, a});
  EXPECT_EQ(cv::countNonZero(r.disparity_px == r.disparity_px), 0);
}

}  // namespace
}  // namespace rangebayes
