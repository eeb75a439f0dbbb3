#include "bayes/decimation/decimate_partition.h"

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <random>

namespace rangebayes {
namespace {

// An abstract problem: faces on a path (or ring) graph, corners made up so that no two faces share a
// vertex (the local fan test then always defers to the BFS).
DecimationProblem PathProblem(const std::vector<std::array<double, 3>>& normals, bool ring) {
  DecimationProblem p;
  const int n = static_cast<int>(normals.size());
  p.dim = 3;
  for (int i = 0; i < n; ++i) {
    p.normals.insert(p.normals.end(), normals[i].begin(), normals[i].end());
    p.weight.push_back(1.0);
    int prev = i - 1, next = i + 1;
    if (ring) {
      prev = (i + n - 1) % n;
      next = (i + 1) % n;
    } else {
      if (next >= n) next = -1;
    }
    p.neighbours.push_back({prev, next, -1});
    p.corners.push_back({3 * i, 3 * i + 1, 3 * i + 2});
  }
  return p;
}

int CountPatches(const std::vector<int>& g) {
  int n = 0;
  for (int k : g) n = std::max(n, k + 1);
  return n;
}

// Worked example (energies by hand): faces 0,1,3,4 point along z, face 2 along x; λ = 1.5.
//   one patch: λ + 1.6 = 3.1; {0,1},{2},{3,4}: 4.5; {0,1,2},{3,4}: 2λ + 4/3 ≈ 4.33.
// Greedy fusion reaches the single patch; splitting face 2 off would then gain 1.6 − λ = 0.1 but cuts the
// path in two, so it must be refused.
TEST(DecimatePartition, BridgeFaceIsNotSplitOffWhenThatDisconnects) {
  const std::vector<std::array<double, 3>> normals = {{0, 0, 1}, {0, 0, 1}, {1, 0, 0}, {0, 0, 1}, {0, 0, 1}};
  const DecimationProblem p = PathProblem(normals, /*ring=*/false);
  PartitionStats stats;
  const std::vector<int> g = HillClimbPartition(p, 1.5, {}, &stats);
  EXPECT_TRUE(PartitionIsContiguous(p, g));
  EXPECT_EQ(CountPatches(g), 1);
  EXPECT_GE(stats.rejected_disconnecting, 1);
  EXPECT_EQ(stats.splits, 0);
  EXPECT_NEAR(stats.energy, 1.5 + 1.6, 1e-12);
  EXPECT_TRUE(stats.converged);
}

// Same normals on a ring: removing face 2 keeps the rest connected, so the split is taken
// (2λ = 3.0 < 3.1).
TEST(DecimatePartition, SplitTakenWhenPatchStaysConnected) {
  const std::vector<std::array<double, 3>> normals = {{0, 0, 1}, {0, 0, 1}, {1, 0, 0}, {0, 0, 1}, {0, 0, 1}};
  const DecimationProblem p = PathProblem(normals, /*ring=*/true);
  PartitionStats stats;
  const std::vector<int> g = HillClimbPartition(p, 1.5, {}, &stats);
  EXPECT_TRUE(PartitionIsContiguous(p, g));
  EXPECT_EQ(CountPatches(g), 2);
  EXPECT_NEAR(stats.energy, 3.0, 1e-12);
  EXPECT_NE(g[2], g[0]);
}

// The incremental energy bookkeeping agrees with a from-scratch evaluation, every patch is contiguous, and
// the result is at least as good as the start (one patch per face) on random normal fields.
TEST(DecimatePartition, RandomGridsStayContiguousAndEnergyIsConsistent) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 1.0);
  const int n = 12;  // n×n quads, two triangles each, on a grid graph with shared corner vertices
  for (int trial = 0; trial < 5; ++trial) {
    DecimationProblem p;
    p.dim = 3;
    auto face = [&](int x, int y, int t) { return 2 * (y * n + x) + t; };
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) {
        const int a = y * (n + 1) + x, b = a + 1, c = a + n + 1, d = c + 1;
        for (int t = 0; t < 2; ++t) {
          // Two smooth regions plus noise, to make patches with ragged boundaries.
          Eigen::Vector3d u(x < n / 2 ? 0.3 : -0.3, 0.05 * y, 1.0);
          u += 0.25 * Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
          u.normalize();
          p.normals.insert(p.normals.end(), {u.x(), u.y(), u.z()});
          p.weight.push_back(0.5 + (trial % 2) * 0.5 * std::abs(noise(rng)));
          if (t == 0) {
            // triangle (a, b, d): edges ab (below), bd (right), da (diagonal)
            p.corners.push_back({a, b, d});
            p.neighbours.push_back({y > 0 ? face(x, y - 1, 1) : -1, x + 1 < n ? face(x + 1, y, 1) : -1, face(x, y, 1)});
          } else {
            // triangle (d, c, a): edges dc (above), ca (left), ad (diagonal)
            p.corners.push_back({d, c, a});
            p.neighbours.push_back({y + 1 < n ? face(x, y + 1, 0) : -1, x > 0 ? face(x - 1, y, 0) : -1, face(x, y, 0)});
          }
        }
      }
    }
    const double lambda = 0.5 + trial;
    PartitionStats stats;
    const std::vector<int> g = HillClimbPartition(p, lambda, {}, &stats);
    EXPECT_TRUE(PartitionIsContiguous(p, g)) << "trial " << trial;
    EXPECT_NEAR(PartitionEnergy(p, g, lambda), stats.energy, 1e-9 * stats.energy);
    EXPECT_LT(stats.energy, lambda * p.num_faces());
    EXPECT_TRUE(stats.converged);
    EXPECT_GT(stats.fuses, 0);
    // A warm start at a larger λ from this partition (as the λ search does) only coarsens it: contiguous,
    // consistent, and never above the start's energy at the larger λ.
    const double coarser = 2.0 * lambda;
    PartitionOptions warm;
    warm.initial = &g;
    PartitionStats warm_stats;
    const std::vector<int> h = HillClimbPartition(p, coarser, warm, &warm_stats);
    EXPECT_TRUE(PartitionIsContiguous(p, h)) << "trial " << trial;
    EXPECT_NEAR(PartitionEnergy(p, h, coarser), warm_stats.energy, 1e-9 * warm_stats.energy);
    EXPECT_LE(warm_stats.energy, PartitionEnergy(p, g, coarser) + 1e-12);
    EXPECT_LE(CountPatches(h), CountPatches(g));
    EXPECT_TRUE(warm_stats.converged);
  }
}

TEST(DecimatePartition, RejectsBadLambda) {
  const DecimationProblem p = PathProblem({{0, 0, 1}, {0, 0, 1}}, false);
  EXPECT_THROW(HillClimbPartition(p, 0.0), std::exception);
  EXPECT_THROW(HillClimbPartition(p, -1.0), std::exception);
  const std::vector<int> short_start = {0};
  PartitionOptions options;
  options.initial = &short_start;
  EXPECT_THROW(HillClimbPartition(p, 1.0, options), std::exception);
}

}  // namespace
}  // namespace rangebayes
