// End-to-end quality guards on bundled benchmark meshes (tests/data/meshes, see SOURCES.md there): smoothing
// with the default rule and the true noise level must stay within issue 3's targets. Our measured values are
// in BENCHMARKS.md ("Bayesian smoothing"); the bounds here are the targets, not our numbers plus slack.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "bayes/noise_model.h"
#include "bayes/smooth.h"
#include "core/mesh_io.h"
#include "core/normal_error.h"

namespace rangebayes {
namespace {

struct QualityCase {
  std::string gt;
  std::string noisy;
  double k;
  double max_mae_deg;
};

class SmoothQuality : public ::testing::TestWithParam<QualityCase> {};

TEST_P(SmoothQuality, MeetsTheIssueTarget) {
  const QualityCase& c = GetParam();
  const Mesh gt = ReadMesh("tests/data/meshes/" + c.gt);
  const Mesh noisy = ReadMesh("tests/data/meshes/" + c.noisy);
  GenericNoiseOptions noise;
  noise.noise_edge_multiple = c.k;
  SmoothSummary summary;
  const Mesh result = Smooth(MakeGenericNoisyMesh(noisy, noise), SmoothOptions{}, &summary);
  const double mae = MeanAngularErrorDeg(result, gt);
  EXPECT_LE(mae, c.max_mae_deg) << summary.iterations << " iterations, " << SmoothTerminationName(summary.termination);
  EXPECT_GT(MeanAngularErrorDeg(noisy, gt), 5 * mae);  // sanity: the input is much worse
  // A few faces fold at sharp corners (measured: 0 on fandisk, 2 of 17550 on block, 5 of 10384 on trim-star).
  EXPECT_LE(summary.flipped_faces, gt.num_faces() / 1000);
}

// Targets from issue 3: fandisk 0.3 → 2.4°, block 0.4 → 4.0°, trim-star 0.3 (GCN copy) → 5.3°.
INSTANTIATE_TEST_SUITE_P(BundledMeshes, SmoothQuality,
                         ::testing::Values(QualityCase{"fandisk_gt.obj", "fandisk_noisy_gauss0.3.obj", 0.3, 2.4},
                                           QualityCase{"block_gt.obj", "block_noisy_gauss0.4.obj", 0.4, 4.0},
                                           QualityCase{"trim-star_gt.obj", "trim-star_noisy_gauss_n3.obj", 0.3,
                                                       5.3}));

}  // namespace
}  // namespace rangebayes
