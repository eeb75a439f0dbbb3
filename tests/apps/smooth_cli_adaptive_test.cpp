// `rangebayes smooth` with its adaptive ε (on by default for the sqrt prior, AdaptiveEpsilonAuto in
// bayes/adaptive_epsilon.h) as a user runs it, on bundled meshes (tests/data/meshes, see SOURCES.md there): the
// gate must keep the global ε² on a CAD shape and apply per-face ε² on a curved scan, and the command's contract
// (output written, vertex order and faces kept) and quality must hold.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "core/mesh.h"
#include "core/mesh_io.h"
#include "core/normal_error.h"
#include "core/topology.h"
#include "tests/apps/run_binary.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

namespace fs = std::filesystem;

// Largest distance of a result vertex from the same-index input vertex, in mean edge lengths.
double MaxMoveInEdges(const Mesh& result, const Mesh& input) {
  return (result.V - input.V).rowwise().norm().maxCoeff() / MeanEdgeLength(input);
}

// A CAD shape: the gate reads it as piecewise flat and keeps the global ε², so the result is the plain solver's.
TEST(SmoothCliAdaptive, KeepsTheGlobalEpsilonOnACadShape) {
  const fs::path dir = FreshTempDir("smooth_adaptive_cad");  // removed at exit, also after a failed ASSERT
  const std::string noisy_path = "tests/data/meshes/fandisk_noisy_gauss0.3.obj";
  const std::string adaptive_path = (dir / "adaptive.ply").string();
  const std::string global_path = (dir / "global.ply").string();

  const RunResult adaptive = RunRangebayes("smooth " + noisy_path + " '" + adaptive_path + "' --noise 0.3 --quiet");
  ASSERT_EQ(adaptive.exit_code, 0) << adaptive.output;
  EXPECT_NE(adaptive.output.find("adaptive:   global eps2 kept (piecewise flat"), std::string::npos) << adaptive.output;
  const RunResult global =
      RunRangebayes("smooth " + noisy_path + " '" + global_path + "' --noise 0.3 --quiet --no-adaptive-eps");
  ASSERT_EQ(global.exit_code, 0) << global.output;
  EXPECT_EQ(global.output.find("adaptive:"), std::string::npos) << global.output;

  const Mesh noisy = ReadMesh(RB_SOURCE_DIR "/" + noisy_path);
  const Mesh gt = ReadMesh(RB_SOURCE_DIR "/tests/data/meshes/fandisk_gt.obj");
  const Mesh result = ReadMesh(adaptive_path);
  ASSERT_EQ(result.num_vertices(), noisy.num_vertices());
  EXPECT_TRUE(result.F == noisy.F);
  EXPECT_LT(MaxMoveInEdges(result, noisy), 2.0);     // σ = 0.3 mean edges: vertices stay near their own input
  EXPECT_TRUE(result.V == ReadMesh(global_path).V);  // same solve, same bytes (the solver is deterministic)
  // The issue target for fandisk 0.3 (2.4°); measured with this command: 2.09°.
  EXPECT_LE(MeanAngularErrorDeg(result, gt), 2.4);
}

// A curved scan (the bundled angel, noise level estimated): per-face ε² are applied and change the result.
TEST(SmoothCliAdaptive, AppliesPerFaceEpsilonOnACurvedScan) {
  const fs::path dir = FreshTempDir("smooth_adaptive_scan");
  const std::string noisy_path = "tests/data/meshes/real_angel_scan.obj";
  const std::string adaptive_path = (dir / "adaptive.ply").string();
  const std::string global_path = (dir / "global.ply").string();

  const RunResult adaptive =
      RunRangebayes("smooth " + noisy_path + " '" + adaptive_path + "' --tolerance fast --quiet --adaptive-eps");
  ASSERT_EQ(adaptive.exit_code, 0) << adaptive.output;
  // Measured: gate median ε² 0.032 (≥ 3e-3), per-face median ε² 0.06.
  EXPECT_NE(adaptive.output.find("adaptive:   per-face eps2"), std::string::npos) << adaptive.output;
  const RunResult global =
      RunRangebayes("smooth " + noisy_path + " '" + global_path + "' --tolerance fast --quiet --no-adaptive-eps");
  ASSERT_EQ(global.exit_code, 0) << global.output;

  const Mesh noisy = ReadMesh(RB_SOURCE_DIR "/" + noisy_path);
  const Mesh result = ReadMesh(adaptive_path);
  const Mesh result_global = ReadMesh(global_path);
  ASSERT_EQ(result.num_vertices(), noisy.num_vertices());
  EXPECT_TRUE(result.F == noisy.F);
  EXPECT_LT(MaxMoveInEdges(result, noisy), 2.0);
  // A real effect: the larger ε² on curved faces change the face normals against the global ε² (measured: mean
  // angle 2.04° between the two results' face normals, Hausdorff 0.13 mean edges).
  EXPECT_GT(MeanAngularErrorDeg(result, result_global), 0.5);
}

}  // namespace
}  // namespace rangebayes
