#include "fusion/model.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "core/error.h"
#include "synthetic.h"

namespace rangebayes {
namespace {

// Two views of the blob, the second started 3° off: PlaceScans aligns them, FuseModel smooths each, fuses and
// decimates, and the summary holds every step in the order of the scans.
TEST(Model, PlacesThenSmoothsFusesAndDecimates) {
  const Mesh truth = testing::MakeBlob();
  const std::vector<Eigen::Isometry3d> reference = {testing::ViewPose(0), testing::ViewPose(60)};
  const std::vector<Scan> scans = testing::RenderViews(truth, reference, 1e-4);
  std::vector<Eigen::Isometry3d> start = reference;
  start[1] = Eigen::AngleAxisd(3 * M_PI / 180, Eigen::Vector3d::UnitX()) * start[1];
  ModelOptions options;
  options.smooth = true;
  options.decimate = true;
  options.decimation.target_faces = 500;
  std::set<std::string> stages;
  std::vector<double> alignment;  // the fractions reported while aligning
  options.progress = [&](double fraction, std::string_view stage) {
    stages.emplace(stage);
    if (stage == "alignment") alignment.push_back(fraction);
  };
  ModelSummary summary;
  const std::vector<Eigen::Isometry3d> poses = PlaceScans(scans, start, options, &summary);
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_TRUE(poses[0].isApprox(start[0]));  // the first scan keeps its pose
  const PoseError error = RelativePoseError(poses[0], poses[1], reference[0], reference[1]);
  EXPECT_LT(error.rotation_deg, 0.2);
  EXPECT_GT(summary.registration.iterations, 0);
  EXPECT_NE(summary.pair_report.find("view0 view1 "), std::string::npos) << summary.pair_report;
  // Eight reports within each step's linearisation (the finest level's take seconds on real scans), one after it.
  ASSERT_EQ(static_cast<int>(alignment.size()), 9 * summary.registration.iterations);
  EXPECT_TRUE(std::is_sorted(alignment.begin(), alignment.end()));
  EXPECT_GT(alignment.front(), 0.0);
  EXPECT_EQ(alignment.back(), 1.0);

  const Mesh model = FuseModel(scans, poses, options, &summary);
  ASSERT_EQ(summary.smoothing.size(), 2u);
  EXPECT_GT(summary.smoothing[1].iterations, 0);
  EXPECT_GT(summary.fusion.faces, 2000);
  ASSERT_TRUE(summary.decimated);
  EXPECT_EQ(summary.decimation.input_faces, summary.fusion.faces);
  EXPECT_LE(model.num_faces(), 500);
  EXPECT_GT(model.num_faces(), 250);
  EXPECT_EQ(stages, (std::set<std::string>{"alignment", "smoothing view0", "smoothing view1", "decimation"}));
}

// Without align the given poses are kept when they pass the check, and named (with the pair table already in the
// summary) when they do not; one scan is fused as it is, and aligning one scan is an error.
TEST(Model, GivenPosesAreCheckedAndKept) {
  const Mesh truth = testing::MakeBlob();
  const std::vector<Eigen::Isometry3d> reference = {testing::ViewPose(0), testing::ViewPose(60)};
  const std::vector<Scan> scans = testing::RenderViews(truth, reference, 1e-4);
  ModelOptions options;
  options.align = false;
  ModelSummary summary;
  const std::vector<Eigen::Isometry3d> kept = PlaceScans(scans, reference, options, &summary);
  EXPECT_TRUE(kept[1].isApprox(reference[1], 0.0));

  std::vector<Eigen::Isometry3d> off = reference;
  off[1] = Eigen::AngleAxisd(25 * M_PI / 180, Eigen::Vector3d::UnitY()) * off[1];
  ModelSummary failed;
  try {
    PlaceScans(scans, off, options, &failed);
    ADD_FAILURE() << "poses 25 degrees off were accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("view0, view1: the given poses do not align them"), std::string::npos)
        << e.what();
  }
  EXPECT_NE(failed.pair_report.find("view1 view0 "), std::string::npos) << failed.pair_report;

  // Poses that place the scans apart (no overlap) are not judged, and said: two views 10 cm apart were fused side by
  // side without a word. A calibrated rig may place scans that meet no other, so it is no error.
  std::vector<Eigen::Isometry3d> apart = reference;
  apart[1].pretranslate(Eigen::Vector3d(10.0, 0, 0));
  ModelSummary placed;
  EXPECT_NO_THROW(PlaceScans(scans, apart, options, &placed));
  EXPECT_EQ(placed.registration.apart, (std::vector<int>{0, 1}));
  ASSERT_EQ(placed.notices.size(), 1u);
  EXPECT_NE(placed.notices[0].find("view0, view1: the given poses place them apart from every other scan"),
            std::string::npos)
      << placed.notices[0];
  PlaceScans(scans, reference, options, &placed);
  EXPECT_TRUE(placed.notices.empty());

  const std::vector<Scan> one = {scans[0]};
  EXPECT_TRUE(PlaceScans(one, {off[1]}, options, &summary)[0].isApprox(off[1], 0.0));
  EXPECT_TRUE(summary.pair_report.empty());
  EXPECT_GT(FuseModel(one, {reference[0]}, options, &summary).num_faces(), 1000);
  options.align = true;
  EXPECT_THROW(PlaceScans(one, {reference[0]}, options), Error);
  EXPECT_THROW(PlaceScans(scans, {reference[0]}, options), Error);  // one pose for two scans
}

}  // namespace
}  // namespace rangebayes
