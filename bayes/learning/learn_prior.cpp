#include "bayes/learning/learn_prior.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "bayes/smoothing_energy.h"
#include "core/error.h"
#include "core/topology.h"

namespace rangebayes {
namespace {

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

Eigen::VectorXd Flatten(const Vertices& v) { return Eigen::Map<const Eigen::VectorXd>(v.data(), v.size()); }

// What the learner keeps per pair: the energy (bound to the shared, mutable spline), the truth flattened and
// the data-term normalisation 1 / l_e².
struct PairProblem {
  std::unique_ptr<SmoothingEnergy> energy;
  Eigen::VectorXd truth;
  double scale = 0;
};

Eigen::Vector3d TruthNormal(const Mesh& mesh, int f) {
  const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0));
  const Eigen::Vector3d c =
      (Eigen::Vector3d(mesh.V.row(mesh.F(f, 1))) - a).cross(Eigen::Vector3d(mesh.V.row(mesh.F(f, 2))) - a);
  const double length = c.norm();
  return length > 1e-300 ? (c / length).eval() : Eigen::Vector3d::Zero().eval();
}

std::vector<PairProblem> Prepare(const std::vector<TrainingPair>& pairs, const LearnPriorOptions& options,
                                 const Potential& potential) {
  std::vector<PairProblem> problems(pairs.size());
  for (size_t p = 0; p < pairs.size(); ++p) {
    const TrainingPair& pair = pairs[p];
    RB_CHECK(pair.noisy.has_covariance(), "learn prior: pair '", pair.name, "' has no per-vertex covariance");
    RB_CHECK(SameConnectivity(pair.truth, pair.noisy.mesh), "learn prior: pair '", pair.name,
             "': the ground truth and the noisy mesh differ in connectivity");
    std::vector<Eigen::Matrix3d> information(pair.noisy.covariance.size());
    for (size_t i = 0; i < information.size(); ++i)
      information[i] = InformationFromCovariance(pair.noisy.covariance[i]);
    problems[p].energy =
        std::make_unique<SmoothingEnergy>(pair.noisy.mesh, information, options.prior_weight, potential);
    problems[p].truth = Flatten(pair.truth.V);
    const double le = MeanEdgeLength(pair.truth);
    RB_CHECK(le > 0 && pair.truth.num_vertices() > 0, "learn prior: pair '", pair.name, "' has no edges");
    problems[p].scale = 1.0 / (le * le);
  }
  return problems;
}

SmoothOptions SmoothOptionsFor(const LearnPriorOptions& options, const Potential& potential) {
  SmoothOptions smooth;
  smooth.potential = &potential;
  smooth.prior_weight = options.prior_weight;
  smooth.tolerance = options.tolerance;
  smooth.num_threads = options.num_threads;
  return smooth;
}

double PairDataLoss(const PairProblem& problem, const Eigen::VectorXd& x) {
  return (x - problem.truth).squaredNorm() * problem.scale;
}

// One Polak–Ribière (PR+) CG step on E from x with the previous direction; line search by a secant on the
// directional derivative with an Armijo backtracking fallback (the energy never rises). The state of the
// interleaved scheme: the paper runs its learning inside the smoother's CG iterations.
struct CgState {
  Eigen::VectorXd x;
  Eigen::VectorXd gradient;  // at x, under the θ of the last step
  Eigen::VectorXd direction;
  double step = 0;
};

CgState CgStep(const SmoothingEnergy& energy, const CgState& state) {
  CgState next;
  Eigen::VectorXd g(state.x.size());
  const double e0 = energy.Evaluate(state.x, &g).total();
  Eigen::VectorXd p = -g;
  if (state.direction.size() == g.size() && state.gradient.size() == g.size()) {
    const double denominator = state.gradient.squaredNorm();
    const double beta = denominator > 0 ? std::max(0.0, g.dot(g - state.gradient) / denominator) : 0.0;
    p += beta * state.direction;
  }
  double slope = g.dot(p);
  if (!(slope < 0)) {
    p = -g;
    slope = -g.squaredNorm();
  }
  next.gradient = g;
  next.direction = p;
  next.x = state.x;
  if (!(slope < 0)) return next;
  double t = state.step > 0 ? state.step : -slope / std::max(energy.DataCurvature(p), 1e-300);
  Eigen::VectorXd g1(state.x.size());
  energy.Evaluate(state.x + t * p, &g1);
  const double slope1 = g1.dot(p);
  if (slope1 > slope) t = std::clamp(t * slope / (slope - slope1), 0.1 * t, 10.0 * t);
  for (int k = 0; k < 30; ++k) {
    const double e = energy.Evaluate(state.x + t * p, nullptr).total();
    if (e <= e0 + 1e-4 * t * slope) {
      next.x = state.x + t * p;
      next.step = t;
      return next;
    }
    t *= 0.5;
  }
  return next;
}

// options.progress called from within the solve of pair `pair` (stage "smoothing pair P of N", the caller's
// fraction): at the solve's first report and then at most every 0.1 s, so that a caller who ends the training
// from the callback (Python's Ctrl-C) is heard within a solver iteration rather than after the pair (13-17 s on
// a loaded machine). Empty when options.progress is.
ProgressCallback WithinSolve(const LearnPriorOptions& options, double fraction, size_t pair, size_t pairs) {
  if (!options.progress) return nullptr;
  const std::string stage = StrCat("smoothing pair ", pair + 1, " of ", pairs);
  auto last = std::make_shared<std::optional<std::chrono::steady_clock::time_point>>();
  return [progress = options.progress, fraction, stage, last](double, std::string_view) {
    const auto now = std::chrono::steady_clock::now();
    if (*last && now - **last < std::chrono::milliseconds(100)) return;
    *last = now;
    progress(fraction, stage);
  };
}

// Smooths every pair under the spline's current θ (a cold Smooth() from the measurements, as at run time);
// returns D. After each pair it reports (fraction, stage) to options.progress, so that a caller hears from within
// a bump sweep (one sweep smooths every pair 2·bumps + 4 times; Python's Ctrl-C waited for the whole sweep), and
// from within each solve (WithinSolve).
double SmoothAll(const std::vector<TrainingPair>& pairs, const std::vector<PairProblem>& problems,
                 const SplinePotential& spline, const LearnPriorOptions& options, double fraction = 0.0,
                 std::string_view stage = "smoothing the training pairs") {
  SmoothOptions smooth = SmoothOptionsFor(options, spline);
  double loss = 0;
  for (size_t p = 0; p < pairs.size(); ++p) {
    smooth.progress = WithinSolve(options, fraction, p, pairs.size());
    loss += PairDataLoss(problems[p], Flatten(Smooth(pairs[p].noisy, smooth).V));
    if (options.progress) options.progress(fraction, stage);
  }
  return loss;
}

struct Report {
  const LearnPriorOptions& options;
  LearnPriorSummary* summary;
  std::chrono::steady_clock::time_point start;
  int max_iterations;

  void Record(double data_loss, double loss) {
    summary->data_loss.push_back(data_loss);
    summary->loss.push_back(loss);
    summary->time_s.push_back(Seconds(start));
  }
  void Progress(int iteration, double data_loss, double loss) const {
    if (options.progress) {
      options.progress(std::min(1.0, static_cast<double>(iteration) / max_iterations),
                       StrCat("iteration ", iteration, ": loss ", loss, " (data ", data_loss, ")"));
    }
  }
  bool OutOfTime() const { return options.time_limit_s > 0 && Seconds(start) > options.time_limit_s; }
};

Eigen::VectorXd LearnInterleaved(const LearnPriorOptions& options, SplinePotential* spline,
                                 const std::vector<PairProblem>& problems, Report* report) {
  LearnPriorSummary* summary = report->summary;
  const size_t count = problems.size();
  std::vector<CgState> states(count);
  double data_loss = 0;
  for (size_t p = 0; p < count; ++p) {
    states[p].x = problems[p].energy->Measurements();
    data_loss += PairDataLoss(problems[p], states[p].x);
  }
  Eigen::VectorXd theta = spline->theta();
  const int num_knots = spline->num_knots();
  summary->termination = "max iterations";
  for (int iteration = 1; iteration <= report->max_iterations; ++iteration) {
    if (report->OutOfTime()) {
      summary->termination = "time limit";
      break;
    }
    // The unperturbed step (kept) and, from the same states, one step per perturbed θ_j (reverted).
    std::vector<CgState> next(count);
    double next_loss = 0;
    for (size_t p = 0; p < count; ++p) {
      next[p] = CgStep(*problems[p].energy, states[p]);
      next_loss += PairDataLoss(problems[p], next[p].x);
    }
    Eigen::VectorXd gradient = Eigen::VectorXd::Zero(num_knots);
    for (int j = 1; j + 1 < num_knots; ++j) {
      Eigen::VectorXd perturbed = theta;
      perturbed[j] += options.interleaved_epsilon;
      spline->SetTheta(perturbed);
      double perturbed_loss = 0;
      for (size_t p = 0; p < count; ++p) {
        perturbed_loss += PairDataLoss(problems[p], CgStep(*problems[p].energy, states[p]).x);
      }
      gradient[j] = (perturbed_loss - next_loss) / options.interleaved_epsilon;
    }
    Eigen::VectorXd regularizer_gradient;
    CurvatureRegularizer(theta, options.regularizer_weight, &regularizer_gradient);
    gradient += regularizer_gradient;
    gradient[0] = 0;
    gradient[num_knots - 1] = 0;
    theta -= options.interleaved_step * gradient;
    spline->SetTheta(theta);
    states = std::move(next);
    data_loss = next_loss;
    const double loss = data_loss + CurvatureRegularizer(theta, options.regularizer_weight);
    summary->iterations = iteration;
    report->Record(data_loss, loss);
    report->Progress(iteration, data_loss, loss);
  }
  return theta;
}

// LearnPriorOptions::bump_search_sweeps. Starts from the spline's θ; summary->final_data_loss must hold D there.
Eigen::VectorXd BumpSearch(const std::vector<TrainingPair>& pairs, const LearnPriorOptions& options,
                           SplinePotential* spline, const std::vector<PairProblem>& problems, Report* report) {
  LearnPriorSummary* summary = report->summary;
  Eigen::VectorXd theta = spline->theta();
  const Eigen::Index n = theta.size();
  const size_t count = options.bump_search_centres_d.size();
  std::vector<Eigen::VectorXd> bumps(count, Eigen::VectorXd::Zero(n));
  for (size_t c = 0; c < count; ++c) {
    const double sigma = options.bump_search_width_d;
    for (Eigen::Index j = 1; j + 1 < n; ++j) {
      const double offset = spline->KnotPosition(static_cast<int>(j)) - options.bump_search_centres_d[c];
      bumps[c][j] = std::exp(-offset * offset / (2 * sigma * sigma));
    }
  }
  double data_loss = summary->final_data_loss;
  double loss = data_loss + CurvatureRegularizer(theta, options.regularizer_weight);
  double h = options.bump_search_step;
  for (int sweep = 0; sweep < options.bump_search_sweeps && h >= options.bump_search_min_step && !report->OutOfTime();
       ++sweep) {
    Eigen::VectorXd gradient(static_cast<Eigen::Index>(count));
    Eigen::VectorXd best;
    double best_data = 0, best_loss = loss;
    // Smooths every pair at `candidate`, keeps it if it is the best so far; returns its L.
    int trial = 0;
    const int stencil_trials = static_cast<int>(2 * count);
    auto consider = [&](const Eigen::VectorXd& candidate) {
      spline->SetTheta(candidate);
      ++trial;
      const double candidate_data =
          SmoothAll(pairs, problems, *spline, options, std::min(1.0, static_cast<double>(trial) / stencil_trials),
                    StrCat("bump sweep ", sweep + 1, ": trial ", trial, " of ", stencil_trials, "+"));
      ++summary->smoothing_runs;
      const double candidate_loss = candidate_data + CurvatureRegularizer(candidate, options.regularizer_weight);
      if (candidate_loss < best_loss) {
        best = candidate;
        best_data = candidate_data;
        best_loss = candidate_loss;
      }
      return candidate_loss;
    };
    // The time limit is checked per trial: a stencil cut short keeps the best trial it measured (a lower L
    // measured is a lower L), with no line search on its partial gradient.
    bool cut = false;
    for (size_t c = 0; c < count && !cut; ++c) {
      const double plus = consider(theta + h * bumps[c]);
      const double minus = consider(theta - h * bumps[c]);
      gradient[static_cast<Eigen::Index>(c)] = (plus - minus) / (2 * h);
      cut = report->OutOfTime();
    }
    if (cut) {
      if (best.size() > 0) {
        theta = best;
        data_loss = best_data;
        loss = best_loss;
        ++summary->bump_search_moves;
      }
      report->Record(data_loss, loss);
      break;
    }
    const bool stencil_failure = best.size() == 0;
    const double largest = gradient.cwiseAbs().maxCoeff();
    if (!stencil_failure && largest > 0) {
      // Line search along −g, the largest bump moving by 2h first, then halving (down to h/4).
      Eigen::VectorXd direction = Eigen::VectorXd::Zero(n);
      for (size_t c = 0; c < count; ++c) direction -= gradient[static_cast<Eigen::Index>(c)] / largest * bumps[c];
      for (double t = 2 * h; t >= 0.25 * h - 1e-15 && !report->OutOfTime(); t *= 0.5) {
        const double before = best_loss;
        consider(theta + t * direction);
        if (best_loss < before && best_loss < loss) break;
      }
    }
    if (stencil_failure) {
      h *= 0.5;
    } else {
      theta = best;
      data_loss = best_data;
      loss = best_loss;
      ++summary->bump_search_moves;
    }
    spline->SetTheta(theta);
    report->Record(data_loss, loss);
    if (options.progress) {
      options.progress(1.0, StrCat("bump sweep ", sweep + 1, ": loss ", loss, " (data ", data_loss, "), stencil ", h));
    }
  }
  spline->SetTheta(theta);
  summary->final_data_loss = data_loss;
  return theta;
}

}  // namespace

std::vector<bool> CreaseVertices(const Mesh& truth, double min_d) {
  const IndexPairs face_pairs = ComputeFacePairs(truth);
  std::vector<bool> crease(truth.num_vertices(), false);
  for (int k = 0; k < face_pairs.rows(); ++k) {
    const int s = face_pairs(k, 0), t = face_pairs(k, 1);
    if ((TruthNormal(truth, s) - TruthNormal(truth, t)).norm() <= min_d) continue;
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) {
        if (truth.F(s, a) == truth.F(t, b)) crease[truth.F(s, a)] = true;
      }
    }
  }
  return crease;
}

LearnMethod ParseLearnMethod(const std::string& name) {
  if (name == "none") return LearnMethod::kNone;
  if (name == "interleaved") return LearnMethod::kInterleaved;
  RB_FAIL("unknown learning method '", name, "' (expected none or interleaved)");
}

std::string LearnMethodName(LearnMethod method) { return method == LearnMethod::kInterleaved ? "interleaved" : "none"; }

void LearnPriorOptions::Check() const {
  spline.Check();
  RB_CHECK(regularizer_weight >= 0 && regularizer_weight <= 1e6,
           "learn prior: regularizer weight must be in [0, 1e6], got ", regularizer_weight);
  RB_CHECK(prior_weight > 0 && prior_weight <= 1e6, "learn prior: prior weight must be in (0, 1e6], got ",
           prior_weight);
  RB_CHECK(max_iterations >= 0 && max_iterations <= 1000000, "learn prior: max_iterations must be in [0, 1e6], got ",
           max_iterations);
  RB_CHECK(time_limit_s >= 0, "learn prior: time limit must be ≥ 0, got ", time_limit_s);
  RB_CHECK(interleaved_step > 0 && interleaved_step <= 1e6, "learn prior: interleaved step must be in (0, 1e6], got ",
           interleaved_step);
  RB_CHECK(interleaved_epsilon > 0 && interleaved_epsilon <= 1,
           "learn prior: interleaved epsilon must be in (0, 1], got ", interleaved_epsilon);
  RB_CHECK(bump_search_sweeps >= 0 && bump_search_sweeps <= 1000,
           "learn prior: bump_search_sweeps must be in [0, 1000], got ", bump_search_sweeps);
  for (const double c : bump_search_centres_d) {
    RB_CHECK(c > 0 && c < 2, "learn prior: bump_search_centres_d must be in (0, 2), got ", c);
  }
  RB_CHECK(bump_search_width_d > 0 && bump_search_width_d <= 1,
           "learn prior: bump_search_width_d must be in (0, 1], got ", bump_search_width_d);
  RB_CHECK(bump_search_step > 0 && bump_search_step <= 1, "learn prior: bump_search_step must be in (0, 1], got ",
           bump_search_step);
  RB_CHECK(bump_search_min_step > 0 && bump_search_min_step <= bump_search_step,
           "learn prior: bump_search_min_step must be in (0, bump_search_step], got ", bump_search_min_step);
  RB_CHECK(num_threads >= 0 && num_threads <= 1024, "learn prior: num_threads must be in [0, 1024], got ", num_threads);
}

std::string LearnPriorSummary::BriefReport() const {
  const int vertices = std::max(1, num_vertices);
  char buffer[512];
  std::snprintf(buffer, sizeof(buffer),
                "learned %d knots by %s on %d pairs (%d vertices): mean squared vertex error %.5f -> %.5f l_e^2 "
                "(%+.1f%%), %d iterations, %.1f s (%s)",
                num_knots, method.c_str(), num_pairs, num_vertices, initial_data_loss / vertices,
                final_data_loss / vertices, 100.0 * (final_data_loss / initial_data_loss - 1.0), iterations,
                total_time_s, termination.c_str());
  return buffer;
}

double CurvatureRegularizer(const Eigen::VectorXd& theta, double weight, Eigen::VectorXd* gradient) {
  if (gradient != nullptr) gradient->setZero(theta.size());
  double value = 0;
  for (Eigen::Index j = 1; j + 1 < theta.size(); ++j) {
    const double c = theta[j - 1] - 2 * theta[j] + theta[j + 1];
    value += weight * c * c;
    if (gradient != nullptr) {
      (*gradient)[j - 1] += 2 * weight * c;
      (*gradient)[j] -= 4 * weight * c;
      (*gradient)[j + 1] += 2 * weight * c;
    }
  }
  return value;
}

PriorEvaluation EvaluatePrior(const std::vector<TrainingPair>& pairs, const Potential& potential,
                              const LearnPriorOptions& options, KeepMeshes keep_meshes) {
  options.Check();
  PriorEvaluation evaluation;
  SmoothOptions smooth = SmoothOptionsFor(options, potential);
  for (const TrainingPair& pair : pairs) {
    smooth.progress = WithinSolve(options, 0.0, evaluation.pair_mse_le2.size(), pairs.size());
    const Mesh result = Smooth(pair.noisy, smooth);
    const double le = MeanEdgeLength(pair.truth);
    const double loss = (result.V - pair.truth.V).squaredNorm() / (pair.truth.num_vertices() * le * le);
    evaluation.pair_mse_le2.push_back(loss);
    evaluation.pair_mae_deg.push_back(MeanAngularErrorDeg(result, pair.truth));
    if (keep_meshes == KeepMeshes::kYes) evaluation.smoothed.push_back(result);
  }
  const double count = std::max<size_t>(1, pairs.size());
  for (size_t p = 0; p < pairs.size(); ++p) {
    evaluation.mean_squared_error_le2 += evaluation.pair_mse_le2[p] / count;
    evaluation.mean_angular_error_deg += evaluation.pair_mae_deg[p] / count;
  }
  return evaluation;
}

Eigen::VectorXd LearnPrior(const std::vector<TrainingPair>& pairs, const LearnPriorOptions& options,
                           const Eigen::VectorXd& initial_theta, LearnPriorSummary* summary_out) {
  options.Check();
  RB_CHECK(!pairs.empty(), "learn prior: no training pairs");
  const auto start = std::chrono::steady_clock::now();
  SplinePotential spline(options.spline,
                         initial_theta.size() == 0 ? SplinePotential::SquareRootTheta(options.spline) : initial_theta);
  const std::vector<PairProblem> problems = Prepare(pairs, options, spline);
  LearnPriorSummary summary;
  summary.num_pairs = static_cast<int>(pairs.size());
  summary.num_knots = options.spline.num_knots;
  for (const TrainingPair& pair : pairs) summary.num_vertices += pair.truth.num_vertices();
  const int max_iterations = options.max_iterations > 0 ? options.max_iterations : 400;
  Report report{options, &summary, start, max_iterations};
  Eigen::VectorXd theta;
  summary.initial_data_loss = SmoothAll(pairs, problems, spline, options);
  if (options.method == LearnMethod::kNone) {
    summary.final_data_loss = summary.initial_data_loss;
    ++summary.smoothing_runs;
    summary.termination = "searches only";
    theta = spline.theta();
  } else {
    theta = LearnInterleaved(options, &spline, problems, &report);
    summary.final_data_loss = SmoothAll(pairs, problems, spline, options);
    summary.smoothing_runs += 2;
  }
  summary.learned_data_loss = summary.final_data_loss;
  summary.method = LearnMethodName(options.method);
  if (options.bump_search_sweeps > 0) {
    theta = BumpSearch(pairs, options, &spline, problems, &report);
    summary.method += StrCat(" + bump search (filtering, ", summary.bump_search_moves, " moves)");
    // Said, as the interleaved phase says it: "0 moves (searches only)" read as a search that found nothing.
    if (report.OutOfTime()) summary.termination += "; the time limit ended the bump search";
  }
  summary.total_time_s = Seconds(start);
  if (summary_out != nullptr) *summary_out = std::move(summary);
  return theta;
}

}  // namespace rangebayes
