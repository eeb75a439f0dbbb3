#include "bayes/warm_start.h"

#include <gtest/gtest.h>

#include "bayes/noise_model.h"
#include "bayes/smooth.h"
#include "core/error.h"
#include "tests/bayes/test_meshes.h"

namespace rangebayes {
namespace {

// The same frame again: every vertex agrees and starts exactly at the remembered result.
TEST(WarmStart, SameFrameStartsAtTheRememberedResult) {
  const NoisyMesh frame = testing::RangeGrid(30, 24, 0.03, 0.001, 7);
  WarmStart warm;
  Vertices start;
  EXPECT_FALSE(warm.Initial(frame, &start));  // nothing remembered yet
  const Mesh smoothed = Smooth(frame);
  warm.Remember(frame, smoothed);
  WarmStartStats stats;
  ASSERT_TRUE(warm.Initial(frame, &start, &stats));
  EXPECT_EQ(stats.agreed, frame.mesh.num_vertices());
  EXPECT_EQ(stats.vertices, frame.mesh.num_vertices());
  EXPECT_LT((start - smoothed.V).cwiseAbs().maxCoeff(), 1e-12);
}

// A second noisy frame of the same surface: measurements agree within the noise, and a warm-started solve (no ε
// continuation, no hierarchy: Smooth skips them with a start) ends at the energy of a cold solve of that frame.
TEST(WarmStart, NextFrameOfAStaticSceneReachesTheColdMinimum) {
  const NoisyMesh first = testing::RangeGrid(40, 32, 0.03, 0.001, 3);
  const NoisyMesh second = testing::RangeGrid(40, 32, 0.03, 0.001, 4);  // same surface, new noise
  WarmStart warm;
  warm.Remember(first, Smooth(first));
  Vertices start;
  WarmStartStats stats;
  ASSERT_TRUE(warm.Initial(second, &start, &stats));
  // Two independent measurements differ by √2 σ per axis: a 3σ test under the summed covariance keeps most.
  EXPECT_GT(stats.agreed, 0.9 * stats.vertices);
  SmoothOptions options;
  SmoothSummary cold, warmed;
  Smooth(second, options, &cold);
  options.initial_positions = &start;
  Smooth(second, options, &warmed);
  EXPECT_EQ(warmed.levels, 1);
  EXPECT_NE(warmed.termination, SmoothTermination::kMaxIterations);
  EXPECT_LT(warmed.energy.back(), warmed.energy.front());
  // Within the default's measured distance from the optimum of each other (BENCHMARKS.md: 0.2% on real stereo).
  EXPECT_NEAR(warmed.energy.back(), cold.energy.back(), 5e-3 * cold.energy.back());
}

// A moved scene (every measurement 100 σ away), a mesh without pixels and a mismatched result.
TEST(WarmStart, NoStartWhereTheSceneChanged) {
  const NoisyMesh frame = testing::RangeGrid(20, 16, 0.03, 0.001, 5);
  WarmStart warm;
  warm.Remember(frame, Smooth(frame));
  NoisyMesh moved = frame;
  moved.mesh.V.col(2).array() += 3.0;  // 100 σ_ray along the optical axis
  Vertices start;
  WarmStartStats stats;
  EXPECT_FALSE(warm.Initial(moved, &start, &stats));
  EXPECT_EQ(stats.agreed, 0);
  NoisyMesh unorganized = frame;
  unorganized.pixel.resize(0, 2);
  EXPECT_FALSE(warm.Initial(unorganized, &start));
  EXPECT_EQ(start.rows(), 0);
  Mesh wrong;
  EXPECT_THROW(warm.Remember(frame, wrong), Error);
  EXPECT_THROW(WarmStart(WarmStartOptions{.max_sigmas = 0}), Error);
  EXPECT_THROW(WarmStart(WarmStartOptions{.min_fraction = 2}), Error);
}

}  // namespace
}  // namespace rangebayes
