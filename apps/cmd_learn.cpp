// `rangebayes synth-meshes` (synthetic right-angled training data) and `rangebayes learn-prior` (a spline
// potential learned from noisy / ground-truth pairs, paper §5).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "apps/command.h"
#include "apps/flags.h"
#include "apps/progress.h"
#include "bayes/learn_prior_io.h"
#include "bayes/learning/learn_prior.h"
#include "bayes/learning/synth_meshes.h"
#include "bayes/learning/training_set.h"
#include "bayes/noise_model.h"
#include "core/error.h"
#include "core/files.h"
#include "core/mesh_io.h"
#include "figures/potential_plot.h"
#include "pipeline/png.h"

namespace rangebayes::apps {
namespace {

struct SynthArgs {
  std::string out;
  std::uint64_t seed = 1;
  double k = 0.3;
  double k_max = 0;
  bool scanner = false;
  int train = 8;
  int test = 4;
  int copies = 1;
  int min_cells = 6;
  int max_cells = 14;
  bool quiet = false;
};

void RunSynth(const SynthArgs& args) {
  SynthMeshSetOptions options;
  options.seed = args.seed;
  options.noise.k = args.k;
  options.noise_k_max = args.k_max;
  options.noise.kind = args.scanner ? SynthNoise::kScanner : SynthNoise::kNormal;
  options.num_train = args.train;
  options.num_test = args.test;
  options.copies = args.copies;
  options.object.min_cells = args.min_cells;
  options.object.max_cells = args.max_cells;
  options.Check();
  const SynthMeshSet set = MakeSynthMeshSet(options);
  namespace fs = std::filesystem;
  ProgressPrinter progress(args.quiet);
  const size_t total = set.train.size() + set.test.size();
  size_t done = 0;
  auto write = [&](const std::vector<SynthPair>& pairs, const std::string& folder) {
    CreateFolder((fs::path(args.out) / folder).string());
    PairsList list;
    list.noise_kind = SynthNoiseName(options.noise.kind);
    list.noise_k = options.noise.k;
    if (options.noise_k_max > options.noise.k) list.noise_k_max = options.noise_k_max;
    for (const SynthPair& pair : pairs) {
      const std::string noisy = folder + "/" + pair.name + "_noisy.ply";
      const std::string truth = folder + "/" + pair.name + "_gt.ply";
      if (pair.noisy.has_covariance()) {
        WriteNoisyMesh(pair.noisy, (fs::path(args.out) / noisy).string());
      } else {
        WriteMesh(pair.noisy.mesh, (fs::path(args.out) / noisy).string());
      }
      WriteMesh(pair.clean, (fs::path(args.out) / truth).string());
      list.noisy.push_back(noisy);
      list.truth.push_back(truth);
      progress.Update(static_cast<double>(++done) / total, "writing meshes");
    }
    if (!pairs.empty()) WritePairsList(list, (fs::path(args.out) / (folder + "_pairs.txt")).string());
  };
  write(set.train, "train");
  write(set.test, "test");
  progress.Finish();
  int vertices = 0;
  for (const auto& p : set.train) vertices += p.clean.num_vertices();
  const std::string levels = options.noise_k_max > options.noise.k
                                 ? StrCat(options.noise.k, "..", options.noise_k_max, " (a mixture)")
                                 : StrCat(options.noise.k);
  std::printf("wrote %zu training pairs (%d vertices) and %zu held-out pairs to %s (noise %s, k = %s, seed %llu)\n",
              set.train.size(), vertices, set.test.size(), args.out.c_str(), SynthNoiseName(options.noise.kind).c_str(),
              levels.c_str(), static_cast<unsigned long long>(args.seed));
  std::printf("train with: rangebayes learn-prior --pairs %s/train_pairs.txt --out prior.yaml\n", args.out.c_str());
}

struct LearnArgs {
  std::string pairs;
  std::string out;
  std::string plot;
  // Defaults from LearnPriorOptions{} (the library's default training, BENCHMARKS.md "Learned priors").
  int knots = LearnPriorOptions{}.spline.num_knots;
  std::string method = LearnMethodName(LearnPriorOptions{}.method);
  double w = LearnPriorOptions{}.regularizer_weight;
  double noise_k = std::numeric_limits<double>::quiet_NaN();
  double prior_weight = LearnPriorOptions{}.prior_weight;
  int iterations = LearnPriorOptions{}.max_iterations;
  double time_limit_s = LearnPriorOptions{}.time_limit_s;
  double step = LearnPriorOptions{}.interleaved_step;
  int bump_sweeps = LearnPriorOptions{}.bump_search_sweeps;
  double bump_step = LearnPriorOptions{}.bump_search_step;
  double bump_width = LearnPriorOptions{}.bump_search_width_d;
  std::vector<double> bump_centres = LearnPriorOptions{}.bump_search_centres_d;
  int threads = LearnPriorOptions{}.num_threads;
  bool quiet = false;
};

std::string DefaultPlotPath(const std::string& out) {
  const size_t dot = out.find_last_of('.');
  const size_t slash = out.find_last_of('/');
  const std::string stem =
      (dot != std::string::npos && (slash == std::string::npos || dot > slash)) ? out.substr(0, dot) : out;
  return stem + ".png";
}

void RunLearn(const LearnArgs& args) {
  ProgressPrinter progress(args.quiet);
  LearnPriorOptions options;
  options.method = ParseLearnMethod(args.method);
  options.spline.num_knots = args.knots;
  options.regularizer_weight = args.w;
  options.prior_weight = args.prior_weight;
  options.max_iterations = args.iterations;
  options.time_limit_s = args.time_limit_s;
  options.num_threads = args.threads;
  options.interleaved_step = args.step;
  options.bump_search_sweeps = args.bump_sweeps;
  options.bump_search_step = args.bump_step;
  options.bump_search_min_step = std::min(options.bump_search_min_step, args.bump_step);
  options.bump_search_width_d = args.bump_width;
  options.bump_search_centres_d = args.bump_centres;
  options.progress = [&progress](double fraction, std::string_view stage) {
    progress.Update(0.02 + 0.98 * fraction, stage);
  };
  options.Check();
  const std::string plot = args.plot.empty() ? DefaultPlotPath(args.out) : args.plot;
  RequireDistinctOutputs({{"--out", args.out}, {args.plot.empty() ? "the plot beside it" : "--plot", plot}});
  CheckFileToWrite(args.out);
  CheckFileToWrite(plot);

  TrainingSetOptions set_options;
  set_options.noise_k = args.noise_k;
  set_options.progress = [&progress](double fraction, std::string_view stage) {
    progress.Update(0.02 * fraction, stage);
  };
  const TrainingSet set = ReadTrainingSet(args.pairs, set_options);
  LearnPriorSummary summary;
  const Eigen::VectorXd theta = LearnPrior(set.pairs, options, {}, &summary);
  progress.Finish();
  WriteLearnedPrior(MakeLearnedPrior(set, options, theta, summary), args.out);
  WritePng(PlotPotential(SplinePotential(options.spline, theta)), plot);
  std::printf("%s\n", summary.BriefReport().c_str());
  const SecondWell well = FindSecondWell(SplinePotential(options.spline, theta));
  if (well.found) {
    std::printf(
        "second well: phi has a local minimum at d = %.3f (depth %.4f below the barrier at d = %.3f and "
        "phi(1.8))\n",
        well.well_d, well.depth, well.barrier_d);
  } else {
    std::printf("second well: none (phi has no strict local minimum in d = [1.2, 1.6])\n");
  }
  std::printf("wrote %s and %s\n", args.out.c_str(), plot.c_str());
}

void AddCommands(CLI::App& app) {
  {
    auto args = std::make_shared<SynthArgs>();
    auto* sub = app.add_subcommand("synth-meshes",
                                   "Write synthetic right-angled training meshes (boxes, stairs, L-shapes, slotted "
                                   "blocks) and noisy copies, with train/test pairs lists");
    sub->add_option("--out,-o", args->out, "Output folder (train/, test/, train_pairs.txt, test_pairs.txt)")
        ->required();
    sub->add_option("--seed", args->seed, "Random seed: the same seed writes the same meshes");
    sub->add_option("--noise", args->k, "Noise sigma in units of the mean edge length l_e (k), (0, 5]")
        ->check(PositiveUpTo(5.0));
    sub->add_option("--noise-max", args->k_max,
                    "A mixture of noise levels: copies spread evenly over k in [--noise, --noise-max] (each noisy "
                    "PLY then holds its own covariance); 0: one level, [0, 5]")
        ->check(RealRange(0.0, 5.0));
    sub->add_flag("--scanner-noise", args->scanner,
                  "Ray-aligned scanner noise (sigma along the ray from a virtual camera, sigma/10 across; the PLY "
                  "holds the covariance) instead of Gaussian noise along the vertex normals");
    sub->add_option("--train", args->train, "Number of training objects, [0, 10000]")->check(CLI::Range(0, 10000));
    sub->add_option("--test", args->test, "Number of held-out objects (never among the training ones), [0, 10000]")
        ->check(CLI::Range(0, 10000));
    sub->add_option("--copies", args->copies, "Noisy copies per object, [1, 100]")->check(CLI::Range(1, 100));
    sub->add_option("--min-cells", args->min_cells, "Smallest object extent in edge lengths, [4, 200]")
        ->check(CLI::Range(4, 200));
    sub->add_option("--max-cells", args->max_cells, "Largest object extent in edge lengths, [min-cells, 200]")
        ->check(CLI::Range(4, 200));
    AddQuietFlag(sub, &args->quiet);
    sub->callback([args] {
      if (args->max_cells < args->min_cells) UsageError("--max-cells must not be below --min-cells");
      if (args->k_max > 0 && args->k_max <= args->k) UsageError("--noise-max must be above --noise");
      RunSynth(*args);
    });
  }
  {
    auto args = std::make_shared<LearnArgs>();
    auto* sub = app.add_subcommand("learn-prior",
                                   "Learn a spline potential from noisy / ground-truth mesh pairs (paper section 5) "
                                   "and write prior.yaml and a plot");
    sub->add_option("--pairs", args->pairs,
                    "Pairs list: one 'NOISY GROUND_TRUTH' per line, paths relative to the list (synth-meshes "
                    "writes one)")
        ->required();
    sub->add_option("--out,-o", args->out, "Output prior (YAML), for 'rangebayes smooth --prior'")->required();
    sub->add_option("--plot", args->plot,
                    "PNG plot of the learned potential beside the square root (default: --out "
                    "with .png)");
    sub->add_option("--knots", args->knots, "Number of spline knots N over d in [0, 2], [3, 256]")
        ->check(CLI::Range(3, 256));
    sub->add_option("--method", args->method,
                    "none (default): no gradient method, theta learned by the bump search (--bump-sweeps) from the "
                    "square root (learns the second well near sqrt(2), BENCHMARKS.md); interleaved: the paper's "
                    "finite differences beside the CG iterations (its reference; add --bump-sweeps 0 for it alone)")
        ->check(CLI::IsMember({"none", "interleaved"}));
    sub->add_option("--w", args->w, "Weight w of the curvature regulariser on the knots (paper eq. 19), [0, 1e6]")
        ->check(RealRange(0.0, 1e6));
    sub->add_option("--noise", args->noise_k,
                    "Noise sigma / l_e of the noisy meshes without covariances (default: the pairs list's "
                    "'# noise:' line, else estimated per mesh), (0, 5]")
        ->check(PositiveUpTo(5.0))
        ->default_str("");
    sub->add_option("--prior-weight", args->prior_weight, "Prior weight beta of the smoother, (0, 1e6]")
        ->check(RealRange(1e-12, 1e6));
    sub->add_option("--iterations", args->iterations, "Interleaved: outer iterations (0: 400), [0, 1e6]")
        ->check(CLI::Range(0, 1000000));
    sub->add_option("--time-limit", args->time_limit_s, "Stop learning after this many seconds (0: no limit)")
        ->check(RealRange(0.0, 1e9));
    sub->add_option("--step", args->step, "Interleaved: fixed step alpha (paper eq. 22), (0, 1e6]")
        ->check(RealRange(1e-12, 1e6));
    sub->add_option("--bump-sweeps", args->bump_sweeps,
                    "After the --method: sweeps of implicit filtering on the cold-smoothing loss along smooth "
                    "Gaussian bumps of the knot values (sigma --bump-width) centred at --bump-centres "
                    "(BENCHMARKS.md 'Learned priors'), [0, 1000]; 0: off")
        ->check(CLI::Range(0, 1000));
    sub->add_option("--bump-step", args->bump_step,
                    "Bump search: initial stencil size in knot-value units (halved after a stencil failure; the "
                    "search ends below 0.005), (0, 1]")
        ->check(RealRange(1e-9, 1.0));
    sub->add_option("--bump-width", args->bump_width, "Bump search: sigma of the bumps in d, (0, 1]")
        ->check(RealRange(1e-9, 1.0));
    sub->add_option("--bump-centres", args->bump_centres,
                    "Bump search: the bump centres in d, comma-separated, each in (0, 2) (default: the knots 7-14 "
                    "of 16)")
        ->delimiter(',')
        ->check(RealRange(1e-9, 2.0 - 1e-9));
    AddThreadsOption(sub, &args->threads);
    AddQuietFlag(sub, &args->quiet);
    sub->callback([args] { RunLearn(*args); });
  }
}

RB_REGISTER_COMMANDS(70, AddCommands);

}  // namespace
}  // namespace rangebayes::apps
