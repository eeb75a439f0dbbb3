// End to end: synth-meshes writes a tiny training set, learn-prior learns from it and writes prior.yaml + PNG.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>

#include "bayes/learn_prior_io.h"
#include "bayes/learning/training_set.h"
#include "core/mesh_io.h"
#include "core/normal_error.h"
#include "tests/apps/run_binary.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

TEST(LearnCli, SynthThenLearn) {
  const std::filesystem::path dir = std::filesystem::path(TempPath("learn_cli_test"));
  std::filesystem::remove_all(dir);
  const RunResult synth = RunRangebayes("synth-meshes --out '" + dir.string() +
                                        "' --train 2 --test 1 --min-cells 4 --max-cells 5 --noise 0.3 --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.output;
  ASSERT_TRUE(std::filesystem::exists(dir / "train_pairs.txt"));
  ASSERT_TRUE(std::filesystem::exists(dir / "test_pairs.txt"));
  const PairsList list = ReadPairsList((dir / "train_pairs.txt").string());
  EXPECT_EQ(list.noisy.size(), 2u);
  EXPECT_EQ(list.noise_kind, "normal");

  const std::string prior = (dir / "prior.yaml").string();
  const RunResult learn =
      RunRangebayes("learn-prior --pairs '" + (dir / "train_pairs.txt").string() + "' --out '" + prior +
                    "' --knots 8 --method interleaved --iterations 3 --bump-sweeps 1 --threads 1 --quiet");
  ASSERT_EQ(learn.exit_code, 0) << learn.output;
  EXPECT_TRUE(std::filesystem::exists(dir / "prior.png"));
  const LearnedPrior read = ReadLearnedPrior(prior);
  EXPECT_EQ(read.spline.num_knots, 8);
  EXPECT_EQ(read.noise_kind, "normal");
  EXPECT_DOUBLE_EQ(read.noise_k, 0.3);
  EXPECT_EQ(read.training_pairs, 2);
  EXPECT_FALSE(read.date.empty());
  EXPECT_NE(read.method.find("interleaved + bump search (filtering"), std::string::npos) << read.method;

  // The learned prior plugs into the smoother: the same mesh smoothed with the square-root prior comes out
  // different (else --prior was read and ignored), and the learned one still denoises. Measured mean angular
  // error against the ground truth: noisy 29.9°, learned prior 8.2°, square root 9.8°; the bound asks for half
  // the noisy mesh's.
  const RunResult smooth = RunRangebayes("smooth '" + list.noisy[0] + "' '" + (dir / "smoothed.ply").string() +
                                         "' --noise 0.3 --prior '" + prior + "' --threads 1 --quiet");
  ASSERT_EQ(smooth.exit_code, 0) << smooth.output;
  EXPECT_NE(smooth.output.find("prior.yaml"), std::string::npos) << smooth.output;
  const RunResult square_root = RunRangebayes(
      "smooth '" + list.noisy[0] + "' '" + (dir / "smoothed_sqrt.ply").string() + "' --noise 0.3 --threads 1 --quiet");
  ASSERT_EQ(square_root.exit_code, 0) << square_root.output;
  const Mesh noisy = ReadMesh(list.noisy[0]), truth = ReadMesh(list.truth[0]);
  const Mesh learned = ReadMesh((dir / "smoothed.ply").string());
  const Mesh sqrt_prior = ReadMesh((dir / "smoothed_sqrt.ply").string());
  ASSERT_EQ(learned.num_vertices(), sqrt_prior.num_vertices());
  EXPECT_GT((learned.V - sqrt_prior.V).cwiseAbs().maxCoeff(), 1e-6);
  const double mae_noisy = MeanAngularErrorDeg(noisy, truth), mae_learned = MeanAngularErrorDeg(learned, truth);
  std::printf("mean angular error: noisy %.2f°, learned prior %.2f°, square root %.2f°\n", mae_noisy, mae_learned,
              MeanAngularErrorDeg(sqrt_prior, truth));
  EXPECT_LT(mae_learned, 0.5 * mae_noisy);
  // A prior that records no β (prior_weight 0, as a hand-edited file may say): the default β, and the summary
  // says so (it printed "beta 2.4" as if the prior's own).
  {
    std::ifstream in(prior);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const size_t at = text.find("prior_weight:");
    ASSERT_NE(at, std::string::npos) << text;
    text.replace(at, text.find('\n', at) - at, "prior_weight: 0");
    std::ofstream((dir / "no_beta.yaml").string()) << text;
    const RunResult no_beta = RunRangebayes("smooth '" + list.noisy[0] + "' '" + (dir / "no_beta.ply").string() +
                                            "' --noise 0.3 --prior '" + (dir / "no_beta.yaml").string() + "' -q");
    ASSERT_EQ(no_beta.exit_code, 0) << no_beta.output;
    EXPECT_NE(
        no_beta.output.find("beta 2.4 (the default: " + (dir / "no_beta.yaml").string() + " records no prior_weight)"),
        std::string::npos)
        << no_beta.output;
  }
  const RunResult not_a_prior =
      RunRangebayes("smooth '" + list.noisy[0] + "' x.ply --prior '" + (dir / "train_pairs.txt").string() + "'");
  EXPECT_EQ(not_a_prior.exit_code, 2) << not_a_prior.output;

  // A truth with an infinite vertex: one error naming it (every loss was NaN, and the prior was written with
  // training_mse_le2 .nan, exit 0).
  {
    Mesh broken = ReadMesh(list.truth[0]);
    broken.V(4, 0) = std::numeric_limits<double>::infinity();
    WriteMesh(broken, (dir / "truth_inf.obj").string());
    std::ofstream((dir / "inf_pairs.txt").string()) << list.noisy[0] << " " << (dir / "truth_inf.obj").string() << "\n";
    const RunResult inf = RunRangebayes("learn-prior --pairs '" + (dir / "inf_pairs.txt").string() + "' --out '" +
                                        (dir / "inf.yaml").string() + "' --time-limit 2 -q");
    EXPECT_EQ(inf.exit_code, 1) << inf.output;
    EXPECT_NE(inf.output.find("pair 1: " + (dir / "truth_inf.obj").string() + ": 1 of "), std::string::npos)
        << inf.output;
    EXPECT_FALSE(std::filesystem::exists(dir / "inf.yaml"));
  }
  // The plot named as the prior (or the prior named .png, where the plot goes beside it): the plot replaced the
  // prior, exit 0.
  for (const std::string outputs : {"--out same.yaml --plot same.yaml", "--out same.png"}) {
    const RunResult same = RunRangebayes("learn-prior --pairs '" + (dir / "train_pairs.txt").string() + "' " + outputs +
                                         " --time-limit 2 -q");
    EXPECT_EQ(same.exit_code, 2) << same.output;
    EXPECT_NE(same.output.find("name the same file"), std::string::npos) << same.output;
  }
  // Noise-free pairs: refused where they would be made (synth-meshes --noise 0 wrote a set that learn-prior then
  // refused with "noise: noise_edge_multiple 0 is outside (0, 10]"), and a list that says k = 0 names itself.
  const RunResult noise_free = RunRangebayes("synth-meshes --out '" + (dir / "k0").string() + "' --noise 0 -q");
  EXPECT_EQ(noise_free.exit_code, 2) << noise_free.output;
  EXPECT_NE(noise_free.output.find("--noise: must be in (0, 5], got 0"), std::string::npos) << noise_free.output;
  {
    std::ifstream in((dir / "train_pairs.txt").string());
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const size_t k = text.find("k=");
    ASSERT_NE(k, std::string::npos) << text;
    text.replace(k, text.find('\n', k) - k, "k=0");
    std::ofstream((dir / "k0_pairs.txt").string()) << text;
    const RunResult k0 = RunRangebayes("learn-prior --pairs '" + (dir / "k0_pairs.txt").string() + "' --out '" +
                                       (dir / "k0.yaml").string() + "' -q");
    EXPECT_EQ(k0.exit_code, 1) << k0.output;
    EXPECT_NE(k0.output.find("k0_pairs.txt: its '# noise:' line gives k = 0, outside (0, 5]"), std::string::npos)
        << k0.output;
  }
  // A time limit that ends the bump search is said in the summary (it read "0 moves ... (searches only)").
  const RunResult cut = RunRangebayes("learn-prior --pairs '" + (dir / "train_pairs.txt").string() + "' --out '" +
                                      (dir / "cut.yaml").string() + "' --time-limit 0.001 -q");
  ASSERT_EQ(cut.exit_code, 0) << cut.output;
  EXPECT_NE(cut.output.find("the time limit ended the bump search"), std::string::npos) << cut.output;
  const RunResult bad = RunRangebayes("learn-prior --pairs '" + (dir / "missing.txt").string() + "' --out x.yaml");
  EXPECT_EQ(bad.exit_code, 1) << bad.output;
  const RunResult usage = RunRangebayes("learn-prior --pairs a --out b --method nope");
  EXPECT_EQ(usage.exit_code, 2) << usage.output;
  std::filesystem::remove_all(dir);
}

// The command's defaults are LearnPriorOptions{}: the same training set read by the library and the same two
// overrides on both sides give the same θ, bit for bit, and the same method record.
TEST(LearnCli, DefaultTrainingEqualsTheLibrary) {
  const std::filesystem::path dir = std::filesystem::path(TempPath("learn_cli_default_test"));
  std::filesystem::remove_all(dir);
  const RunResult synth = RunRangebayes("synth-meshes --out '" + dir.string() +
                                        "' --train 2 --test 0 --min-cells 4 --max-cells 5 --noise 0.2 "
                                        "--noise-max 0.5 --quiet");
  ASSERT_EQ(synth.exit_code, 0) << synth.output;
  const std::string list = (dir / "train_pairs.txt").string();
  const std::string prior = (dir / "prior.yaml").string();
  const RunResult learn =
      RunRangebayes("learn-prior --pairs '" + list + "' --out '" + prior + "' --bump-sweeps 2 --threads 1 --quiet");
  ASSERT_EQ(learn.exit_code, 0) << learn.output;
  const LearnedPrior cli = ReadLearnedPrior(prior);

  LearnPriorOptions options;
  options.bump_search_sweeps = 2;
  options.num_threads = 1;
  const TrainingSet set = ReadTrainingSet(list);
  LearnPriorSummary summary;
  const Eigen::VectorXd theta = LearnPrior(set.pairs, options, {}, &summary);
  EXPECT_EQ(cli.theta, theta);
  EXPECT_EQ(cli.method, summary.method);
  EXPECT_EQ(cli.prior_weight, options.prior_weight);
  EXPECT_EQ(cli.noise_kind, set.noise_kind);
  EXPECT_EQ(cli.training_pairs, 2);
  EXPECT_NE(learn.output.find(summary.method), std::string::npos) << learn.output;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace rangebayes
