// Learned-prior benchmark: trains φ_θ on synthetic right-angled meshes and compares it with the square root on
// the held-out synthetic set and on real benchmark meshes (BENCHMARKS.md "Learned priors"). Without flags it
// trains with LearnPriorOptions{} (what `rangebayes learn-prior` runs).
//
//   learn_prior_bench [--method none|interleaved] [--k 0.3] [--k-max K] [--train 8] [--test 4] [--seed 1]
//                     [--copies 1] [--min-cells 6] [--max-cells 14]
//                     [--iterations N] [--time-limit S] [--knots 16] [--w 1] [--step A] [--theta-out FILE]
//                     [--tolerance fast|default|tight]
//                     [--bump-sweeps 30] [--bump-step 0.2] [--bump-min-step 0.005] [--bump-width 0.1]
//                     [--bump-centres c1,c2,...] [--validation 0] [--no-test]
//                     [--init-theta FILE [--set-knot J VALUE]... [--eval-only]] [--no-train-eval]
//                     [--mesh NOISY GT K]...
//
// Prints the training curve (time, loss) and a table of MAE (degrees) and D (mean squared vertex error / l_e²).
#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "bayes/learning/learn_prior.h"
#include "bayes/learning/synth_meshes.h"
#include "bayes/noise_model.h"
#include "core/mesh_io.h"
#include "core/topology.h"

using namespace rangebayes;

namespace {

TrainingPair MakePair(const std::string& name, const Mesh& noisy, const Mesh& truth, double k) {
  TrainingPair pair;
  pair.name = name;
  GenericNoiseOptions noise;
  noise.noise_edge_multiple = k;
  pair.noisy = MakeGenericNoisyMesh(noisy, noise);
  pair.truth = truth;
  return pair;
}

void Compare(const char* label, const std::vector<TrainingPair>& pairs, const SplinePotential& learned,
             const LearnPriorOptions& options) {
  const SqrtPotential sqrt_potential(options.spline.epsilon_squared);
  const auto start = std::chrono::steady_clock::now();
  const PriorEvaluation base = EvaluatePrior(pairs, sqrt_potential, options, KeepMeshes::kYes);
  const PriorEvaluation mine = EvaluatePrior(pairs, learned, options, KeepMeshes::kYes);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%-10s sqrt: MAE %.3f deg D %.5f | learned: MAE %.3f deg D %.5f | MAE change %+.1f%% (%.1f s)\n", label,
              base.mean_angular_error_deg, base.mean_squared_error_le2, mine.mean_angular_error_deg,
              mine.mean_squared_error_le2, 100.0 * (mine.mean_angular_error_deg / base.mean_angular_error_deg - 1.0),
              seconds);
  // The squared vertex error split into crease vertices (of an edge turning by d > 0.5 in the truth) and the
  // rest, each the mean over all vertices of the set in units of l_e².
  double crease_error[2] = {0, 0}, other_error[2] = {0, 0};
  long long crease_count = 0, other_count = 0;
  for (size_t p = 0; p < pairs.size(); ++p) {
    const std::vector<bool> crease = CreaseVertices(pairs[p].truth, 0.5);
    const double le2 = std::pow(MeanEdgeLength(pairs[p].truth), 2);
    for (int i = 0; i < pairs[p].truth.num_vertices(); ++i) {
      const double e0 = (base.smoothed[p].V.row(i) - pairs[p].truth.V.row(i)).squaredNorm() / le2;
      const double e1 = (mine.smoothed[p].V.row(i) - pairs[p].truth.V.row(i)).squaredNorm() / le2;
      (crease[i] ? crease_error : other_error)[0] += e0;
      (crease[i] ? crease_error : other_error)[1] += e1;
      ++(crease[i] ? crease_count : other_count);
    }
  }
  std::printf("    D split: crease vertices (%lld) sqrt %.5f learned %.5f | others (%lld) sqrt %.5f learned %.5f\n",
              crease_count, crease_error[0] / std::max(1LL, crease_count),
              crease_error[1] / std::max(1LL, crease_count), other_count, other_error[0] / std::max(1LL, other_count),
              other_error[1] / std::max(1LL, other_count));
  for (size_t p = 0; p < pairs.size(); ++p) {
    std::printf("    %-28s sqrt %.3f  learned %.3f\n", pairs[p].name.c_str(), base.pair_mae_deg[p],
                mine.pair_mae_deg[p]);
  }
}

Eigen::Vector3d FaceNormal(const Mesh& m, int f) {
  const Eigen::Vector3d a = m.V.row(m.F(f, 0));
  return (Eigen::Vector3d(m.V.row(m.F(f, 1))) - a).cross(Eigen::Vector3d(m.V.row(m.F(f, 2))) - a).normalized();
}

// How many face pairs the potential acts on per knot interval: d = ‖n_s − n_t‖ at `meshes` (the square-root
// smoothing results), and among them the pairs that meet at a right angle in the ground truth (d = √2 there).
void PrintPairHistogram(const std::vector<TrainingPair>& pairs, const std::vector<Mesh>& meshes, int num_knots) {
  const double spacing = 2.0 / (num_knots - 1);
  std::vector<long long> noisy_count(num_knots - 1, 0), right_angle_noisy(num_knots - 1, 0);
  long long total = 0, right_angles = 0;
  for (size_t p = 0; p < pairs.size(); ++p) {
    const TrainingPair& pair = pairs[p];
    const IndexPairs face_pairs = ComputeFacePairs(pair.truth);
    for (int k = 0; k < face_pairs.rows(); ++k) {
      const int s = face_pairs(k, 0), t = face_pairs(k, 1);
      const double d_truth = (FaceNormal(pair.truth, s) - FaceNormal(pair.truth, t)).norm();
      const double d = (FaceNormal(meshes[p], s) - FaceNormal(meshes[p], t)).norm();
      if (!std::isfinite(d)) continue;
      const int bin = std::min(num_knots - 2, static_cast<int>(d / spacing));
      ++noisy_count[bin];
      ++total;
      if (std::abs(d_truth - std::sqrt(2.0)) < 1e-6) {
        ++right_angles;
        ++right_angle_noisy[bin];
      }
    }
  }
  std::printf(
      "face pairs: %lld, %lld (%.2f%%) at right angles in the truth; d after square-root smoothing per knot interval "
      "[t_j, t_j+1): all (right-angle ones)\n  ",
      total, right_angles, 100.0 * right_angles / std::max<long long>(1, total));
  for (int j = 0; j + 1 < num_knots; ++j) {
    std::printf(" %.2f:%lld(%lld)", j * spacing, noisy_count[j], right_angle_noisy[j]);
  }
  std::printf("\n");
}

}  // namespace

int main(int argc, char** argv) {
  LearnPriorOptions options;
  SynthMeshSetOptions synth;
  std::string theta_out, theta_in;
  bool train_eval = true, eval_only = false, test_eval = true;
  std::vector<std::pair<int, double>> set_knots;  // applied to the --init-theta values
  struct External {
    std::string noisy, truth;
    double k;
  };
  std::vector<External> externals;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "missing value for %s\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--method")
      options.method = ParseLearnMethod(next());
    else if (a == "--k")
      synth.noise.k = std::stod(next());
    else if (a == "--k-max")
      synth.noise_k_max = std::stod(next());
    else if (a == "--copies")
      synth.copies = std::stoi(next());
    else if (a == "--min-cells")
      synth.object.min_cells = std::stoi(next());
    else if (a == "--max-cells")
      synth.object.max_cells = std::stoi(next());
    else if (a == "--train")
      synth.num_train = std::stoi(next());
    else if (a == "--test")
      synth.num_test = std::stoi(next());
    else if (a == "--seed")
      synth.seed = std::stoull(next());
    else if (a == "--iterations")
      options.max_iterations = std::stoi(next());
    else if (a == "--time-limit")
      options.time_limit_s = std::stod(next());
    else if (a == "--knots")
      options.spline.num_knots = std::stoi(next());
    else if (a == "--w")
      options.regularizer_weight = std::stod(next());
    else if (a == "--step")
      options.interleaved_step = std::stod(next());
    else if (a == "--theta-out")
      theta_out = next();
    else if (a == "--init-theta")
      theta_in = next();
    else if (a == "--no-train-eval")
      train_eval = false;
    else if (a == "--bump-sweeps")
      options.bump_search_sweeps = std::stoi(next());
    else if (a == "--bump-step")
      options.bump_search_step = std::stod(next());
    else if (a == "--bump-min-step")
      options.bump_search_min_step = std::stod(next());
    else if (a == "--bump-width")
      options.bump_search_width_d = std::stod(next());
    else if (a == "--bump-centres") {
      options.bump_search_centres_d.clear();
      std::string list = next();
      for (size_t start = 0; start < list.size();) {
        const size_t end = std::min(list.find(',', start), list.size());
        options.bump_search_centres_d.push_back(std::stod(list.substr(start, end - start)));
        start = end + 1;
      }
    } else if (a == "--validation")
      synth.num_validation = std::stoi(next());
    else if (a == "--no-test")
      test_eval = false;
    else if (a == "--eval-only")
      eval_only = true;
    else if (a == "--set-knot") {
      const int j = std::stoi(next());
      set_knots.emplace_back(j, std::stod(next()));
    } else if (a == "--tolerance")
      options.tolerance = ParseSmoothTolerance(next());
    else if (a == "--mesh") {
      External e;
      e.noisy = next();
      e.truth = next();
      e.k = std::stod(next());
      externals.push_back(e);
    } else {
      std::fprintf(stderr, "unknown argument %s\n", a.c_str());
      return 2;
    }
  }
  const SynthMeshSet set = MakeSynthMeshSet(synth);
  std::vector<TrainingPair> train, test, validation;
  // Each pair smoothed with the generic model at its own noise level (a mixture when --k-max is given).
  for (const auto& p : set.train) train.push_back(MakePair(p.name, p.noisy.mesh, p.clean, p.k));
  for (const auto& p : set.test) test.push_back(MakePair(p.name, p.noisy.mesh, p.clean, p.k));
  for (const auto& p : set.validation) validation.push_back(MakePair(p.name, p.noisy.mesh, p.clean, p.k));
  int vertices = 0;
  for (const auto& p : train) vertices += p.truth.num_vertices();
  std::printf(
      "method %s, k %.2f..%.2f, %zu training pairs (%d vertices), %zu test pairs, N %d, w %g, step %g, %d bump "
      "sweeps\n",
      LearnMethodName(options.method).c_str(), synth.noise.k, std::max(synth.noise.k, synth.noise_k_max), train.size(),
      vertices, test.size(), options.spline.num_knots, options.regularizer_weight, options.interleaved_step,
      options.bump_search_sweeps);
  Eigen::VectorXd initial_theta;
  if (!theta_in.empty()) {
    std::ifstream in(theta_in);
    std::vector<double> values;
    for (double v; in >> v;) values.push_back(v);
    initial_theta = Eigen::Map<const Eigen::VectorXd>(values.data(), static_cast<Eigen::Index>(values.size()));
    std::printf("starting from %s (%zu knots)", theta_in.c_str(), values.size());
    for (const auto& [j, value] : set_knots) {
      if (j <= 0 || j + 1 >= initial_theta.size()) {
        std::fprintf(stderr, "--set-knot %d: only interior knots 1..N-2\n", j);
        return 2;
      }
      initial_theta[j] = value;
      std::printf(", theta_%d = %g", j, value);
    }
    std::printf("\n");
  }
  PrintPairHistogram(
      train, EvaluatePrior(train, SqrtPotential(options.spline.epsilon_squared), options, KeepMeshes::kYes).smoothed,
      options.spline.num_knots);
  options.progress = [](double, std::string_view stage) {
    std::fprintf(stderr, "  %.*s\n", static_cast<int>(stage.size()), stage.data());
  };
  if (eval_only && initial_theta.size() == 0) {
    std::fprintf(stderr, "--eval-only needs --init-theta\n");
    return 2;
  }
  LearnPriorSummary summary;
  const Eigen::VectorXd theta = eval_only ? initial_theta : LearnPrior(train, options, initial_theta, &summary);
  options.progress = nullptr;
  if (!eval_only) {
    std::printf(
        "training: D/vertex %.5f -> %.5f, %d iterations, %d smoothing runs, %.1f s, %s, D/vertex after the gradient "
        "method %.5f, %d bump-search moves\n",
        summary.initial_data_loss / summary.num_vertices, summary.final_data_loss / summary.num_vertices,
        summary.iterations, summary.smoothing_runs, summary.total_time_s, summary.termination.c_str(),
        summary.learned_data_loss / summary.num_vertices, summary.bump_search_moves);
    std::printf("curve (s, D/vertex):");
    for (size_t i = 0; i < summary.data_loss.size(); i += std::max<size_t>(1, summary.data_loss.size() / 20)) {
      std::printf(" %.0f:%.5f", summary.time_s[i], summary.data_loss[i] / summary.num_vertices);
    }
    std::printf("\n");
  }
  std::printf("theta:");
  for (int j = 0; j < theta.size(); ++j) std::printf(" %.4f", theta[j]);
  std::printf("\n");
  const SplinePotential learned(options.spline, theta);
  std::printf("phi - sqrt at d:");
  for (double d = 0.0; d <= 2.0001; d += 0.1) std::printf(" %.2f:%+.3f", d, learned.Value(d) - learned.Base(d));
  std::printf("\n");
  const SecondWell well = FindSecondWell(learned);
  std::printf(
      "second well (a strict local minimum d* of phi in [1.2, 1.6] below the max on [0.9, d*] and phi(1.8)): %s; d* "
      "%.3f "
      "phi %.4f, barrier d %.3f phi %.4f, phi(1.8) %.4f, depth %+.4f\n",
      well.found ? "FOUND" : "none", well.well_d, well.well_value, well.barrier_d, well.barrier_value, well.right_value,
      well.depth);
  if (!theta_out.empty()) {
    std::ofstream out(theta_out);
    out.precision(17);
    for (int j = 0; j < theta.size(); ++j) out << theta[j] << "\n";
  }
  if (train_eval) Compare("train", train, learned, options);
  if (!validation.empty()) Compare("validation", validation, learned, options);
  if (test_eval) Compare("test", test, learned, options);
  for (const External& e : externals) {
    const Mesh noisy = ReadMesh(e.noisy);
    const Mesh truth = ReadMesh(e.truth);
    Compare(e.noisy.substr(e.noisy.find_last_of('/') + 1).c_str(), {MakePair(e.noisy, noisy, truth, e.k)}, learned,
            options);
  }
  return 0;
}
