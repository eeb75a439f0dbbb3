// End-to-end: the `rangebayes decimate` subcommand as a user runs it.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "core/mesh_io.h"
#include "tests/apps/run_binary.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

TEST(DecimateCli, WritesMeshWithCornerNormalsAndPicture) {
  const std::string dir = FreshTempDir("decimate_cli_static");
  const RunResult r = RunRangebayes("decimate tests/data/meshes/fandisk_gt.obj " + dir + "/out.obj --lambda 5 --png " +
                                    dir + "/out.png --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("patches:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("fuses"), std::string::npos) << r.output;
  const Mesh out = ReadMesh(dir + "/out.obj");
  EXPECT_GT(out.num_faces(), 12);
  EXPECT_LT(out.num_faces(), 1000);
  EXPECT_TRUE(std::filesystem::file_size(dir + "/out.png") > 1000);
}

TEST(DecimateCli, PolygonsAndTargetFaces) {
  const std::string dir = FreshTempDir("decimate_cli_poly");
  RunResult r = RunRangebayes("decimate tests/data/meshes/fandisk_gt.obj " + dir + "/poly.obj --lambda 5 --polygons");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("one polygon per patch"), std::string::npos);
  r = RunRangebayes("decimate tests/data/meshes/fandisk_gt.obj " + dir + "/t.ply --target-faces 400 --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const Mesh out = ReadMesh(dir + "/t.ply");
  // The budgeted chain pass stops at the target or one collapse (two faces on this closed mesh) below.
  EXPECT_LE(out.num_faces(), 400);
  EXPECT_GE(out.num_faces(), 399);
  EXPECT_NE(r.output.find("lambda search"), std::string::npos) << r.output;
}

// A smoothed stereo mesh (one frame of a synthetic recording through `replay`): the λ search's guide, calibrated
// on fits whose count is the budget the chain pass filled, over-predicts there, so a search that moves one
// resolution step per round took 20 full decimations at 200 faces; it gallops down instead and closes its bracket.
TEST(DecimateCli, TargetFacesSearchDoesNotCreepOnASmoothedStereoMesh) {
  const std::string dir = FreshTempDir("decimate_cli_smoothed_stereo");
  RunResult r = RunRangebayes("synth --scene planes --width 160 --height 120 --frames 1 --out " + dir + "/rec -q");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = RunRangebayes("replay " + dir + "/rec --out " + dir + "/out --no-decimate -q");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  r = RunRangebayes("decimate " + dir + "/out/smoothed/000000.ply " + dir + "/d.ply --target-faces 200 -q");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // "lambda: L (found in N full decimations)", "straightened patches need A faces at lambda L1, fit in B at lambda L2"
  const size_t found = r.output.find("found in ");
  const size_t bracket = r.output.find("faces at lambda ");
  ASSERT_NE(found, std::string::npos) << r.output;
  ASSERT_NE(bracket, std::string::npos) << r.output;
  const size_t second = r.output.find("at lambda ", bracket + 16);
  ASSERT_NE(second, std::string::npos) << r.output;
  const int steps = std::stoi(r.output.substr(found + 9));
  const double too_many = std::stod(r.output.substr(bracket + 16));
  const double fits = std::stod(r.output.substr(second + 10));
  EXPECT_LE(steps, 12) << r.output;
  EXPECT_GT(too_many, 0.0) << r.output;  // the bracket closed: a λ with too many faces was found
  EXPECT_LE(fits, too_many * 1.021) << r.output;  // within lambda_resolution (0.02), printed to 6 digits
}

TEST(DecimateCli, AnimatedWritesOneMeshPerPose) {
  const std::string dir = FreshTempDir("decimate_cli_animated");
  Mesh a = ReadMesh("tests/data/meshes/fandisk_gt.obj");
  Mesh b = a;
  b.V.col(2) += 0.05 * b.V.col(0).cwiseProduct(b.V.col(0));  // a bent copy
  WriteMesh(a, dir + "/pose1.obj");
  WriteMesh(b, dir + "/pose2.obj");
  const RunResult r =
      RunRangebayes("decimate " + dir + "/pose1.obj " + dir + "/pose2.obj --out " + dir + "/out --lambda 5 --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const Mesh o1 = ReadMesh(dir + "/out/pose1.obj"), o2 = ReadMesh(dir + "/out/pose2.obj");
  EXPECT_EQ(o1.F, o2.F);
  EXPECT_GT(o1.num_faces(), 12);

  // Two poses of one name would be written to one file (the first result lost), and a pose in the output folder
  // would be overwritten by its result: both refused before any work, the pose left as it was.
  std::filesystem::create_directories(dir + "/other");
  WriteMesh(b, dir + "/other/pose1.ply");
  const RunResult same = RunRangebayes("decimate " + dir + "/pose1.obj " + dir + "/other/pose1.ply --out " + dir +
                                       "/out2 --lambda 5 --quiet");
  EXPECT_EQ(same.exit_code, 2) << same.output;
  EXPECT_NE(same.output.find("would both be written to"), std::string::npos) << same.output;
  EXPECT_FALSE(std::filesystem::exists(dir + "/out2"));
  const auto before = std::filesystem::last_write_time(dir + "/pose1.obj");
  const RunResult onto =
      RunRangebayes("decimate " + dir + "/pose1.obj " + dir + "/pose2.obj --out " + dir + " --lambda 5 --quiet");
  EXPECT_EQ(onto.exit_code, 2) << onto.output;
  EXPECT_NE(onto.output.find("would be overwritten by its own result"), std::string::npos) << onto.output;
  EXPECT_EQ(std::filesystem::last_write_time(dir + "/pose1.obj"), before);
  EXPECT_EQ(ReadMesh(dir + "/pose1.obj").F, a.F);
}

TEST(DecimateCli, UsageAndInputErrors) {
  EXPECT_EQ(RunRangebayes("decimate tests/data/meshes/fandisk_gt.obj").exit_code, 2);
  EXPECT_EQ(RunRangebayes("decimate a.obj b.obj --lambda 1 --target-faces 5").exit_code, 2);
  EXPECT_EQ(RunRangebayes("decimate a.obj b.obj --lambda -1").exit_code, 2);
  const RunResult missing = RunRangebayes("decimate no_such_mesh.obj /tmp/rb_x.obj");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.output.find("no_such_mesh.obj"), std::string::npos);
}

}  // namespace
}  // namespace rangebayes
