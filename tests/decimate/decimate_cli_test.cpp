// End-to-end: the `rangebayes decimate` subcommand as a user runs it.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

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

  // The corner normals, read from the OBJ text (ReadMesh drops them): every face corner names a normal
  // ("f v//n"), every normal is unit length, and a vertex where patches meet has one normal per patch: more
  // normals than vertices. The shading normals are smooth within a patch, so a corner's normal lies close to its
  // face's: measured 99.1% of the corners within 30° (median 3.9°; the few beyond on sliver faces of 1% of the
  // median area). One normal per vertex, averaged over the patches that meet there, puts 56% within 30°.
  std::ifstream obj(dir + "/out.obj");
  std::vector<Eigen::Vector3d> positions, normals;
  std::vector<std::array<std::pair<int, int>, 3>> faces;
  int malformed_corners = 0;
  for (std::string line; std::getline(obj, line);) {
    std::istringstream in(line);
    std::string tag;
    in >> tag;
    if (tag == "v" || tag == "vn") {
      Eigen::Vector3d p;
      in >> p.x() >> p.y() >> p.z();
      (tag == "v" ? positions : normals).push_back(p);
    } else if (tag == "f") {
      std::array<std::pair<int, int>, 3> face{};
      std::string corner;
      for (auto& [v, n] : face) {
        in >> corner;
        const size_t slashes = corner.find("//");
        if (slashes == std::string::npos) {
          ++malformed_corners;
          continue;
        }
        v = std::stoi(corner.substr(0, slashes));
        n = std::stoi(corner.substr(slashes + 2));
      }
      malformed_corners += static_cast<bool>(in >> corner);  // a fourth corner
      faces.push_back(face);
    }
  }
  ASSERT_EQ(static_cast<int>(faces.size()), out.num_faces());
  EXPECT_EQ(malformed_corners, 0);
  EXPECT_EQ(static_cast<int>(positions.size()), out.num_vertices());
  EXPECT_GT(normals.size(), positions.size());
  for (const Eigen::Vector3d& n : normals) EXPECT_NEAR(n.norm(), 1.0, 1e-9);
  int out_of_range = 0, corners = 0, within_30_deg = 0;
  for (const auto& face : faces) {
    bool in_range = true;
    for (const auto& [v, n] : face) {
      in_range = in_range && v >= 1 && v <= static_cast<int>(positions.size()) && n >= 1 &&
                 n <= static_cast<int>(normals.size());
    }
    if (!in_range) {
      ++out_of_range;
      continue;
    }
    const Eigen::Vector3d a = positions[face[0].first - 1], b = positions[face[1].first - 1],
                          c = positions[face[2].first - 1];
    const Eigen::Vector3d face_normal = (b - a).cross(c - a);
    for (const auto& corner : face) {
      ++corners;
      within_30_deg += normals[corner.second - 1].dot(face_normal.normalized()) > std::cos(30.0 * M_PI / 180.0);
    }
  }
  EXPECT_EQ(out_of_range, 0);
  EXPECT_GE(within_30_deg, 0.95 * corners);
}

TEST(DecimateCli, PolygonsAndTargetFaces) {
  const std::string dir = FreshTempDir("decimate_cli_poly");
  RunResult r = RunRangebayes("decimate tests/data/meshes/fandisk_gt.obj " + dir + "/poly.obj --lambda 5 --polygons");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // The summary says what the file holds (its "output: N faces" counts triangles).
  const size_t said = r.output.find("written as one polygon per patch: ");
  ASSERT_NE(said, std::string::npos) << r.output;
  std::ifstream obj(dir + "/poly.obj");
  int faces = 0;
  for (std::string line; std::getline(obj, line);) faces += line.starts_with("f ") ? 1 : 0;
  EXPECT_EQ(r.output.substr(said + 34, r.output.find(' ', said + 34) - said - 34), std::to_string(faces)) << r.output;
  r = RunRangebayes("decimate tests/data/meshes/fandisk_gt.obj " + dir + "/t.ply --target-faces 400 --quiet");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const Mesh out = ReadMesh(dir + "/t.ply");
  // The budgeted chain pass stops at the target or one collapse (two faces on this closed mesh) below.
  EXPECT_LE(out.num_faces(), 400);
  EXPECT_GE(out.num_faces(), 399);
  EXPECT_NE(r.output.find("lambda search"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("not reached"), std::string::npos) << r.output;
  // More faces than the patches need at any λ (fandisk's flat faces merge at the smallest): fewer faces, said so
  // (it was 8,814 for 12,000 without a word).
  r = RunRangebayes("decimate tests/data/meshes/fandisk_gt.obj " + dir + "/t12k.ply --target-faces 12000");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_LT(ReadMesh(dir + "/t12k.ply").num_faces(), 12000 - 1);
  EXPECT_NE(r.output.find("target 12000 faces not reached: "), std::string::npos) << r.output;
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

  // A pose with a reversed face: the error names both files and what differs (it said "pose 2 does not have the
  // connectivity of pose 1 (N vertices, M faces vs N, M)").
  Mesh c = b;
  std::swap(c.F(0, 1), c.F(0, 2));
  WriteMesh(c, dir + "/pose3.obj");
  const RunResult reversed =
      RunRangebayes("decimate " + dir + "/pose1.obj " + dir + "/pose3.obj --out " + dir + "/out3 --lambda 5 --quiet");
  EXPECT_EQ(reversed.exit_code, 1) << reversed.output;
  EXPECT_NE(reversed.output.find(dir + "/pose3.obj does not have the connectivity of " + dir +
                                 "/pose1.obj: face 1 (counting from 1) has reversed orientation"),
            std::string::npos)
      << reversed.output;
}

// Usage errors: exit 2 and one line that says what is wrong.
TEST(DecimateCli, UsageAndInputErrors) {
  const std::pair<std::string, std::string> usage[] = {
      {"decimate tests/data/meshes/fandisk_gt.obj", "give IN OUT, or several poses with --out DIR (got 1 files)"},
      {"decimate a.obj b.obj --lambda 1 --target-faces 5", "--lambda excludes --target-faces"},
      {"decimate a.obj b.obj --lambda -1", "--lambda: must be a finite number > 0, got -1"},
      // The picture over the mesh: the mesh was lost, exit 0.
      {"decimate tests/data/meshes/fandisk_gt.obj /tmp/rb_same.obj --png /tmp/rb_same.obj",
       "OUT and --png name the same file (/tmp/rb_same.obj): the second would replace the first"}};
  for (const auto& [arguments, message] : usage) {
    const RunResult r = RunRangebayes(arguments);
    EXPECT_EQ(r.exit_code, 2) << arguments;
    EXPECT_EQ(r.output, "rangebayes decimate: error: " + message + " (see --help)\n") << arguments;
  }
  const RunResult missing = RunRangebayes("decimate no_such_mesh.obj /tmp/rb_x.obj");
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_NE(missing.output.find("no_such_mesh.obj"), std::string::npos);
}

// `decimate IN IN` replaced the input by its result (exit 0) while animated mode refused a pose overwritten by
// its own result: refused too, before any work, the input left as it was.
TEST(DecimateCli, RefusesToOverwriteItsInput) {
  const std::string dir = FreshTempDir("decimate_cli_in_place");
  const Mesh a = ReadMesh("tests/data/meshes/fandisk_gt.obj");
  WriteMesh(a, dir + "/in.obj");
  const auto before = std::filesystem::last_write_time(dir + "/in.obj");
  const RunResult r = RunRangebayes("decimate " + dir + "/in.obj " + dir + "/../" +
                                    std::filesystem::path(dir).filename().string() + "/in.obj --quiet");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("would be overwritten by its own result"), std::string::npos) << r.output;
  EXPECT_EQ(std::filesystem::last_write_time(dir + "/in.obj"), before);
  EXPECT_EQ(ReadMesh(dir + "/in.obj").F, a.F);
}

// The help said [0, 1) while the check refused values above 0.99: both say [0, 0.99].
TEST(DecimateCli, ChainReserveHelpAndCheckAgree) {
  const RunResult help = RunRangebayes("decimate --help");
  EXPECT_NE(help.output.find("detail, in [0, 0.99]"), std::string::npos) << help.output;
  const RunResult high = RunRangebayes("decimate a.obj b.obj --target-faces 10 --chain-reserve 0.995");
  EXPECT_EQ(high.exit_code, 2) << high.output;
  EXPECT_NE(high.output.find("[0, 0.99]"), std::string::npos) << high.output;
}

}  // namespace
}  // namespace rangebayes
