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
#include "apps/progress.h"
#include "bayes/learn_prior.h"
#include "bayes/learn_prior_io.h"
#include "bayes/noise_model.h"
#include "bayes/synth_meshes.h"
#include "core/error.h"
#include "core/image.h"
#include "core/mesh_io.h"
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
    std::error_code error;
    fs::create_directories(fs::path(args.out) / folder, error);
    RB_CHECK(!error, "cannot create '", (fs::path(args.out) / folder).string(), "': ", error.message());
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
  int knots = 16;
  // The default training (BENCHMARKS.md "Learned priors"): no gradient method, the bump search from the square
  // root (implicit filtering, 30 sweeps at most, stencil 0.2, bumps at the knots 7–14 of 16).
  std::string method = "none";
  double w = 1.0;
  double noise_k = std::numeric_limits<double>::quiet_NaN();
  double prior_weight = SmoothOptions{}.prior_weight;
  int iterations = 0;
  double time_limit_s = 0;
  double step = 0;
  int pattern_sweeps = 0;
  double pattern_step = LearnPriorOptions{}.pattern_search_step;
  int bump_sweeps = 30;
  double bump_step = LearnPriorOptions{}.bump_search_step;
  std::string bump_method = BumpSearchMethodName(LearnPriorOptions{}.bump_search_method);
  double bump_width = LearnPriorOptions{}.bump_search_width_d;
  std::vector<double> bump_centres = LearnPriorOptions{}.bump_search_centres_d;
  int threads = 0;
  bool quiet = false;
};

// Pixel line between two points (no anti-aliasing), thickness 2.
void Line(RgbImage* image, double x0, double y0, double x1, double y1, const std::uint8_t rgb[3]) {
  const int steps = static_cast<int>(std::max(std::abs(x1 - x0), std::abs(y1 - y0))) + 1;
  for (int i = 0; i <= steps; ++i) {
    const double t = static_cast<double>(i) / steps;
    const int x = static_cast<int>(std::lround(x0 + t * (x1 - x0)));
    const int y = static_cast<int>(std::lround(y0 + t * (y1 - y0)));
    for (int dx = 0; dx <= 1; ++dx) {
      for (int dy = 0; dy <= 1; ++dy) {
        if (x + dx < 0 || y + dy < 0 || x + dx >= image->width || y + dy >= image->height) continue;
        std::copy(rgb, rgb + 3, image->at(x + dx, y + dy));
      }
    }
  }
}

// φ_θ (blue, knots as dots) beside the square root (grey), and, below it, φ_θ − sqrt (blue) around zero
// (grey); dashed red line at d = √2 (orthogonal normals). No text: axes run d = 0..2 left to right.
RgbImage PlotPotential(const SplinePotential& learned) {
  const int width = 720, height = 560, margin = 30;
  RgbImage image(width, height, 255);
  const std::uint8_t grey[3] = {150, 150, 150}, blue[3] = {20, 70, 200}, red[3] = {210, 40, 40}, black[3] = {0, 0, 0},
                     light[3] = {225, 225, 225};
  const int top_height = 340, bottom_top = 380, bottom_height = height - margin - bottom_top;
  const double x_scale = (width - 2.0 * margin) / 2.0;
  double y_max = 0, residual_max = 1e-3;
  for (double d = 0; d <= 2.0; d += 0.005) {
    y_max = std::max({y_max, learned.Value(d), learned.Base(d)});
    residual_max = std::max(residual_max, std::abs(learned.Value(d) - learned.Base(d)));
  }
  auto px = [&](double d) { return margin + d * x_scale; };
  auto top_y = [&](double v) { return margin + top_height - v / y_max * (top_height - 10); };
  auto bottom_y = [&](double v) {
    return bottom_top + bottom_height / 2.0 - v / residual_max * (bottom_height / 2.0 - 5);
  };
  for (int i = 0; i <= 8; ++i) Line(&image, px(0.25 * i), margin, px(0.25 * i), height - margin, light);
  Line(&image, px(0), top_y(0), px(2), top_y(0), black);
  Line(&image, px(0), margin, px(0), top_y(0), black);
  Line(&image, px(0), bottom_y(0), px(2), bottom_y(0), grey);
  Line(&image, px(0), bottom_top, px(0), height - margin, black);
  for (double y = margin; y < height - margin; y += 12)
    Line(&image, px(std::sqrt(2.0)), y, px(std::sqrt(2.0)), y + 5, red);
  const double step = 0.005;
  for (double d = 0; d + step <= 2.0 + 1e-9; d += step) {
    Line(&image, px(d), top_y(learned.Base(d)), px(d + step), top_y(learned.Base(d + step)), grey);
  }
  for (double d = 0; d + step <= 2.0 + 1e-9; d += step) {
    Line(&image, px(d), top_y(learned.Value(d)), px(d + step), top_y(learned.Value(d + step)), blue);
    Line(&image, px(d), bottom_y(learned.Value(d) - learned.Base(d)), px(d + step),
         bottom_y(learned.Value(d + step) - learned.Base(d + step)), blue);
  }
  for (int j = 0; j < learned.num_knots(); ++j) {
    const double x = px(learned.KnotPosition(j)), y = top_y(learned.theta()[j]);
    for (int a = -3; a <= 3; ++a) Line(&image, x - 3, y + a, x + 3, y + a, blue);
  }
  return image;
}

std::string DefaultPlotPath(const std::string& out) {
  const size_t dot = out.find_last_of('.');
  const size_t slash = out.find_last_of('/');
  const std::string stem =
      (dot != std::string::npos && (slash == std::string::npos || dot > slash)) ? out.substr(0, dot) : out;
  return stem + ".png";
}

void RunLearn(const LearnArgs& args) {
  const PairsList list = ReadPairsList(args.pairs);
  const double k = !std::isnan(args.noise_k) ? args.noise_k : list.noise_k;
  std::vector<TrainingPair> pairs;
  ProgressPrinter progress(args.quiet);
  double k_used_sum = 0;
  int k_used_count = 0;
  for (size_t i = 0; i < list.noisy.size(); ++i) {
    TrainingPair pair;
    pair.name = list.noisy[i];
    pair.noisy = ReadNoisyMesh(list.noisy[i]);
    pair.truth = ReadMesh(list.truth[i]);
    RB_CHECK(pair.truth.num_vertices() == pair.noisy.mesh.num_vertices() && pair.truth.F == pair.noisy.mesh.F, "pair ",
             i + 1, ": '", list.noisy[i], "' and '", list.truth[i], "' differ in vertices or faces");
    if (!pair.noisy.has_covariance()) {
      GenericNoiseOptions noise;
      noise.noise_edge_multiple = k;  // NaN: estimated from the mesh
      GenericNoiseSummary noise_summary;
      pair.noisy = MakeGenericNoisyMesh(pair.noisy.mesh, noise, &noise_summary);
      k_used_sum += noise_summary.noise_edge_multiple;
      ++k_used_count;
    }
    pairs.push_back(std::move(pair));
    progress.Update(0.02 * (i + 1) / list.noisy.size(), "reading pairs");
  }
  LearnPriorOptions options;
  options.method = ParseLearnMethod(args.method);
  options.spline.num_knots = args.knots;
  options.regularizer_weight = args.w;
  options.prior_weight = args.prior_weight;
  options.max_iterations = args.iterations;
  options.time_limit_s = args.time_limit_s;
  options.num_threads = args.threads;
  if (args.step > 0) {
    options.initial_step = std::min(args.step, 1.0);
    options.interleaved_step = args.step;
  }
  options.pattern_search_sweeps = args.pattern_sweeps;
  options.pattern_search_step = args.pattern_step;
  options.bump_search_sweeps = args.bump_sweeps;
  options.bump_search_step = args.bump_step;
  options.bump_search_method = ParseBumpSearchMethod(args.bump_method);
  options.bump_search_min_step = std::min(options.bump_search_min_step, args.bump_step);
  options.bump_search_width_d = args.bump_width;
  options.bump_search_centres_d = args.bump_centres;
  options.progress = [&progress](double fraction, std::string_view stage) {
    progress.Update(0.02 + 0.98 * fraction, stage);
  };
  options.Check();
  LearnPriorSummary summary;
  const Eigen::VectorXd theta = LearnPrior(pairs, options, {}, &summary);
  progress.Finish();

  LearnedPrior prior;
  prior.spline = options.spline;
  prior.theta = theta;
  prior.prior_weight = options.prior_weight;
  prior.noise_kind = list.noise_kind.empty() ? (k_used_count > 0 ? "generic" : "covariance") : list.noise_kind;
  prior.noise_k = k_used_count > 0 ? k_used_sum / k_used_count : k;
  if (k_used_count == 0) prior.noise_k_max = list.noise_k_max;
  prior.training_set = std::filesystem::absolute(args.pairs).lexically_normal().string();
  prior.training_pairs = static_cast<int>(pairs.size());
  prior.method = LearnMethodName(options.method);
  if (options.bump_search_sweeps > 0) {
    prior.method += StrCat(" + bump search (", BumpSearchMethodName(options.bump_search_method), ", ",
                           summary.bump_search_moves, " moves)");
  }
  if (options.pattern_search_sweeps > 0) {
    prior.method += StrCat(" + pattern search (", summary.pattern_search_moves, " moves)");
  }
  prior.regularizer_weight = options.regularizer_weight;
  prior.training_mse_le2 = summary.final_data_loss / std::max(1, summary.num_vertices);
  prior.date = UtcNowIso8601();
  WriteLearnedPrior(prior, args.out);
  const std::string plot = args.plot.empty() ? DefaultPlotPath(args.out) : args.plot;
  WritePng(PlotPotential(SplinePotential(options.spline, theta)), plot);
  std::printf(
      "learned %d knots by %s on %zu pairs (%d vertices): mean squared vertex error %.5f -> %.5f l_e^2 "
      "(%+.1f%%), %d iterations, %.1f s (%s)\n",
      options.spline.num_knots, prior.method.c_str(), pairs.size(), summary.num_vertices,
      summary.initial_data_loss / std::max(1, summary.num_vertices), prior.training_mse_le2,
      100.0 * (summary.final_data_loss / summary.initial_data_loss - 1.0), summary.iterations, summary.total_time_s,
      summary.termination.c_str());
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
    sub->add_option("--out", args->out, "Output folder (train/, test/, train_pairs.txt, test_pairs.txt)")->required();
    sub->add_option("--seed", args->seed, "Random seed: the same seed writes the same meshes");
    sub->add_option("--noise", args->k, "Noise sigma in units of the mean edge length l_e (k), [0, 5]")
        ->check(CLI::Range(0.0, 5.0));
    sub->add_option("--noise-max", args->k_max,
                    "A mixture of noise levels: copies spread evenly over k in [--noise, --noise-max] (each noisy "
                    "PLY then holds its own covariance); 0: one level, [0, 5]")
        ->check(CLI::Range(0.0, 5.0));
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
    sub->add_flag("--quiet,-q", args->quiet, "No progress on stderr");
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
    sub->add_option("--out", args->out, "Output prior (YAML), for 'rangebayes smooth --prior'")->required();
    sub->add_option("--plot", args->plot,
                    "PNG plot of the learned potential beside the square root (default: --out "
                    "with .png)");
    sub->add_option("--knots", args->knots, "Number of spline knots N over d in [0, 2], [3, 256]")
        ->check(CLI::Range(3, 256));
    sub->add_option(
           "--method", args->method,
           "none (default): only the searches (--bump-sweeps, --pattern-sweeps), from the square root (learns "
           "the second well near sqrt(2), BENCHMARKS.md); interleaved: the paper's finite differences beside the "
           "CG iterations; implicit: exact gradient at the optimum by implicit differentiation")
        ->check(CLI::IsMember({"interleaved", "implicit", "none"}));
    sub->add_option("--w", args->w, "Weight w of the curvature regulariser on the knots (paper eq. 19), [0, 1e6]")
        ->check(CLI::Range(0.0, 1e6));
    sub->add_option("--noise", args->noise_k,
                    "Noise sigma / l_e of the noisy meshes without covariances (default: the pairs list's "
                    "'# noise:' line, else estimated per mesh)");
    sub->add_option("--prior-weight", args->prior_weight, "Prior weight beta of the smoother, (0, 1e6]")
        ->check(CLI::Range(1e-12, 1e6));
    sub->add_option("--iterations", args->iterations, "Outer iterations (0: 400 interleaved, 40 implicit), [0, 1e6]")
        ->check(CLI::Range(0, 1000000));
    sub->add_option("--time-limit", args->time_limit_s, "Stop learning after this many seconds (0: no limit)")
        ->check(CLI::Range(0.0, 1e9));
    sub->add_option("--step", args->step,
                    "Step: interleaved fixed step alpha (default 0.01); implicit first step in knot units "
                    "(default 0.02); 0: default")
        ->check(CLI::Range(0.0, 1e6));
    sub->add_option("--pattern-sweeps", args->pattern_sweeps,
                    "After learning: sweeps of a pattern search on the cold-smoothing loss (each tries theta_j +- "
                    "step for every knot; BENCHMARKS.md 'Learned priors'), [0, 1000]; 0: off")
        ->check(CLI::Range(0, 1000));
    sub->add_option("--pattern-step", args->pattern_step,
                    "Pattern search: initial step in knot-value units, halved after a sweep without a move, (0, 1]")
        ->check(CLI::Range(1e-9, 1.0));
    sub->add_option("--bump-sweeps", args->bump_sweeps,
                    "After the --method (none by default): sweeps of a search on the cold-smoothing loss along "
                    "smooth Gaussian bumps of the knot values (sigma --bump-width) centred at d = 14/15, 16/15, "
                    "..., 28/15 (BENCHMARKS.md 'Learned priors'), [0, 1000]; 0: off")
        ->check(CLI::Range(0, 1000));
    sub->add_option("--bump-method", args->bump_method,
                    "Bump search: filtering (implicit filtering: central-difference gradient over the bump heights "
                    "with a stencil that halves on failure, then a line search) or coordinate (one bump at a time)")
        ->check(CLI::IsMember({"filtering", "coordinate"}));
    sub->add_option("--bump-step", args->bump_step,
                    "Bump search: initial bump height in knot-value units (filtering: the stencil size, halved "
                    "after a stencil failure, the search ends below 0.005; coordinate: grown x1.5 after a move, "
                    "halved after a failure), (0, 1]")
        ->check(CLI::Range(1e-9, 1.0));
    sub->add_option("--bump-width", args->bump_width, "Bump search: sigma of the bumps in d, (0, 1]")
        ->check(CLI::Range(1e-9, 1.0));
    sub->add_option("--bump-centres", args->bump_centres,
                    "Bump search: the bump centres in d, comma-separated, each in (0, 2) (default: the knots 7-14 "
                    "of 16)")
        ->delimiter(',')
        ->check(CLI::Range(1e-9, 2.0 - 1e-9));
    sub->add_option("--threads", args->threads, "Smoother threads (0: all cores)")->check(CLI::Range(0, 1024));
    sub->add_flag("--quiet,-q", args->quiet, "No progress on stderr");
    sub->callback([args] { RunLearn(*args); });
  }
}

RB_REGISTER_COMMANDS(70, AddCommands);

}  // namespace
}  // namespace rangebayes::apps
