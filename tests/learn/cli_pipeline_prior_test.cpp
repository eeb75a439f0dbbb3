// A prior learned for a scanner's noise plugs into the stereo pipeline: synth-meshes --scanner-noise,
// learn-prior, then `rangebayes replay RECORDING --prior prior.yaml` on the bundled recording.
#include <gtest/gtest.h>

#include <filesystem>

#include "bayes/learn_prior_io.h"
#include "core/mesh_io.h"
#include "tests/apps/run_binary.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

namespace fs = std::filesystem;

TEST(LearnCli, ScannerPriorPlugsIntoReplay) {
  const fs::path dir = fs::path(TempPath("learn_pipeline_prior_test"));
  fs::remove_all(dir);
  const RunResult synth = RunRangebayes("synth-meshes --out '" + dir.string() +
                                        "' --train 2 --test 0 --min-cells 4 --max-cells 5 --noise 0.4 "
                                        "--scanner-noise --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.output;
  const std::string prior = (dir / "prior.yaml").string();
  const RunResult learn =
      RunRangebayes("learn-prior --pairs '" + (dir / "train_pairs.txt").string() + "' --out '" + prior +
                    "' --knots 8 --method interleaved --iterations 3 --bump-sweeps 0 --threads 1 --quiet");
  ASSERT_EQ(learn.exit_code, 0) << learn.output;
  const LearnedPrior read = ReadLearnedPrior(prior);
  EXPECT_EQ(read.noise_kind, "scanner");
  ASSERT_GT(read.prior_weight, 0);

  // One frame, coarse triangulation, no decimation: the smoothing stage is what this checks.
  const std::string common =
      " recordings/synth_planes_320x240 --count 1 --downsample 4 --tolerance fast "
      "--no-decimate --no-previews --quiet --out ";
  const RunResult learned =
      RunRangebayes("replay" + common + "'" + (dir / "learned").string() + "' --prior '" + prior + "'");
  ASSERT_EQ(learned.exit_code, 0) << learned.output;
  const RunResult square_root = RunRangebayes("replay" + common + "'" + (dir / "sqrt").string() + "'");
  ASSERT_EQ(square_root.exit_code, 0) << square_root.output;
  const Mesh a = ReadMesh((dir / "learned" / "smoothed" / "000000.ply").string());
  const Mesh b = ReadMesh((dir / "sqrt" / "smoothed" / "000000.ply").string());
  ASSERT_EQ(a.F, b.F);
  ASSERT_GT(a.num_vertices(), 100);
  // The same raw mesh, smoothed under another potential: the learned θ differs from the square root's after
  // three steps, so the result must differ (else --prior was ignored) while staying finite.
  EXPECT_TRUE(a.V.allFinite());
  EXPECT_GT((a.V - b.V).cwiseAbs().maxCoeff(), 0.0);

  const RunResult missing = RunRangebayes("replay" + common + "'" + (dir / "bad").string() + "' --prior '" +
                                          (dir / "missing.yaml").string() + "'");
  EXPECT_EQ(missing.exit_code, 1) << missing.output;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rangebayes
