// Adaptive ε benchmark (BENCHMARKS.md "Bayesian smoothing" → "Adaptive ε"): the square-root prior with one ε²
// per face from bayes/adaptive_epsilon.h, on every denoising case of the benchmark meshes.
//
//   bench_adaptive quality [--data DIR] [--reference gt|prepass|auto|smoothref|none] [--rule scan]
//                          [--scale C] [--rings R] [--truncate T] [--protect D] [--protect-rings N] [--floor D0]
//                          [--max E2] [--cases a,b,...] [--estimate] [--baseline]
//     --reference gt       the rule on the ground truth: an upper bound of what any per-face ε can do
//     --reference prepass  the rule on the noisy input smoothed once with the default (global ε² = 1e-4,
//                          fast tolerance): what a real run can do; the pre-pass time is included
//     --reference auto     AdaptiveEpsilonAuto (what `rangebayes smooth` does by default for --prior sqrt): one
//                          fast pre-pass, the gate, then the detail rule or the global ε²
//     --reference smoothref  the rule on a smoother reference (--ref-eps2 E global ε² or --ref-prior quadratic,
//                          --ref-beta, --ref-tolerance); prints the reference's pair-d median / q90 and MAE
//     --reference none     the default smoother (global ε²), for comparison
//     --normal-rings N     average the reference's face normals over N vertex rings first (the detail rule: 4)
//     --beta B             prior weight of every run (default 2.4)
//     --rule scan          the scan rule (the gate of auto; AdaptiveEpsilonOptions{}, also without --rule)
//     --baseline           also run the default smoother and print its MAE beside
//     --held-out           the held-out meshes (trim-star 0.5, buste, impulsive nicolo) instead of the table
//     with --reference auto (SmoothAdaptiveEpsilon, as `rangebayes smooth`; prints pre-pass and final iterations /
//     evaluations): --prepass-iterations N (cap, 0: the fast preset's), --early-iterations N (0: no early
//     decision), --early-gate E, --gate E, --warm 0|1 (final solve of a curved mesh from the pre-pass)
//
//   bench_adaptive gates [--data DIR] [--caps 0,10,20,40,80,-1] [--estimate] [--held-out] [--cases a,b]
//                        [--resynth K [--seed S]]
//     the gate rule's and the detail rule's median ε² on pre-passes capped at each count (0: the noisy input,
//     -1: the fast preset, i.e. converged), with the rules' time; --resynth K smooths new noisy copies of the
//     ground truths (Gaussian noise of K mean edges along the vertex normals) instead of the files
#include <sys/resource.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "bayes/adaptive_epsilon.h"
#include "bayes/noise_model.h"
#include "bayes/smooth.h"
#include "bench/bench_main.h"
#include "core/mesh_io.h"
#include "core/normal_error.h"
#include "core/render.h"
#include "core/topology.h"

using namespace rangebayes;

namespace {

struct Case {
  std::string name, gt, noisy;
  double k, target;
};

// Meshes the rules were never looked at while they were chosen: noise level given where the
// file name states it, else estimated (NaN k).
std::vector<Case> HeldOutCases() {
  const double none = std::nan("");
  return {
      {"trim-star 0.5 (held out)", "guideddenoising/trim-star_gt.obj", "guideddenoising/trim-star_noisy_0.5.obj", 0.5,
       none},
      {"buste i1 (held out, k estimated)", "nllr/buste_gt.off", "nllr/buste_noisy_i1.off", none, none},
      {"nicolo impulsive 0.6 (held out, k estimated)", "gcn-denoiser/nicolo_gt.obj",
       "gcn-denoiser/nicolo_noisy_impulsive_n6.obj", none, none},
  };
}

std::vector<Case> Cases() {
  const double none = std::nan("");
  return {
      {"fandisk 0.3", "guideddenoising/fandisk_gt.obj", "guideddenoising/fandisk_noisy_gauss0.3.obj", 0.3, 2.4},
      {"fandisk 0.6 (GCN)", "gcn-denoiser/fandisk_gt.obj", "gcn-denoiser/fandisk_noisy_gauss_n6.obj", 0.6, none},
      {"fandisk 0.7", "guideddenoising/fandisk_gt.obj", "guideddenoising/fandisk_noisy_gauss0.7.obj", 0.7, 5.5},
      {"block 0.4", "guideddenoising/block_gt.obj", "guideddenoising/block_noisy_gauss0.4.obj", 0.4, 4.0},
      {"trim-star 0.3 (GCN)", "gcn-denoiser/trim-star_gt.obj", "gcn-denoiser/trim-star_noisy_gauss_n3.obj", 0.3, 5.3},
      {"nicolo 0.2", "guideddenoising/nicolo_gt.obj", "guideddenoising/nicolo_noisy_gauss0.2.obj", 0.2, 6.5},
      {"bunny 0.2", "guideddenoising/bunny_gt.obj", "guideddenoising/bunny_noisy_gauss0.2.obj", 0.2, 6.6},
      {"julius 0.2", "guideddenoising/julius_gt.obj", "guideddenoising/julius_noisy_gauss0.2.obj", 0.2, none},
      {"igea 0.3", "nllr/igea_gt.off", "nllr/igea_noisy_n3.off", 0.3, 10.0},
      {"child 0.3", "nllr/child_gt.off", "nllr/child_noisy_n3.off", 0.3, 7.5},
  };
}

// Median and 90th percentile of the normal difference d = ‖n_s − n_t‖ over the face pairs of `mesh`.
std::pair<double, double> PairDifferenceQuantiles(const Mesh& mesh) {
  const IndexPairs pairs = ComputeFacePairs(mesh);
  std::vector<Eigen::Vector3d> normal(static_cast<size_t>(mesh.num_faces()));
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)).transpose();
    normal[static_cast<size_t>(f)] =
        (mesh.V.row(mesh.F(f, 1)).transpose() - a).cross(mesh.V.row(mesh.F(f, 2)).transpose() - a).normalized();
  }
  std::vector<double> d;
  for (Eigen::Index p = 0; p < pairs.rows(); ++p) {
    const double x = (normal[static_cast<size_t>(pairs(p, 0))] - normal[static_cast<size_t>(pairs(p, 1))]).norm();
    if (std::isfinite(x)) d.push_back(x);
  }
  if (d.empty()) return {0, 0};
  std::sort(d.begin(), d.end());
  return {d[d.size() / 2], d[d.size() * 9 / 10]};
}

double CpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_utime.tv_sec + 1e-6 * usage.ru_utime.tv_usec + usage.ru_stime.tv_sec + 1e-6 * usage.ru_stime.tv_usec;
}

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

int Quality(std::map<std::string, std::string>& flags) {
  const std::string data = flags.count("--data") ? flags["--data"] : "../shared/data/meshes";
  const std::string reference = flags.count("--reference") ? flags["--reference"] : "prepass";
  if (reference != "gt" && reference != "prepass" && reference != "none" && reference != "smoothref" &&
      reference != "auto") {
    std::fprintf(stderr, "bench_adaptive: --reference must be gt, prepass, auto, smoothref or none\n");
    return 2;
  }
  AdaptiveEpsilonOptions rule;
  if (flags.count("--rule")) {
    if (flags["--rule"] != "scan") {
      std::fprintf(stderr, "bench_adaptive: --rule must be scan\n");
      return 2;
    }
    rule = ScanAdaptiveEpsilonOptions();
  }
  if (flags.count("--scale")) rule.scale = std::stod(flags["--scale"]);
  if (flags.count("--normal-rings")) rule.normal_smoothing_rings = std::stoi(flags["--normal-rings"]);
  if (flags.count("--rings")) rule.ring_iterations = std::stoi(flags["--rings"]);
  if (flags.count("--truncate")) rule.truncate_normal_difference = std::stod(flags["--truncate"]);
  if (flags.count("--protect")) rule.protect_normal_difference = std::stod(flags["--protect"]);
  if (flags.count("--protect-rings")) rule.protect_rings = std::stoi(flags["--protect-rings"]);
  if (flags.count("--protect-degree")) rule.protect_min_crease_degree = std::stoi(flags["--protect-degree"]);
  if (flags.count("--floor")) rule.floor_normal_difference = std::stod(flags["--floor"]);
  if (flags.count("--max")) rule.max_epsilon_squared = std::stod(flags["--max"]);
  rule.Check();
  const bool estimate = flags.count("--estimate") > 0;
  const bool baseline = flags.count("--baseline") > 0;
  const std::string selected = flags.count("--cases") ? flags["--cases"] : "";

  std::printf("normal smoothing rings %d\n", rule.normal_smoothing_rings);
  std::printf(
      "reference %s, truncated mean, scale %g, rings %d, truncate %g, protect %g (rings %d, degree %d), floor %g, "
      "eps2 in [%g, %g], noise level %s\n",
      reference.c_str(), rule.scale,
      rule.ring_iterations, rule.truncate_normal_difference, rule.protect_normal_difference, rule.protect_rings,
      rule.protect_min_crease_degree, rule.floor_normal_difference, rule.min_epsilon_squared, rule.max_epsilon_squared,
      estimate ? "estimated" : "given");
  std::printf(
      "| case | target | default MAE | adaptive MAE | eps2 p10 / p50 / p90 | pre-pass (s) | total (s) | "
      "CPU (s) |\n");
  std::printf("|---|---|---|---|---|---|---|---|\n");
  for (const Case& c : flags.count("--held-out") ? HeldOutCases() : Cases()) {
    if (!selected.empty() && selected.find(c.name.substr(0, c.name.find(' '))) == std::string::npos) continue;
    const Mesh gt = ReadMesh(data + "/" + c.gt);
    const Mesh noisy = ReadMesh(data + "/" + c.noisy);
    GenericNoiseOptions noise;
    if (!estimate) noise.noise_edge_multiple = c.k;
    const NoisyMesh input = MakeGenericNoisyMesh(noisy, noise);
    SmoothOptions options;
    options.adaptive_epsilon = false;  // the plain solve (global ε²)
    if (flags.count("--beta")) options.prior_weight = std::stod(flags["--beta"]);
    double baseline_mae = std::nan("");
    if (baseline) baseline_mae = MeanAngularErrorDeg(Smooth(input, options), gt);

    const double cpu_start = CpuSeconds();
    const auto start = std::chrono::steady_clock::now();
    AdaptiveEpsilonSummary rule_summary;
    double prepass_s = 0;
    std::string ref_info;
    if (reference == "gt") {
      options.face_epsilon_squared = AdaptiveEpsilonSquared(gt, rule, &rule_summary);
    } else if (reference == "prepass") {
      options.face_epsilon_squared = AdaptiveEpsilonFromPrepass(input, options, rule, &rule_summary);
      prepass_s = Seconds(start);
    } else if (reference == "auto") {
      // AdaptiveEpsilonAuto exactly as `rangebayes smooth` uses it (the rule flags above are not applied;
      // --gate changes the gate threshold for scans of it).
      AutoAdaptiveEpsilonOptions automatic;
      if (flags.count("--gate")) automatic.min_gate_median_epsilon_squared = std::stod(flags["--gate"]);
      if (flags.count("--prepass-iterations"))
        automatic.prepass_max_iterations = std::stoi(flags["--prepass-iterations"]);
      if (flags.count("--warm")) automatic.final_from_prepass = flags["--warm"] != "0";
      if (flags.count("--early-iterations"))
        automatic.prepass_early_iterations = std::stoi(flags["--early-iterations"]);
      if (flags.count("--early-gate"))
        automatic.early_curved_gate_median_epsilon_squared = std::stod(flags["--early-gate"]);
      SmoothSummary final_summary;
      const Mesh result = SmoothAdaptiveEpsilon(input, options, automatic, &rule_summary, &final_summary);
      const double total_s = Seconds(start), cpu = CpuSeconds() - cpu_start;
      std::printf(
          "| %s | %s | %s | %.3f | gate %.2e %s | pre-pass %d it / %d ev | final %d it / %d ev | total %d ev "
          "| %.2f s | CPU %.2f s |\n",
          c.name.c_str(), std::isnan(c.target) ? "–" : std::to_string(c.target).substr(0, 4).c_str(),
          std::isnan(baseline_mae) ? "–" : std::to_string(baseline_mae).substr(0, 5).c_str(),
          MeanAngularErrorDeg(result, gt), rule_summary.gate_median_epsilon_squared,
          rule_summary.per_face ? "curved" : "flat", rule_summary.prepass_iterations, rule_summary.prepass_evaluations,
          final_summary.iterations, final_summary.evaluations,
          rule_summary.prepass_evaluations + final_summary.evaluations, total_s, cpu);
      std::fflush(stdout);
      continue;
      ref_info = " gate median eps2 " + std::to_string(rule_summary.gate_median_epsilon_squared).substr(0, 7) +
                 (rule_summary.per_face ? ": per-face eps2" : ": global eps2 kept");
    } else if (reference == "smoothref") {
      // The rule on a smoother reference (global --ref-eps2, or --ref-prior quadratic), protection read from the
      // reference itself.
      SmoothOptions ref = options;
      ref.tolerance =
          flags.count("--ref-tolerance") ? ParseSmoothTolerance(flags["--ref-tolerance"]) : SmoothTolerance::kFast;
      ref.sqrt_epsilon_squared = flags.count("--ref-eps2") ? std::stod(flags["--ref-eps2"]) : 0.05;
      if (flags.count("--ref-prior")) ref.prior = ParsePriorKind(flags["--ref-prior"]);
      if (flags.count("--ref-beta")) ref.prior_weight = std::stod(flags["--ref-beta"]);
      const Mesh reference_mesh = Smooth(input, ref);
      const auto [d50, d90] = PairDifferenceQuantiles(reference_mesh);
      ref_info = "ref d50 " + std::to_string(d50).substr(0, 5) + " d90 " + std::to_string(d90).substr(0, 5) + " MAE " +
                 std::to_string(MeanAngularErrorDeg(reference_mesh, gt)).substr(0, 5);
      options.face_epsilon_squared = AdaptiveEpsilonSquared(reference_mesh, rule, &rule_summary);
      prepass_s = Seconds(start);
    }
    const Mesh result = Smooth(input, options);
    const double total_s = Seconds(start), cpu = CpuSeconds() - cpu_start;
    const double mae = MeanAngularErrorDeg(result, gt);
    char base[32], target[32];
    std::snprintf(base, sizeof base, std::isnan(baseline_mae) ? "–" : "%.2f", baseline_mae);
    std::snprintf(target, sizeof target, std::isnan(c.target) ? "–" : "%.1f", c.target);
    std::printf("| %s | %s | %s | %.3f | %.2g / %.2g / %.2g | %.2f | %.2f | %.2f |%s\n", c.name.c_str(), target, base,
                mae, rule_summary.p10_epsilon_squared, rule_summary.median_epsilon_squared,
                rule_summary.p90_epsilon_squared, prepass_s, total_s, cpu, ref_info.c_str());
    std::fflush(stdout);
  }
  return 0;
}

// Gate statistics on pre-passes capped at several iteration counts (0: the noisy input itself): the scan rule's
// median ε² (the gate of AdaptiveEpsilonAuto) and the detail rule's median / p25 ε², per case.
int Gates(std::map<std::string, std::string>& flags) {
  const std::string data = flags.count("--data") ? flags["--data"] : "../shared/data/meshes";
  const bool estimate = flags.count("--estimate") > 0;
  const std::string selected = flags.count("--cases") ? flags["--cases"] : "";
  std::vector<int> caps = {0, 10, 20, 40, 80, -1};
  if (flags.count("--caps")) {
    caps.clear();
    std::string list = flags["--caps"];
    size_t pos = 0;
    while (pos <= list.size()) {
      const size_t comma = std::min(list.find(',', pos), list.size());
      caps.push_back(std::stoi(list.substr(pos, comma - pos)));
      pos = comma + 1;
    }
  }
  std::printf(
      "| case | pre-pass iterations (evaluations) | scan gate median eps2 | detail median eps2 | detail p25 |\n");
  std::printf("|---|---|---|---|---|\n");
  for (const Case& c : flags.count("--held-out") ? HeldOutCases() : Cases()) {
    if (!selected.empty() && selected.find(c.name.substr(0, c.name.find(' '))) == std::string::npos) continue;
    Mesh noisy = ReadMesh(data + "/" + c.noisy);
    double k = c.k;
    if (flags.count("--resynth")) {
      // A new noisy copy of the ground truth: Gaussian noise of --resynth mean edge lengths along the
      // area-weighted vertex normals (seeded), for noise levels the files do not have.
      k = std::stod(flags["--resynth"]);
      noisy = ReadMesh(data + "/" + c.gt);
      const Normals normals = AreaWeightedVertexNormals(noisy);
      const double sigma = k * MeanEdgeLength(noisy);
      std::mt19937 rng(flags.count("--seed") ? std::stoi(flags["--seed"]) : 1);
      std::normal_distribution<double> gauss(0.0, sigma);
      for (int v = 0; v < noisy.num_vertices(); ++v) noisy.V.row(v) += gauss(rng) * normals.row(v);
    }
    GenericNoiseOptions noise;
    if (!estimate) noise.noise_edge_multiple = k;
    const NoisyMesh input = MakeGenericNoisyMesh(noisy, noise);
    for (int cap : caps) {
      Mesh reference = input.mesh;
      SmoothSummary summary;
      if (cap != 0) {
        SmoothOptions pre;
        pre.adaptive_epsilon = false;  // the plain solve (global ε²)
        pre.tolerance = SmoothTolerance::kFast;
        pre.max_iterations = std::max(cap, 0);
        reference = Smooth(input, pre, &summary);
      }
      AdaptiveEpsilonSummary gate, detail;
      AdaptiveEpsilonSquared(reference, ScanAdaptiveEpsilonOptions(), &gate);
      const std::vector<double> e2 = AdaptiveEpsilonSquared(reference, DetailAdaptiveEpsilonOptions(), &detail);
      std::vector<double> sorted = e2;
      std::sort(sorted.begin(), sorted.end());
      const double p25 = sorted.empty() ? 0 : sorted[sorted.size() / 4];
      std::printf("| %s | %d (%d) | %.2e | %.2e | %.2e | rules %.3f / %.3f s, pre-pass %.3f s (setup %.3f s) |\n",
                  c.name.c_str(), summary.iterations, summary.evaluations, gate.median_epsilon_squared,
                  detail.median_epsilon_squared, p25, gate.time_s, detail.time_s, summary.time_s, summary.setup_time_s);
      std::fflush(stdout);
    }
  }
  return 0;
}

int RunBench(int argc, char** argv) {
  if (argc < 2 || (std::string(argv[1]) != "quality" && std::string(argv[1]) != "gates")) {
    std::fprintf(stderr, "usage: bench_adaptive quality [--reference gt|prepass|none] [options]\n");
    return 2;
  }
  std::map<std::string, std::string> flags;
  for (int i = 2; i < argc; ++i) {
    const std::string a(argv[i]);
    if (a.rfind("--", 0) != 0) {
      std::fprintf(stderr, "bench_adaptive: unexpected argument %s\n", a.c_str());
      return 2;
    }
    if (i + 1 < argc && std::string(argv[i + 1]).rfind("--", 0) != 0) {
      flags.insert_or_assign(a, std::string(argv[++i]));
    } else {
      flags.insert_or_assign(a, std::string(1, '1'));
    }
  }
  return std::string(argv[1]) == "gates" ? Gates(flags) : Quality(flags);
}

}  // namespace

int main(int argc, char** argv) { return rangebayes::bench::Main("bench_adaptive", RunBench, argc, argv); }
