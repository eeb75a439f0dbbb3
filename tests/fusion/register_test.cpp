#include "fusion/register.h"

#include <gtest/gtest.h>

#include <random>
#include <string>

#include "core/error.h"
#include "synthetic.h"

namespace rangebayes {
namespace {

Eigen::Isometry3d Perturb(const Eigen::Isometry3d& pose, double max_deg, double max_shift, std::mt19937_64* rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  Eigen::Vector3d axis(u(*rng), u(*rng), u(*rng));
  Eigen::Isometry3d delta = Eigen::Isometry3d::Identity();
  delta.linear() = Eigen::AngleAxisd(max_deg * M_PI / 180 * std::abs(u(*rng)), axis.normalized()).toRotationMatrix();
  delta.translation() = max_shift / std::sqrt(3.0) * Eigen::Vector3d(u(*rng), u(*rng), u(*rng));
  return delta * pose;
}

TEST(Register, RecoversAKnownPerturbationOfThreeViews) {
  const Mesh truth = testing::MakeBlob();
  const std::vector<Eigen::Isometry3d> poses = {testing::ViewPose(0), testing::ViewPose(70, 15),
                                                testing::ViewPose(-70, -10)};
  const std::vector<Scan> scans = testing::RenderViews(truth, poses, 5e-5);
  std::mt19937_64 rng(7);
  std::vector<Eigen::Isometry3d> start = poses;
  for (size_t k = 1; k < start.size(); ++k) start[k] = Perturb(poses[k], 5.0, 0.01, &rng);
  RegisterSummary summary;
  const std::vector<Eigen::Isometry3d> result = RegisterScans(scans, start, {}, &summary);
  EXPECT_TRUE(result[0].isApprox(poses[0]));
  for (size_t k = 1; k < result.size(); ++k) {
    const PoseError start_error = RelativePoseError(start[0], start[k], poses[0], poses[k]);
    const PoseError error = RelativePoseError(result[0], result[k], poses[0], poses[k]);
    EXPECT_GT(start_error.rotation_deg, 0.5);
    // Tolerances: 0.1° and 0.2 mm, a tenth of a grid cell (1.4 mm), noise 0.05 mm.
    EXPECT_LT(error.rotation_deg, 0.1) << "scan " << k << ": " << summary.BriefReport();
    EXPECT_LT(error.translation, 2e-4) << "scan " << k;
  }
  // The neighbouring views (70° apart) overlap well and their residuals are of the order of the modelled
  // noise; the two side views (140° apart) share only a grazing rim.
  int good = 0;
  for (const PairReport& pair : summary.pairs) {
    if (pair.a != 0 && pair.b != 0) continue;
    EXPECT_GT(pair.overlap, 0.1);
    EXPECT_LT(pair.rms_sigma, 3.0);
    ++good;
  }
  EXPECT_EQ(good, 4);
}

TEST(Register, NonOverlappingScanIsNamed) {
  const Mesh truth = testing::MakeBlob();
  std::vector<Eigen::Isometry3d> poses = {testing::ViewPose(0), testing::ViewPose(60)};
  const std::vector<Scan> scans = testing::RenderViews(truth, poses, 5e-5);
  poses[1].translation() += Eigen::Vector3d(0.5, 0, 0);  // half a metre away from the other scan
  try {
    RegisterScans(scans, poses);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("view1: overlaps no other scan"), std::string::npos) << e.what();
  }
}

// A scan given twice (or a copy of it) would count its measurements twice in the fused model: refused, in the
// alignment and in the check of given poses alike.
TEST(Register, AScanGivenTwiceIsRefused) {
  const Mesh truth = testing::MakeBlob();
  const std::vector<Eigen::Isometry3d> poses = {testing::ViewPose(0), testing::ViewPose(60), testing::ViewPose(0)};
  std::vector<Scan> scans = testing::RenderViews(truth, {poses[0], poses[1]}, 5e-5);
  scans.push_back(scans[0]);
  scans[2].name = "copy";
  for (const bool align : {true, false}) {
    try {
      if (align) {
        RegisterScans(scans, poses);
      } else {
        CheckPoses(scans, poses);
      }
      ADD_FAILURE() << "no error, align " << align;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("copy is the same scan as view0 (the same vertices): give each scan once"),
                std::string::npos)
          << e.what();
    }
  }
}

// A scan in other units (here millimetres among metres) overlaps nothing at any pose: the error says so.
TEST(Register, AScanInOtherUnitsIsNamedWithItsSize) {
  const Mesh truth = testing::MakeBlob();
  const std::vector<Eigen::Isometry3d> poses = {testing::ViewPose(0), testing::ViewPose(60), testing::ViewPose(-60)};
  std::vector<Scan> scans = testing::RenderViews(truth, poses, 5e-5);
  scans[2].noisy.mesh.V *= 1000.0;
  for (Eigen::Matrix3d& c : scans[2].noisy.covariance) c *= 1e6;
  scans[2].mean_edge *= 1000.0;
  try {
    RegisterScans(scans, poses);
    FAIL() << "no error";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("view2: overlaps no other scan"), std::string::npos) << what;
    EXPECT_NE(what.find("times the size of the median scan"), std::string::npos) << what;
    EXPECT_NE(what.find("are its units those of the others?"), std::string::npos) << what;
  }
}

// A scan whose every vertex lies on or beside its boundary has nothing to align with: named as too small, not as
// a scan that overlaps nothing (what it was told before, with advice about its pose).
TEST(Register, ScanWithoutInteriorVerticesIsTooSmall) {
  const Mesh truth = testing::MakeBlob();
  const std::vector<Eigen::Isometry3d> poses = {testing::ViewPose(0), testing::ViewPose(60)};
  std::vector<Scan> scans = testing::RenderViews(truth, poses, 5e-5);
  NoisyMesh triangle;
  triangle.mesh.V = scans[1].noisy.mesh.V.topRows(3);
  triangle.mesh.F.resize(1, 3);
  triangle.mesh.F << 0, 1, 2;
  scans[1] = MakeScanFromMesh(triangle, "view1");
  try {
    RegisterScans(scans, poses);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("view1: no vertex lies more than"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("too small to align"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rangebayes
