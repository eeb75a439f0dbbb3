// `rangebayes info` and `rangebayes convert` as a user runs them.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>

#include "core/mesh_io.h"
#include "tests/apps/run_binary.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

namespace fs = std::filesystem;

const char kAngel[] = "tests/data/meshes/real_angel_scan.obj";

class MeshCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    temp_ = std::make_unique<TempDir>(std::string("mesh_cli_") +
                                      ::testing::UnitTest::GetInstance()->current_test_info()->name());
    dir_ = temp_->path();
  }
  void TearDown() override { temp_.reset(); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }
  std::unique_ptr<TempDir> temp_;
  fs::path dir_;
};

TEST_F(MeshCliTest, InfoPrintsCountsAndValidation) {
  const RunResult r = RunRangebayes(std::string("info ") + kAngel);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("vertices:         24566"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("faces:            48090"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("mean edge length"), std::string::npos);
  EXPECT_NE(r.output.find("validation"), std::string::npos);
}

TEST_F(MeshCliTest, InfoJson) {
  const RunResult r = RunRangebayes("info tests/data/meshes/block_gt.obj --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output);
  EXPECT_EQ(j["vertices"], 8771);
  EXPECT_EQ(j["faces"], 17550);
  EXPECT_EQ(j["components"], 1);
  EXPECT_EQ(j["boundary_loops"], 0);
  EXPECT_EQ(j["has_normals"], true);
  EXPECT_EQ(j["validation"]["clean"], true);
  EXPECT_GT(j["mean_edge_length"].get<double>(), 0.0);
}

// A file name that is not UTF-8 (a valid Linux name) is printed with U+FFFD for its byte; json::dump threw on it
// and `info --json` printed an error instead.
TEST_F(MeshCliTest, InfoJsonOfAFileNameThatIsNotUtf8) {
  const std::string path = Path("\xff.off");
  std::ofstream(path) << "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  const RunResult r = RunRangebayes("info '" + path + "' --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const nlohmann::json j = nlohmann::json::parse(r.output);
  EXPECT_EQ(j["file"], Path("\xEF\xBF\xBD.off"));
  EXPECT_EQ(j["faces"], 1);
}

TEST_F(MeshCliTest, InfoOnBadFilesIsOneErrorLine) {
  RunResult r = RunRangebayes("info " + Path("missing.ply"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("missing.ply"), std::string::npos);
  EXPECT_EQ(r.output.find('\n'), r.output.size() - 1) << r.output;
  std::ofstream(Path("bad.off")) << "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 9\n";
  r = RunRangebayes("info " + Path("bad.off"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("bad.off: line 6: face 0 uses vertex 9"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find('\n'), r.output.size() - 1) << r.output;
}

TEST_F(MeshCliTest, ConvertRoundTripIsExact) {
  const Mesh original = ReadMesh(kAngel);
  ASSERT_EQ(RunRangebayes(std::string("convert -q ") + kAngel + " " + Path("a.ply")).exit_code, 0);
  ASSERT_EQ(RunRangebayes("convert -q --big-endian " + Path("a.ply") + " " + Path("b.ply")).exit_code, 0);
  ASSERT_EQ(RunRangebayes("convert -q --ascii " + Path("b.ply") + " " + Path("c.ply")).exit_code, 0);
  ASSERT_EQ(RunRangebayes("convert -q " + Path("c.ply") + " " + Path("d.off")).exit_code, 0);
  ASSERT_EQ(RunRangebayes("convert -q " + Path("d.off") + " " + Path("e.obj")).exit_code, 0);
  const Mesh back = ReadMesh(Path("e.obj"));
  ASSERT_EQ(back.V.rows(), original.V.rows());
  ASSERT_EQ(back.F.rows(), original.F.rows());
  EXPECT_TRUE(back.V == original.V);
  EXPECT_TRUE(back.F == original.F);
}

TEST_F(MeshCliTest, ConvertUsageErrors) {
  // Usage errors: exit 2, one line that says what is wrong, and nothing written.
  const std::pair<std::string, std::string> usage[] = {
      {std::string("convert --ascii ") + kAngel + " " + Path("x.obj"),
       "--ascii and --big-endian apply to .ply output only"},
      {std::string("convert --ascii --big-endian ") + kAngel + " " + Path("x.ply"),
       "--ascii and --big-endian exclude each other"},
      {std::string("convert ") + kAngel, "OUT is required"}};
  for (const auto& [arguments, message] : usage) {
    const RunResult r = RunRangebayes(arguments);
    EXPECT_EQ(r.exit_code, 2) << arguments;
    EXPECT_EQ(r.output, "rangebayes convert: error: " + message + " (see --help)\n") << arguments;
  }
  EXPECT_FALSE(std::filesystem::exists(Path("x.obj")));
  EXPECT_FALSE(std::filesystem::exists(Path("x.ply")));
  const RunResult r = RunRangebayes(std::string("convert ") + kAngel + " " + Path("x.stl"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("unknown mesh format"), std::string::npos) << r.output;
  const RunResult none = RunRangebayes(std::string("info /dev/null"));
  EXPECT_EQ(none.exit_code, 1);
  EXPECT_NE(none.output.find("/dev/null: no file extension to tell the mesh format"), std::string::npos) << none.output;
}

// An output that cannot be written is refused before the work, not after it: the commands print their input line
// (smooth), their progress (learn-prior) or read their meshes only after the check.
// eval compares surfaces: a mesh without faces (a point cloud) or with a vertex that is not finite is named.
TEST_F(MeshCliTest, EvalNamesMeshesItCannotCompare) {
  std::ofstream(Path("points.ply")) << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                       "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
  const RunResult r = RunRangebayes("eval " + std::string(kAngel) + " " + Path("points.ply") + " --surface-only");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("points.ply: no faces (eval compares surfaces)"), std::string::npos) << r.output;
  Mesh broken = ReadMesh(kAngel);
  broken.V(7, 1) = std::numeric_limits<double>::quiet_NaN();
  WriteMesh(broken, Path("broken.ply"));
  for (const std::string& order : {std::string(kAngel) + " " + Path("broken.ply"), Path("broken.ply") + " " + kAngel}) {
    const RunResult nan = RunRangebayes("eval " + order);
    EXPECT_EQ(nan.exit_code, 1);
    EXPECT_NE(nan.output.find("broken.ply: 1 of 24566 vertices have non-finite coordinates"), std::string::npos)
        << nan.output;
  }
}

TEST_F(MeshCliTest, OutputsThatCannotBeWrittenAreRefusedBeforeTheWork) {
  const std::string block = "tests/data/meshes/block_noisy_gauss0.4.obj";
  RunResult r = RunRangebayes("smooth " + block + " " + Path("missing/out.ply"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("missing/out.ply: cannot create: folder " + Path("missing") + " does not exist"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("input:"), std::string::npos) << r.output;
  r = RunRangebayes("smooth " + block + " " + Path("out.ply") + " --png " + dir_.string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find(dir_.string() + ": is a directory"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("input:"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(Path("out.ply")));

  std::ofstream(Path("a_file")) << "x";
  r = RunRangebayes("decimate tests/data/meshes/fandisk_gt.obj tests/data/meshes/block_gt.obj --out " + Path("a_file"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("a_file: cannot create folder"), std::string::npos) << r.output;
  r = RunRangebayes("decimate tests/data/meshes/fandisk_gt.obj " + Path("a_file/out.obj"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("a_file/out.obj: cannot create: " + Path("a_file") + " is not a folder"), std::string::npos)
      << r.output;

  std::ofstream(Path("pairs.txt")) << fs::absolute(block).string() << " "
                                   << fs::absolute("tests/data/meshes/block_gt.obj").string() << "\n";
  r = RunRangebayes("learn-prior --pairs " + Path("pairs.txt") + " --out " + dir_.string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find(dir_.string() + ": is a directory"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("%"), std::string::npos) << r.output;  // no progress: nothing was learned
}

// An output that fails half-way (here a file size limit, as a full disk) leaves the file it would replace as it
// was and no partial file or temporary beside it: it was opened in place, truncated, and left cut.
TEST_F(MeshCliTest, AWriteThatFailsLeavesTheOldFile) {
  const std::string out = Path("out.ply");
  ASSERT_EQ(RunRangebayes("convert tests/data/meshes/trim-star_gt.obj " + out).exit_code, 0);
  std::ifstream old_in(out, std::ios::binary);
  const std::string before((std::istreambuf_iterator<char>(old_in)), std::istreambuf_iterator<char>());
  // The limit (ulimit -f, 512-byte blocks in sh) lets the old file be read but not a bigger one be written.
  const std::string command = std::string("cd '") + RB_SOURCE_DIR + "' && trap '' XFSZ && ulimit -f " +
                              std::to_string(before.size() / 512 + 1) + " && '" + RB_BINARY +
                              "' convert tests/data/meshes/block_gt.obj " + out + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  ASSERT_NE(pipe, nullptr);
  std::string output;
  std::array<char, 4096> buffer{};
  for (size_t n; (n = fread(buffer.data(), 1, buffer.size(), pipe)) > 0;) output.append(buffer.data(), n);
  const int status = pclose(pipe);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 1) << output;
  EXPECT_NE(output.find(out + ": write failed"), std::string::npos) << output;
  std::ifstream new_in(out, std::ios::binary);
  EXPECT_EQ(std::string((std::istreambuf_iterator<char>(new_in)), std::istreambuf_iterator<char>()), before);
  int entries = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir_)) ++entries;
  EXPECT_EQ(entries, 1);  // out.ply alone
}

// Pictures are PNG whatever the name (the encoder was chosen by the extension, and `--png pic` failed after the
// whole solve, its mesh written).
TEST_F(MeshCliTest, PngWithoutTheExtensionIsAPng) {
  const RunResult r = RunRangebayes("smooth tests/data/meshes/trim-star_gt.obj " + Path("s.ply") +
                                    " --tolerance fast --max-iterations 3 --png " + Path("picture") + " -q");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(Path("picture"), std::ios::binary);
  std::string magic(8, '\0');
  in.read(magic.data(), 8);
  EXPECT_EQ(magic, std::string("\x89PNG\r\n\x1a\n", 8));
}

// A result that cannot reach standard output is an error, not exit 0 with an empty or cut file.
TEST_F(MeshCliTest, AResultThatCannotBeWrittenToStandardOutputFails) {
  EXPECT_EQ(RunRangebayes("info tests/data/meshes/trim-star_gt.obj > /dev/full").exit_code, 1);
  EXPECT_EQ(RunRangebayes("info tests/data/meshes/trim-star_gt.obj --json > /dev/full").exit_code, 1);
  EXPECT_EQ(RunRangebayes("info tests/data/meshes/trim-star_gt.obj > /dev/null").exit_code, 0);
}

// A mesh without edges has no mean edge length (it said 0; JSON null as documented).
TEST_F(MeshCliTest, InfoOfPointsHasNoMeanEdgeLength) {
  std::ofstream(Path("points.off")) << "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n";
  RunResult r = RunRangebayes("info " + Path("points.off"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("mean edge length: n/a (no edges)"), std::string::npos) << r.output;
  r = RunRangebayes("info " + Path("points.off") + " --json");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(nlohmann::json::parse(r.output)["mean_edge_length"].is_null()) << r.output;
}

// A mesh at 1e300 (any unit system's coordinates are far below): `info` names it, and the commands that compute
// refuse it in one line, where `smooth` failed on a "not finite" covariance after printing "sigma -nan" and
// `decimate` wrote a mesh with a summary of NaN.
TEST_F(MeshCliTest, AMeshBeyondTheComputableScaleIsNamedAndRefused) {
  std::ofstream(Path("huge.off")) << "OFF\n4 2 0\n0 0 0\n1e300 0 0\n0 1e300 0\n1e300 1e300 0\n3 0 1 2\n3 1 3 2\n";
  RunResult r = RunRangebayes("info " + Path("huge.off"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("mean edge length: 1.08284e+300"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("3 vertices with a coordinate beyond ±1e+60"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("zero-area"), std::string::npos) << r.output;
  for (const std::string command : {"smooth", "decimate"}) {
    r = RunRangebayes(command + " " + Path("huge.off") + " " + Path("out.ply"));
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("vertex 1 lies at (1e+300, 0, 0), beyond ±1e+60, where lengths squared and areas "
                            "overflow: rescale the mesh"),
              std::string::npos)
        << r.output;
    EXPECT_EQ(r.output.find("nan"), std::string::npos) << r.output;
    EXPECT_FALSE(std::filesystem::exists(Path("out.ply"))) << command;
  }
}

}  // namespace
}  // namespace rangebayes
