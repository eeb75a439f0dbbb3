#include "core/scan_poses.h"

#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "core/error.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

std::string ErrorOf(const std::string& name, const std::string& text) {
  try {
    ReadScanPoses(WriteTempFile(name, text));
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

TEST(ScanPoses, ReadsTheStanfordConventionAndRoundTrips) {
  // Two lines of bun.conf: p_world = R(q)ᵀ p + t.
  const std::string path = WriteTempFile("bun.conf",
                                         "camera -0.0172 -0.0936 -0.734  -0.0461723 0.970603 -0.235889 0.0124573\n"
                                         "bmesh bun000.ply 0 0 0 0 0 0 1\n"
                                         "bmesh bun045.ply -0.0520211 -0.000383981 -0.0109223 0.00548449 -0.294635 "
                                         "-0.0038555 0.955586\n");
  const std::vector<ScanPose> poses = ReadScanPoses(path);
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_TRUE(poses[0].world_from_scan.isApprox(Eigen::Isometry3d::Identity()));
  const Eigen::Quaterniond q = Eigen::Quaterniond(0.955586, 0.00548449, -0.294635, -0.0038555).normalized();
  EXPECT_TRUE(poses[1].world_from_scan.linear().isApprox(q.toRotationMatrix().transpose(), 1e-12));
  EXPECT_NEAR(poses[1].world_from_scan.translation().x(), -0.0520211, 1e-15);
  const std::string again = TempPath("again.conf");
  WriteScanPoses(poses, again);
  const std::vector<ScanPose> read = ReadScanPoses(again);
  ASSERT_EQ(read.size(), 2u);
  EXPECT_EQ(read[1].file, "bun045.ply");
  EXPECT_TRUE(read[1].world_from_scan.isApprox(poses[1].world_from_scan, 1e-14));
  EXPECT_EQ(FindScanPose(read, "some/folder/bun045.ply", again).file, "bun045.ply");
  // A mirror (orthogonal, determinant −1) has no quaternion: it was written as some other rotation.
  std::vector<ScanPose> mirrored = poses;
  mirrored[1].world_from_scan.linear() = Eigen::Vector3d(1, 1, -1).asDiagonal();
  EXPECT_THROW(WriteScanPoses(mirrored, TempPath("mirror.conf")), Error);
}

TEST(ScanPoses, BadFilesNameTheScan) {
  EXPECT_NE(ErrorOf("norm.conf", "bmesh a.ply 0 0 0 0 0 0 2\n").find("scan a.ply: quaternion"), std::string::npos);
  EXPECT_NE(ErrorOf("nan.conf", "bmesh b.ply 0 nan 0 0 0 0 1\n").find("scan b.ply: value 2"), std::string::npos);
  EXPECT_NE(ErrorOf("short.conf", "bmesh c.ply 0 0 0 0 0 1\n").find("scan c.ply has 6 of the 7"), std::string::npos);
  EXPECT_NE(ErrorOf("word.conf", "bmesh d.ply 0 0 x 0 0 0 1\n").find("'x' is not a number"), std::string::npos);
  EXPECT_NE(ErrorOf("twice.conf", "bmesh e.ply 0 0 0 0 0 0 1\nbmesh e.ply 0 0 0 0 0 0 1\n").find("listed twice"),
            std::string::npos);
  EXPECT_NE(ErrorOf("key.conf", "mesh f.ply 0 0 0 0 0 0 1\n").find("unknown keyword 'mesh'"), std::string::npos);
  EXPECT_NE(ErrorOf("none.conf", "camera 0 0 0 0 0 0 1\n").find("no 'bmesh"), std::string::npos);
  const std::vector<ScanPose> poses = ReadScanPoses(WriteTempFile("one.conf", "bmesh g.ply 0 0 0 0 0 0 1\n"));
  try {
    FindScanPose(poses, "h.ply", "one.conf");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("one.conf: no pose for scan h.ply"), std::string::npos);
  }
}

}  // namespace
}  // namespace rangebayes
