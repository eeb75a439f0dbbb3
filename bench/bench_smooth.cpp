// Bayesian smoothing benchmarks (BENCHMARKS.md "Bayesian smoothing").
//
//   bench_smooth quality [--data DIR] [--estimate] [--tolerance fast|default|tight]
//                        [--beta B] [--ratio R] [--eps2 E] [--prior sqrt|quadratic|cauchy] [--cases a,b,...]
//       runs every denoising case of DIR (default ../shared/data/meshes) and prints a Markdown table of the
//       mean angular error (degrees) beside the reference points of docs/journal/benchmarks-sessions-1-4.md.
//   bench_smooth speed MESH|--synthetic-faces N [--threads N] [--tolerance T] [--noise K]
//                      [--repeat R] [--gt GT] [--file-covariance]
//                      [--energy-tolerance E] [--kernel portable|auto]
//       times one smoothing run (setup, iterations, per-iteration and per-face times, CPU time, peak RSS, final
//       energy; MAE against GT when given). --file-covariance uses the PLY's covariances (stereo meshes).
//   bench_smooth estimate [--data DIR]     noise-level estimate against the known level of every noisy file.
//   bench_smooth profile [--rings R] MESH...  one JSON line per mesh: EstimateNoiseLevel, the residual profile
//                                           (NoiseResidualProfile, rings 1 … R, default 8) and the tail ratio
//                                           (NoiseResidualTailRatio)
#include <sys/resource.h>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bayes/noise_model.h"
#include "bayes/smooth.h"
#include "bayes/smoothing_energy.h"
#include "bench/bench_main.h"
#include "core/mesh_io.h"
#include "core/normal_error.h"
#include "core/topology.h"

using namespace rangebayes;

namespace {

struct Case {
  std::string name;
  std::string gt;
  std::string noisy;
  double k;
  double reference;  // reference minimiser of docs/journal/benchmarks-sessions-1-4.md (NaN: none)
  double target;     // issue 3's quality target (NaN: none)
  std::string anchor;
};

std::vector<Case> Cases() {
  const double none = std::nan("");
  return {
      {"fandisk 0.3", "guideddenoising/fandisk_gt.obj", "guideddenoising/fandisk_noisy_gauss0.3.obj", 0.3, 2.2, 2.4,
       "L0 2.24, guided 2.93"},
      {"fandisk 0.6 (GCN)", "gcn-denoiser/fandisk_gt.obj", "gcn-denoiser/fandisk_noisy_gauss_n6.obj", 0.6, 4.05, none,
       "guided 6.71, GCN 3.95"},
      {"fandisk 0.7", "guideddenoising/fandisk_gt.obj", "guideddenoising/fandisk_noisy_gauss0.7.obj", 0.7, 4.9, 5.5,
       "guided 8.41"},
      {"block 0.4", "guideddenoising/block_gt.obj", "guideddenoising/block_noisy_gauss0.4.obj", 0.4, 3.7, 4.0,
       "guided 4.09"},
      {"trim-star 0.3 (GCN)", "gcn-denoiser/trim-star_gt.obj", "gcn-denoiser/trim-star_noisy_gauss_n3.obj", 0.3, 5.3,
       5.3, "L0 6.19, GCN 5.32"},
      {"nicolo 0.2", "guideddenoising/nicolo_gt.obj", "guideddenoising/nicolo_noisy_gauss0.2.obj", 0.2, 6.1, 6.5,
       "bilateral normal 7.22"},
      {"bunny 0.2", "guideddenoising/bunny_gt.obj", "guideddenoising/bunny_noisy_gauss0.2.obj", 0.2, 5.7, 6.6,
       "bilateral normal 6.64"},
      {"julius 0.2", "guideddenoising/julius_gt.obj", "guideddenoising/julius_noisy_gauss0.2.obj", 0.2, none, none,
       ""},
      {"igea 0.3", "nllr/igea_gt.off", "nllr/igea_noisy_n3.off", 0.3, 10.2, 10.0, "Taubin 10.18, NLLR 9.40"},
      {"child 0.3", "nllr/child_gt.off", "nllr/child_noisy_n3.off", 0.3, 8.3, 7.5, "bilateral normal 7.80, NLLR 6.70"},
  };
}

std::map<std::string, std::string> ParseFlags(int argc, char** argv, int first, std::vector<std::string>* positional) {
  std::map<std::string, std::string> flags;
  for (int i = first; i < argc; ++i) {
    const std::string a(argv[i]);
    if (a.size() >= 2 && a[0] == '-' && a[1] == '-') {
      if (i + 1 < argc && !(argv[i + 1][0] == '-' && argv[i + 1][1] == '-')) {
        flags[a] = argv[++i];
      } else {
        flags[a] = std::string(1, '1');  // not "1": GCC 12 -Wrestrict false positive once inlined
      }
    } else {
      positional->push_back(a);
    }
  }
  return flags;
}

std::string Join(const std::string& folder, const std::string& file) {
  std::string path = folder;
  path.push_back('/');
  path.append(file);
  return path;
}

double CpuSeconds() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_utime.tv_sec + 1e-6 * usage.ru_utime.tv_usec + usage.ru_stime.tv_sec + 1e-6 * usage.ru_stime.tv_usec;
}

double PeakRssMiB() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;
}

SmoothOptions OptionsFromFlags(std::map<std::string, std::string>& flags) {
  SmoothOptions options;
  if (flags.count("--tolerance")) options.tolerance = ParseSmoothTolerance(flags["--tolerance"]);
  if (flags.count("--beta")) options.prior_weight = std::stod(flags["--beta"]);
  if (flags.count("--eps2")) options.sqrt_epsilon_squared = std::stod(flags["--eps2"]);
  if (flags.count("--prior")) options.prior = ParsePriorKind(flags["--prior"]);
  if (flags.count("--cauchy")) options.cauchy_scale = std::stod(flags["--cauchy"]);
  if (flags.count("--threads")) options.num_threads = std::stoi(flags["--threads"]);
  if (flags.count("--max-iterations")) options.max_iterations = std::stoi(flags["--max-iterations"]);
  if (flags.count("--energy-tolerance")) options.energy_tolerance = std::stod(flags["--energy-tolerance"]);
  if (flags.count("--c2")) options.line_search_c2 = std::stod(flags["--c2"]);
  if (flags.count("--gap-tolerance")) options.gap_tolerance = std::stod(flags["--gap-tolerance"]);
  // The solver alone (the speed targets are stated for it); --adaptive-eps: what `rangebayes smooth` runs.
  options.adaptive_epsilon = flags.count("--adaptive-eps") > 0;
  options.multilevel = flags.count("--no-multilevel") == 0;
  options.precondition_rays = flags.count("--no-precondition-rays") == 0;
  if (flags.count("--continuation")) options.epsilon_continuation_stages = std::stoi(flags["--continuation"]);
  // --kernel portable|auto: the energy's portable kernels even where the CPU has AVX-512 (same
  // bytes; for A/B timing). Default: the widest the CPU has.
  if (flags.count("--kernel")) {
    const std::string kernel = flags["--kernel"];
    if (kernel != "portable" && kernel != "auto") throw std::runtime_error("--kernel: " + kernel);
    SetSmoothingKernel(kernel == "portable" ? SmoothingKernel::kPortable : SmoothingKernel::kAuto);
  }
  return options;
}

int Quality(std::map<std::string, std::string>& flags) {
  const std::string data = flags.count("--data") ? flags["--data"] : "../shared/data/meshes";
  const bool estimate = flags.count("--estimate") > 0;
  SmoothOptions options = OptionsFromFlags(flags);
  GenericNoiseOptions noise;
  if (flags.count("--ratio")) noise.across_ratio = std::stod(flags["--ratio"]);
  std::string selected = flags.count("--cases") ? flags["--cases"] : "";
  std::printf("| case | k given | k used | ours MAE (deg) | reference (journal) | target | best classical / published | iterations | evaluations | energy | time (s) | CPU (s) |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Case& c : Cases()) {
    if (!selected.empty() && selected.find(c.name.substr(0, c.name.find(' '))) == std::string::npos) continue;
    const Mesh gt = ReadMesh(Join(data, c.gt));
    const Mesh noisy = ReadMesh(Join(data, c.noisy));
    GenericNoiseOptions n = noise;
    if (!estimate) n.noise_edge_multiple = c.k;
    GenericNoiseSummary noise_summary;
    const NoisyMesh input = MakeGenericNoisyMesh(noisy, n, &noise_summary);
    SmoothSummary summary;
    const double cpu_start = CpuSeconds();
    const Mesh result = Smooth(input, options, &summary);
    const double cpu = CpuSeconds() - cpu_start;
    const double mae = MeanAngularErrorDeg(result, gt);
    auto fmt = [](double v) {
      char b[32];
      std::snprintf(b, sizeof b, std::isnan(v) ? "–" : "%.2f", v);
      return std::string(b);
    };
    std::printf("| %s | %.2f | %.3f | %.2f | %s | %s | %s | %d | %d | %.6e | %.2f | %.2f |\n", c.name.c_str(), c.k,
                noise_summary.noise_edge_multiple, mae, fmt(c.reference).c_str(), fmt(c.target).c_str(),
                c.anchor.c_str(), summary.iterations, summary.evaluations,
                summary.data_energy + summary.prior_energy, summary.time_s, cpu);
    std::fflush(stdout);
  }
  return 0;
}

int Estimate(std::map<std::string, std::string>& flags) {
  const std::string data = flags.count("--data") ? flags["--data"] : "../shared/data/meshes";
  std::printf("| noisy file | true k (RMS / GT l_e) | true k (RMS / noisy l_e) | estimate (of the latter) | error |\n|---|---|---|---|---|\n");
  for (const Case& c : Cases()) {
    const Mesh gt = ReadMesh(Join(data, c.gt));
    const Mesh noisy = ReadMesh(Join(data, c.noisy));
    const double rms = std::sqrt((noisy.V - gt.V).rowwise().squaredNorm().mean());
    const double k_true = rms / MeanEdgeLength(gt);
    const double k_noisy = rms / MeanEdgeLength(noisy);
    const double k = EstimateNoiseLevel(noisy);
    std::printf("| %s | %.3f | %.3f | %.3f | %+.0f%% |\n", c.noisy.c_str(), k_true, k_noisy, k, 100 * (k / k_noisy - 1));
  }
  return 0;
}

// A closed torus of about `faces` triangles (2·nu·nv, nu = 2·nv) with seeded Gaussian noise of 0.3 l_e.
Mesh NoisyTorus(int faces) {
  const int nv = std::max(3, static_cast<int>(std::sqrt(faces / 4.0)));
  const int nu = 2 * nv;
  Mesh mesh;
  mesh.V.resize(static_cast<Eigen::Index>(nu) * nv, 3);
  mesh.F.resize(2 * static_cast<Eigen::Index>(nu) * nv, 3);
  const double R = 1.0, r = 0.4;
  for (int i = 0; i < nu; ++i) {
    for (int j = 0; j < nv; ++j) {
      const double u = 2 * M_PI * i / nu, v = 2 * M_PI * j / nv;
      mesh.V.row(i * nv + j) << (R + r * std::cos(v)) * std::cos(u), (R + r * std::cos(v)) * std::sin(u), r * std::sin(v);
      const int a = i * nv + j, b = ((i + 1) % nu) * nv + j, c = ((i + 1) % nu) * nv + (j + 1) % nv,
                d = i * nv + (j + 1) % nv;
      mesh.F.row(2 * a) << a, b, c;
      mesh.F.row(2 * a + 1) << a, c, d;
    }
  }
  const double edge = MeanEdgeLength(mesh);
  std::mt19937 rng(1);
  std::normal_distribution<double> gauss(0.0, 0.3 * edge / std::sqrt(3.0));
  for (Eigen::Index i = 0; i < mesh.V.size(); ++i) mesh.V.data()[i] += gauss(rng);
  return mesh;
}

int Speed(std::map<std::string, std::string>& flags, const std::vector<std::string>& positional) {
  if (positional.empty() && !flags.count("--synthetic-faces")) {
    std::fprintf(stderr, "usage: bench_smooth speed MESH|--synthetic-faces N [--threads N] ...\n");
    return 2;
  }
  const std::string name = positional.empty() ? "torus " + flags["--synthetic-faces"] : positional[0];
  const Mesh mesh = positional.empty() ? NoisyTorus(std::stoi(flags["--synthetic-faces"])) : ReadMesh(positional[0]);
  const double rss_mesh = PeakRssMiB();
  SmoothOptions options = OptionsFromFlags(flags);
  GenericNoiseOptions noise;
  noise.noise_edge_multiple = flags.count("--noise") ? std::stod(flags["--noise"]) : 0.3;
  const int repeat = flags.count("--repeat") ? std::stoi(flags["--repeat"]) : 1;
  // --file-covariance: the PLY's own per-vertex covariances (stereo meshes), not the generic noise model.
  const NoisyMesh input = flags.count("--file-covariance") ? ReadNoisyMesh(positional.at(0)) : MakeGenericNoisyMesh(mesh, noise);
  const double rss_input = PeakRssMiB();
  for (int r = 0; r < repeat; ++r) {
    SmoothSummary summary;
    const double cpu_start = CpuSeconds();
    const Mesh result = Smooth(input, options, &summary);
    const double cpu = CpuSeconds() - cpu_start;
    const double iteration_time = (summary.time_s - summary.setup_time_s) / std::max(1, summary.iterations);
    const double evaluation_time = (summary.time_s - summary.setup_time_s) / std::max(1, summary.evaluations);
    if (flags.count("--gt")) {
      std::printf("MAE %.3f deg vs %s | ", MeanAngularErrorDeg(result, ReadMesh(flags["--gt"])), flags["--gt"].c_str());
    }
    std::printf("final energy %.6e (data %.4e prior %.4e) | ", summary.data_energy + summary.prior_energy,
                summary.data_energy, summary.prior_energy);
    std::printf(
        "%s: V=%d F=%d threads=%d kernels=%s tolerance=%s | total %.3f s (CPU %.3f s), setup %.3f s, %d iterations, %d "
        "evaluations, %.2f ms/iteration, %.2f ms/evaluation, %.1f ns/face/iteration, %.1f ns/face/evaluation | "
        "termination: %s, remaining %.3g (%.3g of E), levels %d, coarse work %.1f | "
        "solver memory %.1f B/vertex | peak RSS %.0f MiB (after loading %.0f, with covariances %.0f)\n",
        name.c_str(), mesh.num_vertices(), mesh.num_faces(), summary.num_threads, SmoothingKernelName(),
        SmoothToleranceName(options.tolerance).c_str(), summary.time_s,
        cpu, summary.setup_time_s, summary.iterations, summary.evaluations, 1e3 * iteration_time, 1e3 * evaluation_time,
        1e9 * iteration_time / std::max(1, mesh.num_faces()), 1e9 * evaluation_time / std::max(1, mesh.num_faces()), SmoothTerminationName(summary.termination).c_str(),
        summary.remaining_decrease,
        summary.remaining_decrease / std::max(1e-300, summary.data_energy + summary.prior_energy),
        summary.levels, summary.coarse_work,
        static_cast<double>(summary.memory_bytes) / std::max(1, mesh.num_vertices()), PeakRssMiB(), rss_mesh,
        rss_input);
    std::fflush(stdout);
  }
  return 0;
}

int Profile(std::map<std::string, std::string>& flags, const std::vector<std::string>& meshes) {
  const int rings = flags.count("--rings") ? std::stoi(flags["--rings"]) : 8;
  for (const std::string& path : meshes) {
    const Mesh mesh = ReadMesh(path);
    NoiseEstimateDetails details;
    const double estimate = EstimateNoiseLevel(mesh, &details);
    std::printf("{\"mesh\": \"%s\", \"estimate\": %.4f, \"profile\": [", path.c_str(), estimate);
    const std::vector<double> profile = NoiseResidualProfile(mesh, rings);
    for (size_t r = 0; r < profile.size(); ++r) std::printf("%s%.4f", r ? ", " : "", profile[r]);
    std::printf("], \"tail\": %.3f}\n", details.tail);
    std::fflush(stdout);
  }
  return 0;
}

int RunBench(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_smooth quality|speed|estimate ...\n");
    return 2;
  }
  std::vector<std::string> positional;
  auto flags = ParseFlags(argc, argv, 2, &positional);
  const std::string mode = argv[1];
  if (mode == "quality") return Quality(flags);
  if (mode == "estimate") return Estimate(flags);
  if (mode == "speed") return Speed(flags, positional);
  if (mode == "profile") return Profile(flags, positional);
  std::fprintf(stderr, "bench_smooth: unknown mode %s\n", mode.c_str());
  return 2;
}

}  // namespace

int main(int argc, char** argv) { return rangebayes::bench::Main("bench_smooth", RunBench, argc, argv); }
