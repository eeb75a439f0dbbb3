// The synthetic renderer: ground truth of the plane scene, determinism, the recording it writes.
#include "stereo/synth.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <string_view>
#include <vector>

#include "capture/recording.h"
#include "core/error.h"
#include "stereo/pfm.h"
#include "stereo/spacetime_matcher.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

SynthOptions Small(SynthScene scene) {
  SynthOptions o;
  o.scene = scene;
  o.width = 96;
  o.height = 72;
  o.frames = 3;
  o.supersample = 2;
  return o;
}

TEST(Synth, PlaneGroundTruthIsExact) {
  const SynthRecording rec = RenderSynthetic(Small(SynthScene::kPlane));
  ASSERT_EQ(rec.left.size(), 3u);
  const double f = rec.intrinsics.fx_px;
  for (int y = 0; y < rec.depth_m.rows; y += 7) {
    for (int x = 0; x < rec.depth_m.cols; x += 5) {
      EXPECT_NEAR(rec.depth_m.at<float>(y, x), 1.0, 1e-6);
      EXPECT_NEAR(rec.disparity_px.at<float>(y, x), f * 0.1, 1e-4);
    }
  }
}

TEST(Synth, SameSeedSameImagesOtherSeedOtherImages) {
  SynthOptions o = Small(SynthScene::kSphere);
  const SynthRecording a = RenderSynthetic(o), b = RenderSynthetic(o);
  o.seed = 2;
  const SynthRecording c = RenderSynthetic(o);
  for (size_t t = 0; t < a.left.size(); ++t) {
    EXPECT_EQ(cv::norm(a.left[t], b.left[t], cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(a.right[t], b.right[t], cv::NORM_INF), 0.0);
    EXPECT_GT(cv::norm(a.left[t], c.left[t], cv::NORM_L1), 0.0);
  }
  // Patterns change from frame to frame.
  EXPECT_GT(cv::norm(a.left[0], a.left[1], cv::NORM_L1), 0.0);
}

TEST(Synth, EveryScenePatternRendersWithDepthInRange) {
  for (const auto scene : {SynthScene::kPlanes, SynthScene::kBox, SynthScene::kSphere, SynthScene::kCylinder,
                           SynthScene::kStairs}) {
    for (const auto pattern : {SynthPattern::kRandom, SynthPattern::kGrayCode}) {
      SynthOptions o = Small(scene);
      o.pattern = pattern;
      const SynthRecording rec = RenderSynthetic(o);
      double lo = 0, hi = 0;
      cv::minMaxLoc(rec.depth_m, &lo, &hi, nullptr, nullptr, rec.depth_m == rec.depth_m);
      EXPECT_GT(lo, 0.5) << ToString(scene);
      EXPECT_LT(hi, 3.0) << ToString(scene);
      EXPECT_EQ(cv::countNonZero(rec.depth_m == rec.depth_m), o.width * o.height) << ToString(scene);
      cv::Scalar mean = cv::mean(rec.left[0]);
      EXPECT_GT(mean[0], 20.0) << ToString(scene) << " " << ToString(pattern);
    }
  }
}

TEST(Synth, WritesARecordingThatReadsBack) {
  const std::string folder = TempPath("synth_test");
  std::filesystem::remove_all(folder);
  const SynthOptions o = Small(SynthScene::kBox);
  const SynthRecording rec = RenderSynthetic(o);
  WriteSyntheticRecording(rec, o, folder);
  const Recording back = OpenRecording(folder);
  ASSERT_EQ(back.num_frames(), 3);
  ASSERT_TRUE(back.rig.has_value());
  EXPECT_TRUE(back.rig->is_rectified);
  EXPECT_NEAR(back.rig->baseline_m(), 0.1, 1e-12);
  const StereoFrame f = LoadRecordingFrame(back, 1);
  EXPECT_EQ(cv::norm(f.left, rec.left[1], cv::NORM_INF), 0.0);
  const cv::Mat depth = ReadPfm(folder + "/ground_truth/depth_left_m.pfm");
  EXPECT_EQ(cv::norm(depth, rec.depth_m, cv::NORM_INF), 0.0);
  // A second write into the same folder needs overwrite.
  EXPECT_THROW(WriteSyntheticRecording(rec, o, folder), Error);
  SynthWriteOptions w;
  w.overwrite = true;
  EXPECT_NO_THROW(WriteSyntheticRecording(rec, o, folder, w));
}

// Streaming: the frames written one by one are the frames rendered in memory, with progress per frame; a stop
// request keeps the frames written before it in a finished recording with its ground truth, saying so in
// meta.yaml (synth rendered every frame before writing any, and Ctrl-C lost them all).
TEST(Synth, WritesFrameByFrameAndKeepsTheFramesBeforeAStop) {
  const SynthOptions o = Small(SynthScene::kBox);
  const SynthRecording whole = RenderSynthetic(o);
  const std::string folder = TempPath("synth_stream_test");
  std::filesystem::remove_all(folder);
  std::vector<double> fractions;
  SynthWriteOptions w;
  w.progress = [&fractions](double fraction, std::string_view) { fractions.push_back(fraction); };
  const SynthRecording streamed = WriteSynthetic(o, folder, w);
  EXPECT_EQ(fractions, (std::vector<double>{1.0 / 3.0, 2.0 / 3.0, 1.0}));
  EXPECT_EQ(streamed.pattern_ids, whole.pattern_ids);
  EXPECT_TRUE(streamed.left.empty());
  const Recording back = OpenRecording(folder);
  ASSERT_EQ(back.num_frames(), 3);
  for (int t = 0; t < 3; ++t) {
    EXPECT_EQ(cv::norm(LoadRecordingFrame(back, t).right, whole.right[static_cast<size_t>(t)], cv::NORM_INF), 0.0);
  }
  EXPECT_EQ(cv::norm(ReadPfm(folder + "/ground_truth/disparity_left_px.pfm"), whole.disparity_px, cv::NORM_INF), 0.0);

  std::atomic<bool> stop{false};
  w.overwrite = true;
  w.stop = &stop;
  w.progress = [&stop](double fraction, std::string_view) {
    if (fraction > 0.5) stop = true;  // after the second frame
  };
  const SynthRecording stopped = WriteSynthetic(o, folder, w);
  EXPECT_EQ(stopped.pattern_ids.size(), 2u);
  const Recording cut = OpenRecording(folder);
  ASSERT_EQ(cut.num_frames(), 2);
  EXPECT_EQ(cut.meta.at("complete"), "true");
  EXPECT_EQ(cut.meta.at("frames"), "2");
  EXPECT_EQ(cut.meta.at("stopped"), "by request after 2 of 3 frames");
  EXPECT_EQ(cv::norm(LoadRecordingFrame(cut, 1).left, whole.left[1], cv::NORM_INF), 0.0);
  EXPECT_TRUE(std::filesystem::exists(folder + "/ground_truth/depth_left_m.pfm"));
}

// Pixel jitter: δ has the asked σ, the ground truth is that of the jittered ray (a fronto-parallel plane keeps
// its depth, the point's x moves by Z/f·δu), the space-time disparity stays as exact as without jitter (both
// cameras see each point with the same δ), and the true points are written beside the depth.
TEST(Synth, PixelJitterMovesRaysButKeepsTheDisparity) {
  SynthOptions o = Small(SynthScene::kPlane);
  o.width = 160;
  o.height = 120;
  o.frames = 8;
  o.pixel_jitter_px = 0.3;
  o.pixel_jitter_cell_px = 4.0;
  const SynthRecording rec = RenderSynthetic(o);
  ASSERT_EQ(rec.pixel_jitter_px.type(), CV_32FC2);
  cv::Scalar mean, dev;
  cv::meanStdDev(rec.pixel_jitter_px, mean, dev);
  // 41×31 grid nodes per component: the field's sample σ is within a few % of 0.3 (10% allowed).
  EXPECT_NEAR(dev[0], 0.3, 0.03);
  EXPECT_NEAR(dev[1], 0.3, 0.03);
  for (int y = 0; y < rec.depth_m.rows; y += 7)
    for (int x = 0; x < rec.depth_m.cols; x += 5) EXPECT_NEAR(rec.depth_m.at<float>(y, x), 1.0, 1e-6);
  SpaceTimeMatcherOptions m;
  m.min_disparity_px = 4;
  m.num_disparities = 24;
  const DisparityResult r = SpaceTimeMatcher(m).Match(rec.left, rec.right);
  std::vector<float> err;
  for (int y = 5; y < rec.depth_m.rows - 5; ++y)
    for (int x = 30; x < rec.depth_m.cols - 5; ++x) {
      const float d = r.disparity_px.at<float>(y, x);
      if (std::isfinite(d)) err.push_back(std::abs(d - rec.disparity_px.at<float>(y, x)));
    }
  ASSERT_GT(err.size(), 1000u);
  std::nth_element(err.begin(), err.begin() + err.size() / 2, err.end());
  // Without jitter the median error on this plane is ~0.02 px; a disparity that followed δu would be off by
  // its median |δu| = 0.67·0.3 = 0.2 px.
  EXPECT_LT(err[err.size() / 2], 0.05);
  const std::string folder = TempPath("synth_jitter_test");
  std::filesystem::remove_all(folder);
  WriteSyntheticRecording(rec, o, folder);
  const cv::Mat points = ReadPfm(folder + "/ground_truth/points_left_m.pfm");
  ASSERT_EQ(points.type(), CV_32FC3);
  const int u = 37, v = 21;
  const cv::Vec2f delta = rec.pixel_jitter_px.at<cv::Vec2f>(v, u);
  EXPECT_NEAR(points.at<cv::Vec3f>(v, u)[0], (u + delta[0] - rec.intrinsics.cx_px) / rec.intrinsics.fx_px, 1e-6);
  EXPECT_NEAR(points.at<cv::Vec3f>(v, u)[2], 1.0, 1e-6);
  std::filesystem::remove_all(folder);
}

TEST(Synth, BadOptionsThrow) {
  SynthOptions o;
  o.frames = 0;
  EXPECT_THROW(RenderSynthetic(o), Error);
  EXPECT_THROW(ParseSynthScene("teapot"), Error);
  EXPECT_THROW(ParseSynthPattern("checker"), Error);
  SynthOptions j;
  j.pixel_jitter_px = 3.0;
  EXPECT_THROW(RenderSynthetic(j), Error);
}

}  // namespace
}  // namespace rangebayes
