// `rangebayes smooth IN OUT` (Bayesian smoothing, bayes/smooth.h) and `rangebayes eval GT RESULT` (docs/design.md §7).
#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>

#include "apps/command.h"
#include "apps/flags.h"
#include "apps/progress.h"
#include "apps/read_input.h"
#include "bayes/adaptive_epsilon.h"
#include "bayes/learn_prior_io.h"
#include "bayes/noise_model.h"
#include "bayes/smooth.h"
#include "core/error.h"
#include "core/files.h"
#include "core/mesh_io.h"
#include "core/render.h"
#include "pipeline/mesh_metrics.h"
#include "pipeline/png.h"

namespace rangebayes::apps {
namespace {

struct SmoothArgs {
  std::string input;
  std::string output;
  std::optional<double> noise;  // empty: the file's covariances, else estimated
  std::optional<double> sigma;
  std::string prior = PriorKindName(SmoothOptions{}.prior);
  std::string tolerance = "default";
  std::optional<double> prior_weight;  // empty: ResolvePriorWeight's rule
  double epsilon_squared = SmoothOptions{}.sqrt_epsilon_squared;
  bool adaptive_epsilon = true;
  bool multilevel = SmoothOptions{}.multilevel;
  bool prior_weight_per_stride = SmoothOptions{}.prior_weight_per_stride;
  bool precondition_rays = SmoothOptions{}.precondition_rays;
  double gap_tolerance = SmoothOptions{}.gap_tolerance;
  double robust_data_nu = SmoothOptions{}.robust_data_nu;
  double time_limit_s = SmoothOptions{}.time_limit_s;
  int max_iterations = SmoothOptions{}.max_iterations;
  int continuation = SmoothOptions{}.epsilon_continuation_stages;  // per-face ε² by AdaptiveEpsilonAuto (sqrt prior); --no-adaptive-eps: off
  double across_ratio = GenericNoiseOptions{}.across_ratio;
  int threads = 0;
  std::string png;
  std::vector<double> view;  // empty: as the camera saw it (a depth image's mesh), else along −z
  bool ignore_covariance = false;
  bool quiet = false;
};

// --view, or along −z when it is not given.
Eigen::Vector3d ViewDirection(const std::vector<double>& v) {
  return v.empty() ? Eigen::Vector3d(0, 0, -1) : ViewDirectionOption(v);
}

void RunSmooth(const SmoothArgs& args) {
  if (args.noise && args.sigma) UsageError("give --noise or --sigma, not both");
  const Eigen::Vector3d view = ViewDirection(args.view);
  SmoothOptions options;
  const SmoothingPrior smoothing_prior = ApplySmoothingPrior(args.prior, args.prior_weight, &options);
  const std::optional<LearnedPrior>& prior = smoothing_prior.learned;
  options.tolerance = ParseSmoothTolerance(args.tolerance);
  options.sqrt_epsilon_squared = args.epsilon_squared;
  options.num_threads = args.threads;
  options.Check();
  CheckOutputMesh(args.output);
  RequireDistinctOutputs({{"OUT", args.output}, {"--png", args.png}});
  if (!args.png.empty()) CheckFileToWrite(args.png);

  NoisyMesh noisy = ReadInputMesh(args.input, args.quiet);
  std::printf("input:      %s (%d vertices, %d faces)\n", args.input.c_str(), noisy.mesh.num_vertices(),
              noisy.mesh.num_faces());
  GenericNoiseOptions noise;
  noise.noise_edge_multiple = args.noise;
  noise.sigma = args.sigma;
  noise.across_ratio = args.across_ratio;
  NoiseModelChoice choice;
  noisy = ChooseNoiseModel(noisy, noise, args.ignore_covariance ? CovarianceSource::kGeneric : CovarianceSource::kAuto,
                           &choice);
  if (choice.replaced_file) {
    Notice(args.quiet, "the file's per-vertex covariances are replaced by the generic noise model");
  }
  std::printf("noise:      %s\n", choice.BriefReport().c_str());
  if (!choice.from_file && choice.generic.estimated && !(choice.generic.noise_edge_multiple > 0)) {
    Notice(false, "warning: no noise measurable in this mesh; give --noise or --sigma");
  }
  // Where β came from when it is not the prior's own: a prior.yaml with prior_weight 0 records none.
  const std::string beta_source = args.prior_weight.has_value() ? " (--prior-weight)"
                                  : prior && !(prior->prior_weight > 0)
                                      ? " (the default: " + args.prior + " records no prior_weight)"
                                      : "";
  std::printf("prior:      %s, beta %.4g%s%s\n", args.prior.c_str(), options.prior_weight, beta_source.c_str(),
              !prior && options.prior == PriorKind::kSqrt
                  ? (", eps2 " + std::to_string(options.sqrt_epsilon_squared)).c_str()
                  : "");
  std::printf("minimiser:  CG, tolerance %s, threads %s\n", args.tolerance.c_str(),
              args.threads > 0 ? std::to_string(args.threads).c_str() : "all");
  std::fflush(stdout);

  ProgressPrinter progress(args.quiet);
  options.progress = progress.callback();
  options.adaptive_epsilon = args.adaptive_epsilon;
  options.multilevel = args.multilevel;
  options.prior_weight_per_stride = args.prior_weight_per_stride;
  options.precondition_rays = args.precondition_rays;
  options.epsilon_continuation_stages = args.continuation;
  options.gap_tolerance = args.gap_tolerance;
  options.robust_data_nu = args.robust_data_nu;
  options.time_limit_s = args.time_limit_s;
  options.max_iterations = args.max_iterations;
  SmoothSummary summary;
  const Mesh result = Smooth(noisy, options, &summary);
  progress.Finish();
  WriteMesh(result, args.output);
  std::printf("result:     %s\n", args.output.c_str());
  std::fputs(summary.BriefReport().c_str(), stdout);
  // Noise folds some faces and smoothing unfolds most; the warning is for a result with more folds than its input.
  if (summary.flipped_faces > summary.input_flipped_faces) {
    Notice(false, "warning: " + std::to_string(summary.flipped_faces) +
                      " faces flipped in the result (folded against their neighbours; the input had " +
                      std::to_string(summary.input_flipped_faces) + "); try a lower " +
                      (choice.from_file ? "--prior-weight" : "--noise or --prior-weight"));
  }
  if (!args.png.empty()) {
    RenderOptions render;
    render.width_px = 640;
    render.height_px = 640;
    // Before and after in one framing, fitted to the input; a --view given is kept as it is.
    render.view_direction = view;
    if (args.view.empty()) {
      FitView(noisy, &render);
    } else {
      render.fit_box = CentralBox(noisy.mesh, 1.0);
    }
    WritePng(SideBySide({RenderMesh(noisy.mesh, render), RenderMesh(result, render)}), args.png);
    std::printf("picture:    %s (before | after)\n", args.png.c_str());
  }
}

struct EvalArgs {
  std::string ground_truth;
  std::string result;
  bool surface_only = false;
};

nlohmann::json Number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

void RunEval(const EvalArgs& args) {
  const Mesh gt = ReadMesh(args.ground_truth);
  const Mesh result = ReadMesh(args.result);
  if (!args.surface_only && !SameConnectivity(result, gt)) {
    RB_FAIL(args.result, " and ", args.ground_truth,
            " do not share connectivity (needed for mae_deg); use --surface-only for surface distances alone");
  }
  nlohmann::json out;
  for (const EvaluationField& f :
       EvaluationFields(EvaluateMesh(result, gt, !args.surface_only, args.result, args.ground_truth))) {
    out[f.name] = f.count ? nlohmann::json(static_cast<std::int64_t>(f.value)) : Number(f.value);
  }
  std::printf("%s\n", out.dump().c_str());
}

}  // namespace

RB_REGISTER_COMMANDS(20, [](CLI::App& app) {
  auto args = std::make_shared<SmoothArgs>();
  auto* sub = app.add_subcommand(
      "smooth", "Bayesian smoothing of a noisy mesh (MAP of paper §3-4): keeps vertex order and faces");
  sub->add_option("IN", args->input, "Noisy mesh (.ply/.obj/.off); PLY cov_xx..cov_zz vertex properties are used")
      ->required();
  sub->add_option("OUT", args->output, "Smoothed mesh (.ply/.obj/.off)")->required();
  sub->add_option("--noise", args->noise,
                  "Noise std as a multiple k of the mean edge length, (0, 10]; default: the file's covariances, "
                  "else estimated from the mesh")
      ->check(PositiveReal())
      ->check(RealRange(0.0, 10.0));
  sub->add_option("--sigma", args->sigma, "Noise std in model units (> 0); instead of --noise")->check(PositiveReal());
  AddPriorOption(sub, &args->prior);
  AddToleranceOption(sub, &args->tolerance);
  AddPriorWeightOption(sub, &args->prior_weight);
  sub->add_option("--eps2", args->epsilon_squared, "epsilon^2 of the sqrt potential, (0, 4]")
      ->check(PositiveReal())
      ->check(RealRange(0.0, 4.0));
  sub->add_flag("--adaptive-eps,!--no-adaptive-eps", args->adaptive_epsilon,
                "On by default; sqrt prior: per-face epsilon^2 read from a fast pre-pass on curved meshes "
                "(scans), the global --eps2 on piecewise-flat ones (CAD); costs a pre-pass of 40-80 fast "
                "iterations, from which a curved mesh's final solve starts (BENCHMARKS.md 'Adaptive eps'). "
                "--no-adaptive-eps: the global --eps2 everywhere, no pre-pass");
  sub->add_flag("--stride-weight,!--no-stride-weight", args->prior_weight_per_stride,
                "On by default; meshes with pixel positions and covariances (stereo): the prior weight beta divided "
                "by the pixel grid's step (1 at every pixel, 4 at --downsample 4; at most 4). --no-stride-weight: "
                "beta at every stride");
  sub->add_flag("--multilevel,!--no-multilevel", args->multilevel,
                "On by default; meshes with pixel positions (from rangebayes stereo/replay): solve coarse-to-fine "
                "over the pixel grid. --no-multilevel: one level");
  sub->add_flag("--precondition-rays,!--no-precondition-rays", args->precondition_rays,
                "On by default; meshes with anisotropic covariances (stereo, range scans): CG preconditioned by the "
                "Gauss-Newton matrix of the depths along the rays (multigrid on the pixel grid above 40,000 "
                "vertices). --no-precondition-rays: by the data term alone");
  sub->add_option("--max-iterations", args->max_iterations,
                  "Iteration cap per solve (each continuation stage and grid level has its own), [0, 1e7]; 0: the "
                  "--tolerance preset's (fast 300, default 2000, tight 20000)")
      ->check(CLI::Range(0, 10000000));
  sub->add_option("--time-limit", args->time_limit_s,
                  "Seconds for the whole solve, continuation stages and grid levels included; the summary's distance "
                  "says how far from converged it stopped; 0: no limit")
      ->check(RealRange(0.0, kMaxSmoothTimeLimitS));
  sub->add_option("--gap-tolerance", args->gap_tolerance,
                  "Stop when the estimated distance to the optimum is below this fraction of the energy, [0, 1); "
                  "0: the --tolerance preset's")
      ->check(RealRange(0.0, 0.999999));
  sub->add_option("--robust-data", args->robust_data_nu,
                  "Heavy-tailed data term: Student-t with this many degrees of freedom nu on the Mahalanobis distance "
                  "(gross mismatches stop pulling), (0, 1e6]; 0: Gaussian (the default)")
      ->check(RealRange(0.0, 1e6));
  sub->add_option("--continuation", args->continuation,
                  "sqrt prior: epsilon continuation stages before the final solve (eps2 x 10^s, s = N..1), [-1, 6]; "
                  "-1: 3 on meshes with pixel positions and covariances (stereo), 0 on others")
      ->check(CLI::Range(-1, 6));
  sub->add_option("--across-ratio", args->across_ratio,
                  "Generic noise model: sigma along the normal / sigma across it, [1, 100]")
      ->check(RealRange(1.0, 100.0));
  AddThreadsOption(sub, &args->threads);
  sub->add_option("--png", args->png, "Write a before|after shaded picture (PNG) to this file");
  sub->add_option("--view", args->view,
                  "View direction x y z for --png (model coordinates); default: a depth image's mesh as its camera "
                  "saw it, any other along -z")
      ->expected(3);
  sub->add_flag("--ignore-covariance", args->ignore_covariance,
                "Use the generic noise model even when the file has covariances");
  AddQuietFlag(sub, &args->quiet);
  sub->callback([args] { RunSmooth(*args); });

  auto eval_args = std::make_shared<EvalArgs>();
  auto* eval = app.add_subcommand(
      "eval", "Compare a result mesh with ground truth: one JSON line {mae_deg, ev, hausdorff_rel_bbox, ...}");
  eval->add_option("GT", eval_args->ground_truth, "Ground-truth mesh")->required();
  eval->add_option("RESULT", eval_args->result, "Result mesh (same connectivity for mae_deg)")->required();
  eval->add_flag("--surface-only", eval_args->surface_only,
                 "Skip mae_deg (for results with other connectivity, e.g. decimated meshes)");
  eval->callback([eval_args] { RunEval(*eval_args); });
});

}  // namespace rangebayes::apps
