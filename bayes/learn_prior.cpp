#include "bayes/learn_prior.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>

#include "bayes/smoothing_energy.h"
#include "core/error.h"
#include "core/topology.h"

namespace rangebayes {
namespace {

double Seconds(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

Eigen::VectorXd Flatten(const Vertices& v) { return Eigen::Map<const Eigen::VectorXd>(v.data(), v.size()); }

// What the learner keeps per pair: the energy (bound to the shared, mutable spline), the truth flattened,
// the data-term normalisation 1 / l_e² and the face pairs the prior runs over.
struct PairProblem {
  std::unique_ptr<SmoothingEnergy> energy;
  Eigen::VectorXd truth;
  double scale = 0;
  double edge_length = 0;
  Eigen::VectorXd weight;  // per coordinate (3 per vertex); empty: all 1
  IndexPairs face_pairs;
};

Eigen::Vector3d TruthNormal(const Mesh& mesh, int f) {
  const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0));
  const Eigen::Vector3d c =
      (Eigen::Vector3d(mesh.V.row(mesh.F(f, 1))) - a).cross(Eigen::Vector3d(mesh.V.row(mesh.F(f, 2))) - a);
  const double length = c.norm();
  return length > 1e-300 ? (c / length).eval() : Eigen::Vector3d::Zero().eval();
}

// LearnPriorOptions::feature_vertex_weight: the vertices shared by face pairs across a crease of the truth.
Eigen::VectorXd FeatureWeights(const Mesh& truth, const LearnPriorOptions& options) {
  const std::vector<bool> feature = CreaseVertices(truth, options.feature_min_d);
  const long long count = std::count(feature.begin(), feature.end(), true);
  const double n = truth.num_vertices();
  const double mean = (n + (options.feature_vertex_weight - 1) * count) / n;
  Eigen::VectorXd weight(3 * truth.num_vertices());
  for (int i = 0; i < truth.num_vertices(); ++i) {
    weight.segment<3>(3 * i).setConstant((feature[i] ? options.feature_vertex_weight : 1.0) / mean);
  }
  return weight;
}

std::vector<PairProblem> Prepare(const std::vector<TrainingPair>& pairs, const LearnPriorOptions& options,
                                 const Potential& potential) {
  std::vector<PairProblem> problems(pairs.size());
  long long total_vertices = 0;
  for (const TrainingPair& pair : pairs) total_vertices += pair.truth.num_vertices();
  for (size_t p = 0; p < pairs.size(); ++p) {
    const TrainingPair& pair = pairs[p];
    RB_CHECK(pair.noisy.has_covariance(), "learn prior: pair '", pair.name, "' has no per-vertex covariance");
    RB_CHECK(pair.truth.num_vertices() == pair.noisy.mesh.num_vertices() && pair.truth.F == pair.noisy.mesh.F,
             "learn prior: pair '", pair.name, "': the ground truth and the noisy mesh differ in connectivity");
    std::vector<Eigen::Matrix3d> information(pair.noisy.covariance.size());
    for (size_t i = 0; i < information.size(); ++i)
      information[i] = InformationFromCovariance(pair.noisy.covariance[i]);
    problems[p].energy =
        std::make_unique<SmoothingEnergy>(pair.noisy.mesh, information, options.prior_weight, potential);
    problems[p].truth = Flatten(pair.truth.V);
    const double le = MeanEdgeLength(pair.truth);
    RB_CHECK(le > 0 && pair.truth.num_vertices() > 0, "learn prior: pair '", pair.name, "' has no edges");
    problems[p].scale = 1.0 / (le * le);
    problems[p].edge_length = le;
    if (options.loss_weighting == LossWeighting::kPerObject) {
      problems[p].scale *= static_cast<double>(total_vertices) / (pairs.size() * pair.truth.num_vertices());
    }
    problems[p].face_pairs = ComputeFacePairs(pair.truth);
    if (options.feature_vertex_weight != 1.0) {
      problems[p].weight = FeatureWeights(pair.truth, options);
    }
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
  if (problem.weight.size() == 0) return (x - problem.truth).squaredNorm() * problem.scale;
  return problem.weight.dot((x - problem.truth).cwiseAbs2()) * problem.scale;
}

// Unit normals and 1/|c_t| of every face at x (zero for degenerate faces).
void FaceFrames(const Faces& faces, const Eigen::VectorXd& x, std::vector<Eigen::Vector3d>* normal,
                std::vector<double>* inverse_length) {
  normal->resize(faces.rows());
  inverse_length->resize(faces.rows());
  for (int f = 0; f < faces.rows(); ++f) {
    const Eigen::Vector3d a = x.segment<3>(3 * faces(f, 0));
    const Eigen::Vector3d c = (x.segment<3>(3 * faces(f, 1)) - a).cross(x.segment<3>(3 * faces(f, 2)) - a);
    const double length = c.norm();
    if (length > 1e-300) {
      (*normal)[f] = c / length;
      (*inverse_length)[f] = 1.0 / length;
    } else {
      (*normal)[f].setZero();
      (*inverse_length)[f] = 0;
    }
  }
}

// J_j = vᵀ ∇ₓ Σ_(s,t) c_j(d_st) at x for every knot j: the directional derivative of each basis energy.
Eigen::VectorXd BasisDirectionalDerivatives(const PairProblem& problem, const Faces& faces, const Eigen::VectorXd& x,
                                            const Eigen::VectorXd& v, const SplinePotential& spline) {
  std::vector<Eigen::Vector3d> normal;
  std::vector<double> inverse_length;
  FaceFrames(faces, x, &normal, &inverse_length);
  std::vector<Eigen::Vector3d> normal_rate(faces.rows());
  for (int f = 0; f < faces.rows(); ++f) {
    const int a = faces(f, 0), b = faces(f, 1), c = faces(f, 2);
    const Eigen::Vector3d xa = x.segment<3>(3 * a);
    const Eigen::Vector3d va = v.segment<3>(3 * a);
    const Eigen::Vector3d c_rate = (v.segment<3>(3 * b) - va).cross(x.segment<3>(3 * c) - xa) +
                                   (x.segment<3>(3 * b) - xa).cross(v.segment<3>(3 * c) - va);
    const Eigen::Vector3d& n = normal[f];
    normal_rate[f] = (c_rate - n * n.dot(c_rate)) * inverse_length[f];
  }
  const int num_knots = spline.num_knots();
  Eigen::VectorXd result = Eigen::VectorXd::Zero(num_knots);
  for (int k = 0; k < problem.face_pairs.rows(); ++k) {
    const int s = problem.face_pairs(k, 0), t = problem.face_pairs(k, 1);
    if (inverse_length[s] == 0 || inverse_length[t] == 0) continue;
    const Eigen::Vector3d difference = normal[s] - normal[t];
    const double d = difference.norm();
    if (d < 1e-12) continue;  // every basis slope vanishes at d = 0 (clamped, symmetric in n_s − n_t)
    const double d_rate = difference.dot(normal_rate[s] - normal_rate[t]) / d;
    for (int j = 1; j + 1 < num_knots; ++j) {
      double slope = 0;
      spline.Basis(j, d, nullptr, &slope);
      result[j] += slope * d_rate;
    }
  }
  return result;
}

// Solves H v = b by CG, H v products by central differences of the energy gradient at x. Stops at the
// tolerance, the iteration limit, or on non-positive curvature (x slightly off the minimum).
Eigen::VectorXd SolveHessian(const SmoothingEnergy& energy, const Eigen::VectorXd& x, const Eigen::VectorXd& b,
                             double length_scale, int max_iterations, double tolerance) {
  Eigen::VectorXd gradient_plus(x.size()), gradient_minus(x.size());
  auto hessian_times = [&](const Eigen::VectorXd& p) {
    const double p_max = p.cwiseAbs().maxCoeff();
    if (!(p_max > 0)) return Eigen::VectorXd::Zero(p.size()).eval();
    // Small against the scale on which the square root bends (ε = 0.01 in d ~ displacement / l_e).
    const double h = 1e-5 * length_scale / p_max;
    energy.Evaluate(x + h * p, &gradient_plus);
    energy.Evaluate(x - h * p, &gradient_minus);
    return ((gradient_plus - gradient_minus) / (2 * h)).eval();
  };
  Eigen::VectorXd v = Eigen::VectorXd::Zero(b.size());
  Eigen::VectorXd r = b;
  Eigen::VectorXd p = r;
  double rr = r.squaredNorm();
  const double stop = tolerance * tolerance * rr;
  for (int it = 0; it < max_iterations && rr > stop; ++it) {
    const Eigen::VectorXd hp = hessian_times(p);
    const double curvature = p.dot(hp);
    if (!(curvature > 0)) break;
    const double alpha = rr / curvature;
    v += alpha * p;
    r -= alpha * hp;
    const double rr_new = r.squaredNorm();
    p = r + (rr_new / rr) * p;
    rr = rr_new;
  }
  return v;
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

// Minimises E from x (a nearby minimum: the warm start) by truncated Newton until ‖∇E‖ ≤ gradient_stop: each
// step solves H p = −∇E by CG (SolveHessian, forcing term min(0.5, sqrt(‖∇E‖ / ‖∇E(x0)‖))), then an Armijo
// backtracking line search from t = 1. Near a minimum this converges quadratically, where nonlinear CG on
// this ill-conditioned energy (φ'' ~ 1/ε at d ≈ 0) crawls and stops short of a tight tolerance (measured: a
// second warm solve from its own "minimum" still moved D by 3e-5 relative). Returns the Newton steps taken.
int MinimiseFrom(const SmoothingEnergy& energy, double gradient_stop, int max_iterations, double length_scale,
                 int hessian_cg_iterations, Eigen::VectorXd* x) {
  Eigen::VectorXd g(x->size());
  double e0 = energy.Evaluate(*x, &g).total();
  const double g_start = g.norm();
  int iteration = 0;
  for (; iteration < max_iterations && g.norm() > gradient_stop; ++iteration) {
    const double forcing = std::min(0.5, std::sqrt(g.norm() / std::max(g_start, 1e-300)));
    Eigen::VectorXd p = SolveHessian(energy, *x, -g, length_scale, hessian_cg_iterations, forcing);
    double slope = g.dot(p);
    if (!(slope < 0)) {
      p = -g / std::max(energy.DataCurvature(g) / g.squaredNorm(), 1e-300);
      slope = g.dot(p);
    }
    bool moved = false;
    double t = 1.0;
    for (int k = 0; k < 40; ++k, t *= 0.5) {
      const Eigen::VectorXd candidate = *x + t * p;
      Eigen::VectorXd candidate_gradient(x->size());
      const double e = energy.Evaluate(candidate, &candidate_gradient).total();
      if (e <= e0 + 1e-4 * t * slope) {
        *x = candidate;
        g = std::move(candidate_gradient);
        e0 = e;
        moved = true;
        break;
      }
    }
    if (!moved) break;  // at the minimum to rounding
  }
  return iteration;
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
  if (name == "interleaved") return LearnMethod::kInterleaved;
  if (name == "implicit") return LearnMethod::kImplicit;
  if (name == "none") return LearnMethod::kNone;
  RB_FAIL("unknown learning method '", name, "' (expected interleaved, implicit or none)");
}

std::string LearnMethodName(LearnMethod method) {
  switch (method) {
    case LearnMethod::kInterleaved:
      return "interleaved";
    case LearnMethod::kImplicit:
      return "implicit";
    case LearnMethod::kNone:
      break;
  }
  return "none";
}

KnotStepScaling ParseKnotStepScaling(const std::string& name) {
  if (name == "fixed") return KnotStepScaling::kFixed;
  if (name == "rms") return KnotStepScaling::kRms;
  RB_FAIL("unknown knot step scaling '", name, "' (expected fixed or rms)");
}

std::string KnotStepScalingName(KnotStepScaling scaling) {
  return scaling == KnotStepScaling::kFixed ? "fixed" : "rms";
}

BumpSearchMethod ParseBumpSearchMethod(const std::string& name) {
  if (name == "coordinate") return BumpSearchMethod::kCoordinate;
  if (name == "filtering") return BumpSearchMethod::kImplicitFiltering;
  RB_FAIL("unknown bump search method '", name, "' (expected coordinate or filtering)");
}

std::string BumpSearchMethodName(BumpSearchMethod method) {
  return method == BumpSearchMethod::kCoordinate ? "coordinate" : "filtering";
}

LossWeighting ParseLossWeighting(const std::string& name) {
  if (name == "vertex") return LossWeighting::kPerVertex;
  if (name == "object") return LossWeighting::kPerObject;
  RB_FAIL("unknown loss weighting '", name, "' (expected vertex or object)");
}

std::string LossWeightingName(LossWeighting weighting) {
  return weighting == LossWeighting::kPerVertex ? "vertex" : "object";
}

void LearnPriorOptions::Check() const {
  spline.Check();
  RB_CHECK(regularizer_weight >= 0 && regularizer_weight <= 1e6,
           "learn prior: regularizer weight must be in [0, 1e6], got ", regularizer_weight);
  RB_CHECK(prior_weight > 0 && prior_weight <= 1e6, "learn prior: prior weight must be in (0, 1e6], got ",
           prior_weight);
  RB_CHECK(max_iterations >= 0 && max_iterations <= 1000000, "learn prior: max_iterations must be in [0, 1e6], got ",
           max_iterations);
  RB_CHECK(time_limit_s >= 0, "learn prior: time limit must be ≥ 0, got ", time_limit_s);
  RB_CHECK(initial_step > 0 && initial_step <= 1, "learn prior: initial step must be in (0, 1], got ", initial_step);
  RB_CHECK(warm_gradient_tolerance > 0 && warm_gradient_tolerance < 1,
           "learn prior: warm_gradient_tolerance must be in (0, 1), got ", warm_gradient_tolerance);
  RB_CHECK(warm_max_iterations >= 1 && warm_max_iterations <= 1000000,
           "learn prior: warm_max_iterations must be in [1, 1e6], got ", warm_max_iterations);
  RB_CHECK(hessian_cg_iterations >= 1 && hessian_cg_iterations <= 100000,
           "learn prior: hessian_cg_iterations must be in [1, 1e5], got ", hessian_cg_iterations);
  RB_CHECK(hessian_cg_tolerance > 0 && hessian_cg_tolerance < 1,
           "learn prior: hessian_cg_tolerance must be in (0, 1), got ", hessian_cg_tolerance);
  RB_CHECK(interleaved_step > 0 && interleaved_step <= 1e6, "learn prior: interleaved step must be in (0, 1e6], got ",
           interleaved_step);
  RB_CHECK(interleaved_epsilon > 0 && interleaved_epsilon <= 1,
           "learn prior: interleaved epsilon must be in (0, 1], got ", interleaved_epsilon);
  RB_CHECK(interleaved_rms_decay >= 0 && interleaved_rms_decay < 1,
           "learn prior: interleaved_rms_decay must be in [0, 1), got ", interleaved_rms_decay);
  RB_CHECK(interleaved_step_decay_iterations >= 0 && interleaved_step_decay_iterations <= 1e9,
           "learn prior: interleaved_step_decay_iterations must be in [0, 1e9], got ",
           interleaved_step_decay_iterations);
  RB_CHECK(feature_vertex_weight >= 1 && feature_vertex_weight <= 1e6,
           "learn prior: feature_vertex_weight must be in [1, 1e6], got ", feature_vertex_weight);
  RB_CHECK(feature_min_d > 0 && feature_min_d < 2, "learn prior: feature_min_d must be in (0, 2), got ", feature_min_d);
  RB_CHECK(pattern_search_sweeps >= 0 && pattern_search_sweeps <= 1000,
           "learn prior: pattern_search_sweeps must be in [0, 1000], got ", pattern_search_sweeps);
  RB_CHECK(pattern_search_step > 0 && pattern_search_step <= 1,
           "learn prior: pattern_search_step must be in (0, 1], got ", pattern_search_step);
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
                              const LearnPriorOptions& options, bool keep_meshes) {
  options.Check();
  PriorEvaluation evaluation;
  const SmoothOptions smooth = SmoothOptionsFor(options, potential);
  for (const TrainingPair& pair : pairs) {
    const Mesh result = Smooth(pair.noisy, smooth);
    const double le = MeanEdgeLength(pair.truth);
    const double loss = (result.V - pair.truth.V).squaredNorm() / (pair.truth.num_vertices() * le * le);
    evaluation.pair_mse_le2.push_back(loss);
    evaluation.pair_mae_deg.push_back(MeanAngularErrorDeg(result, pair.truth));
    if (keep_meshes) evaluation.smoothed.push_back(result);
  }
  const double count = std::max<size_t>(1, pairs.size());
  for (size_t p = 0; p < pairs.size(); ++p) {
    evaluation.mean_squared_error_le2 += evaluation.pair_mse_le2[p] / count;
    evaluation.mean_angular_error_deg += evaluation.pair_mae_deg[p] / count;
  }
  return evaluation;
}

namespace {

// Smooths every pair under the spline's current θ; returns D and keeps the minima.
double SmoothAll(const std::vector<TrainingPair>& pairs, const std::vector<PairProblem>& problems,
                 const SplinePotential& spline, const LearnPriorOptions& options,
                 std::vector<Eigen::VectorXd>* minima) {
  const SmoothOptions smooth = SmoothOptionsFor(options, spline);
  minima->resize(pairs.size());
  double loss = 0;
  for (size_t p = 0; p < pairs.size(); ++p) {
    (*minima)[p] = Flatten(Smooth(pairs[p].noisy, smooth).V);
    loss += PairDataLoss(problems[p], (*minima)[p]);
  }
  return loss;
}

// Re-solves every pair under the spline's current θ from `from` (warm start, see LearnPriorOptions::warm_start)
// into `minima`; returns D.
double WarmSolveAll(const std::vector<PairProblem>& problems, const LearnPriorOptions& options,
                    const std::vector<double>& gradient_stop, const std::vector<Eigen::VectorXd>& from,
                    std::vector<Eigen::VectorXd>* minima, long long* iterations) {
  minima->resize(problems.size());
  double loss = 0;
  for (size_t p = 0; p < problems.size(); ++p) {
    (*minima)[p] = from[p];
    *iterations += MinimiseFrom(*problems[p].energy, gradient_stop[p], options.warm_max_iterations,
                                problems[p].edge_length, options.hessian_cg_iterations, &(*minima)[p]);
    loss += PairDataLoss(problems[p], (*minima)[p]);
  }
  return loss;
}

Eigen::VectorXd GradientAtMinima(const std::vector<TrainingPair>& pairs, const std::vector<PairProblem>& problems,
                                 const SplinePotential& spline, const LearnPriorOptions& options,
                                 const std::vector<Eigen::VectorXd>& minima) {
  Eigen::VectorXd gradient = Eigen::VectorXd::Zero(spline.num_knots());
  for (size_t p = 0; p < pairs.size(); ++p) {
    const PairProblem& problem = problems[p];
    Eigen::VectorXd b = 2.0 * problem.scale * (minima[p] - problem.truth);
    if (problem.weight.size() > 0) b = b.cwiseProduct(problem.weight);
    const double le = problem.edge_length;
    const Eigen::VectorXd v =
        SolveHessian(*problem.energy, minima[p], b, le, options.hessian_cg_iterations, options.hessian_cg_tolerance);
    gradient -=
        options.prior_weight * BasisDirectionalDerivatives(problem, pairs[p].noisy.mesh.F, minima[p], v, spline);
  }
  return gradient;
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

Eigen::VectorXd LearnImplicit(const std::vector<TrainingPair>& pairs, const LearnPriorOptions& options,
                              SplinePotential* spline, const std::vector<PairProblem>& problems, Report* report) {
  LearnPriorSummary* summary = report->summary;
  std::vector<Eigen::VectorXd> minima;
  Eigen::VectorXd theta = spline->theta();
  const Eigen::Index n = theta.size();
  double data_loss = SmoothAll(pairs, problems, *spline, options, &minima);
  ++summary->smoothing_runs;
  summary->initial_data_loss = data_loss;  // scored cold, as the smoother will be used
  // Warm starts: the first minima refined to the tight tolerance; every later solve starts from the last
  // accepted minima.
  std::vector<double> gradient_stop(problems.size());
  if (options.warm_start) {
    Eigen::VectorXd g;
    for (size_t p = 0; p < problems.size(); ++p) {
      problems[p].energy->Evaluate(problems[p].energy->Measurements(), &g);
      gradient_stop[p] = options.warm_gradient_tolerance * g.norm();
    }
    const std::vector<Eigen::VectorXd> cold = minima;
    data_loss = WarmSolveAll(problems, options, gradient_stop, cold, &minima, &summary->warm_iterations);
  }
  auto solve = [&](std::vector<Eigen::VectorXd>* out) {
    ++summary->smoothing_runs;
    return options.warm_start ? WarmSolveAll(problems, options, gradient_stop, minima, out, &summary->warm_iterations)
                              : SmoothAll(pairs, problems, *spline, options, out);
  };
  Eigen::VectorXd regularizer_gradient;
  double loss = data_loss + CurvatureRegularizer(theta, options.regularizer_weight, &regularizer_gradient);
  report->Record(data_loss, loss);
  auto full_gradient = [&]() {
    Eigen::VectorXd g = GradientAtMinima(pairs, problems, *spline, options, minima) + regularizer_gradient;
    g[0] = 0;
    g[n - 1] = 0;
    return g;
  };
  Eigen::VectorXd gradient = full_gradient();
  // L-BFGS over θ (the knots differ in how many normal pairs they see by orders of magnitude, so plain
  // gradient steps are badly scaled); the first step moves the largest knot by initial_step.
  std::vector<Eigen::VectorXd> s_history, y_history;
  summary->termination = "max iterations";
  int failures = 0;
  for (int iteration = 1; iteration <= report->max_iterations; ++iteration) {
    if (report->OutOfTime()) {
      summary->termination = "time limit";
      break;
    }
    Eigen::VectorXd q = gradient;
    const size_t m = s_history.size();
    std::vector<double> alpha(m);
    for (size_t k = m; k-- > 0;) {
      alpha[k] = s_history[k].dot(q) / y_history[k].dot(s_history[k]);
      q -= alpha[k] * y_history[k];
    }
    if (m > 0) {
      q *= s_history.back().dot(y_history.back()) / y_history.back().squaredNorm();
    } else {
      const double largest = q.cwiseAbs().maxCoeff();
      if (!(largest > 0)) {
        summary->termination = "converged";
        break;
      }
      q *= options.initial_step / largest;
    }
    for (size_t k = 0; k < m; ++k)
      q += s_history[k] * (alpha[k] - y_history[k].dot(q) / y_history[k].dot(s_history[k]));
    Eigen::VectorXd direction = -q;
    direction[0] = 0;
    direction[n - 1] = 0;
    double slope = gradient.dot(direction);
    if (!(slope < 0)) {
      s_history.clear();
      y_history.clear();
      direction = -gradient * (options.initial_step / std::max(gradient.cwiseAbs().maxCoeff(), 1e-300));
      slope = gradient.dot(direction);
    }
    // Backtracking on the true loss (every trial smooths every pair).
    bool accepted = false;
    double t = 1.0;
    for (int trial = 0; trial < 6 && !accepted; ++trial, t *= 0.3) {
      const Eigen::VectorXd candidate = theta + t * direction;
      spline->SetTheta(candidate);
      std::vector<Eigen::VectorXd> candidate_minima;
      const double candidate_data = solve(&candidate_minima);
      Eigen::VectorXd candidate_regularizer_gradient;
      const double candidate_loss =
          candidate_data + CurvatureRegularizer(candidate, options.regularizer_weight, &candidate_regularizer_gradient);
      if (candidate_loss <= loss + 1e-4 * t * slope) {
        accepted = true;
        minima = std::move(candidate_minima);
        regularizer_gradient = candidate_regularizer_gradient;
        const Eigen::VectorXd new_gradient = full_gradient();
        const Eigen::VectorXd s_step = candidate - theta;
        const Eigen::VectorXd y_step = new_gradient - gradient;
        if (s_step.dot(y_step) > 1e-12 * s_step.norm() * y_step.norm()) {
          s_history.push_back(s_step);
          y_history.push_back(y_step);
          if (s_history.size() > 6) {
            s_history.erase(s_history.begin());
            y_history.erase(y_history.begin());
          }
        }
        theta = candidate;
        gradient = new_gradient;
        data_loss = candidate_data;
        loss = candidate_loss;
      }
    }
    summary->iterations = iteration;
    if (!accepted) {
      spline->SetTheta(theta);
      s_history.clear();
      y_history.clear();
      // Twice in a row without progress even along the plain gradient: the loss is flat to the smoother's
      // tolerance here.
      if (++failures >= 2) {
        summary->termination = "no progress";
        report->Record(data_loss, loss);
        break;
      }
    } else {
      failures = 0;
    }
    report->Record(data_loss, loss);
    report->Progress(iteration, data_loss, loss);
  }
  spline->SetTheta(theta);
  // Scored as it will be used: a cold smoothing from the measurements (the warm minima may differ).
  summary->final_data_loss = options.warm_start ? SmoothAll(pairs, problems, *spline, options, &minima) : data_loss;
  ++summary->smoothing_runs;
  return theta;
}

Eigen::VectorXd LearnInterleaved(const std::vector<TrainingPair>& pairs, const LearnPriorOptions& options,
                                 SplinePotential* spline, const std::vector<PairProblem>& problems, Report* report) {
  LearnPriorSummary* summary = report->summary;
  const size_t count = pairs.size();
  std::vector<CgState> states(count);
  double data_loss = 0;
  for (size_t p = 0; p < count; ++p) {
    states[p].x = problems[p].energy->Measurements();
    data_loss += PairDataLoss(problems[p], states[p].x);
  }
  Eigen::VectorXd theta = spline->theta();
  const int num_knots = spline->num_knots();
  Eigen::VectorXd mean_square = Eigen::VectorXd::Zero(num_knots);  // kRms: running mean of g_j²
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
    const double tau = options.interleaved_step_decay_iterations;
    const double step = tau > 0 ? options.interleaved_step * tau / (tau + iteration - 1) : options.interleaved_step;
    if (options.interleaved_scaling == KnotStepScaling::kRms) {
      const double rho = options.interleaved_rms_decay;
      // Bias-corrected as in Adam, so that the first steps are not inflated by the zero start of v.
      mean_square = rho * mean_square + (1 - rho) * gradient.cwiseAbs2();
      const double correction = 1 - std::pow(rho, iteration);
      for (int j = 1; j + 1 < num_knots; ++j) {
        const double rms = std::sqrt(mean_square[j] / correction);
        if (rms > 0) theta[j] -= step * gradient[j] / rms;
      }
    } else {
      theta -= step * gradient;
    }
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

// LearnPriorOptions::pattern_search_sweeps. Starts from the spline's θ; summary->final_data_loss must hold D there.
Eigen::VectorXd PatternSearch(const std::vector<TrainingPair>& pairs, const LearnPriorOptions& options,
                              SplinePotential* spline, const std::vector<PairProblem>& problems, Report* report) {
  LearnPriorSummary* summary = report->summary;
  Eigen::VectorXd theta = spline->theta();
  std::vector<Eigen::VectorXd> minima;
  double data_loss = summary->final_data_loss;
  double loss = data_loss + CurvatureRegularizer(theta, options.regularizer_weight);
  double step = options.pattern_search_step;
  for (int sweep = 0; sweep < options.pattern_search_sweeps && !report->OutOfTime(); ++sweep) {
    bool moved = false;
    for (Eigen::Index j = 1; j + 1 < theta.size() && !report->OutOfTime(); ++j) {
      // Both directions, the better one kept (trying one first and stopping there biases the search).
      Eigen::VectorXd best;
      double best_data = 0, best_loss = loss;
      for (const double sign : {1.0, -1.0}) {
        Eigen::VectorXd candidate = theta;
        candidate[j] += sign * step;
        spline->SetTheta(candidate);
        const double candidate_data = SmoothAll(pairs, problems, *spline, options, &minima);
        ++summary->smoothing_runs;
        const double candidate_loss = candidate_data + CurvatureRegularizer(candidate, options.regularizer_weight);
        if (candidate_loss < best_loss) {
          best = candidate;
          best_data = candidate_data;
          best_loss = candidate_loss;
        }
      }
      if (best.size() > 0) {
        theta = best;
        data_loss = best_data;
        loss = best_loss;
        moved = true;
        ++summary->pattern_search_moves;
      }
      spline->SetTheta(theta);
    }
    report->Record(data_loss, loss);
    if (options.progress) {
      options.progress(1.0,
                       StrCat("pattern sweep ", sweep + 1, ": loss ", loss, " (data ", data_loss, "), step ", step));
    }
    if (!moved) step *= 0.5;
  }
  spline->SetTheta(theta);
  summary->final_data_loss = data_loss;
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
  std::vector<double> step(count, options.bump_search_step);
  std::vector<Eigen::VectorXd> minima;
  double data_loss = summary->final_data_loss;
  double loss = data_loss + CurvatureRegularizer(theta, options.regularizer_weight);
  auto try_theta = [&](const Eigen::VectorXd& candidate, double* candidate_data) {
    spline->SetTheta(candidate);
    *candidate_data = SmoothAll(pairs, problems, *spline, options, &minima);
    ++summary->smoothing_runs;
    return *candidate_data + CurvatureRegularizer(candidate, options.regularizer_weight);
  };
  if (options.bump_search_method == BumpSearchMethod::kImplicitFiltering) {
    double h = options.bump_search_step;
    for (int sweep = 0; sweep < options.bump_search_sweeps && h >= options.bump_search_min_step && !report->OutOfTime();
         ++sweep) {
      Eigen::VectorXd gradient(static_cast<Eigen::Index>(count));
      Eigen::VectorXd best;
      double best_data = 0, best_loss = loss;
      auto consider = [&](const Eigen::VectorXd& candidate) {
        double candidate_data = 0;
        const double candidate_loss = try_theta(candidate, &candidate_data);
        if (candidate_loss < best_loss) {
          best = candidate;
          best_data = candidate_data;
          best_loss = candidate_loss;
        }
        return candidate_loss;
      };
      for (size_t c = 0; c < count; ++c) {
        const double plus = consider(theta + h * bumps[c]);
        const double minus = consider(theta - h * bumps[c]);
        gradient[static_cast<Eigen::Index>(c)] = (plus - minus) / (2 * h);
      }
      const bool stencil_failure = best.size() == 0;
      const double largest = gradient.cwiseAbs().maxCoeff();
      if (!stencil_failure && largest > 0) {
        // Line search along −g, the largest bump moving by 2h first, then halving (down to h/4).
        Eigen::VectorXd direction = Eigen::VectorXd::Zero(n);
        for (size_t c = 0; c < count; ++c) direction -= gradient[static_cast<Eigen::Index>(c)] / largest * bumps[c];
        for (double t = 2 * h; t >= 0.25 * h - 1e-15; t *= 0.5) {
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
        options.progress(1.0,
                         StrCat("bump sweep ", sweep + 1, ": loss ", loss, " (data ", data_loss, "), stencil ", h));
      }
    }
    spline->SetTheta(theta);
    summary->final_data_loss = data_loss;
    return theta;
  }
  for (int sweep = 0; sweep < options.bump_search_sweeps && !report->OutOfTime(); ++sweep) {
    if (*std::max_element(step.begin(), step.end()) < options.bump_search_min_step) break;
    for (size_t c = 0; c < count && !report->OutOfTime(); ++c) {
      if (step[c] < options.bump_search_min_step) continue;
      // Both signs, the better kept; then, while accepted, a step 1.5 times longer in the same direction.
      double sign = 0, best_data = 0, best_loss = loss;
      Eigen::VectorXd best;
      for (const double s : {1.0, -1.0}) {
        const Eigen::VectorXd candidate = theta + s * step[c] * bumps[c];
        double candidate_data = 0;
        const double candidate_loss = try_theta(candidate, &candidate_data);
        if (candidate_loss < best_loss) {
          best = candidate;
          best_data = candidate_data;
          best_loss = candidate_loss;
          sign = s;
        }
      }
      if (best.size() == 0) {
        step[c] *= 0.5;
        continue;
      }
      while (best.size() > 0) {
        theta = best;
        data_loss = best_data;
        loss = best_loss;
        ++summary->bump_search_moves;
        step[c] = std::min(1.0, 1.5 * step[c]);
        best.resize(0);
        if (report->OutOfTime()) break;
        const Eigen::VectorXd candidate = theta + sign * step[c] * bumps[c];
        double candidate_data = 0;
        const double candidate_loss = try_theta(candidate, &candidate_data);
        if (candidate_loss < loss) {
          best = candidate;
          best_data = candidate_data;
          best_loss = candidate_loss;
        }
      }
    }
    spline->SetTheta(theta);
    report->Record(data_loss, loss);
    if (options.progress) {
      options.progress(1.0, StrCat("bump sweep ", sweep + 1, ": loss ", loss, " (data ", data_loss, "), largest step ",
                                   *std::max_element(step.begin(), step.end())));
    }
  }
  spline->SetTheta(theta);
  summary->final_data_loss = data_loss;
  return theta;
}

}  // namespace

double ImplicitDataGradient(const std::vector<TrainingPair>& pairs, const Eigen::VectorXd& theta,
                            const LearnPriorOptions& options, Eigen::VectorXd* gradient) {
  options.Check();
  SplinePotential spline(options.spline, theta);
  const std::vector<PairProblem> problems = Prepare(pairs, options, spline);
  std::vector<Eigen::VectorXd> minima;
  const double loss = SmoothAll(pairs, problems, spline, options, &minima);
  if (gradient != nullptr) *gradient = GradientAtMinima(pairs, problems, spline, options, minima);
  return loss;
}

double WarmDataGradient(const std::vector<TrainingPair>& pairs, const Eigen::VectorXd& theta,
                        const LearnPriorOptions& options, std::vector<Eigen::VectorXd>* minima,
                        Eigen::VectorXd* gradient) {
  options.Check();
  SplinePotential spline(options.spline, theta);
  const std::vector<PairProblem> problems = Prepare(pairs, options, spline);
  if (minima->size() != pairs.size()) SmoothAll(pairs, problems, spline, options, minima);
  std::vector<double> gradient_stop(problems.size());
  Eigen::VectorXd g;
  for (size_t p = 0; p < problems.size(); ++p) {
    problems[p].energy->Evaluate(problems[p].energy->Measurements(), &g);
    gradient_stop[p] = options.warm_gradient_tolerance * g.norm();
  }
  const std::vector<Eigen::VectorXd> from = *minima;
  long long iterations = 0;
  const double loss = WarmSolveAll(problems, options, gradient_stop, from, minima, &iterations);
  if (gradient != nullptr) *gradient = GradientAtMinima(pairs, problems, spline, options, *minima);
  return loss;
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
  for (const TrainingPair& pair : pairs) summary.num_vertices += pair.truth.num_vertices();
  const int max_iterations =
      options.max_iterations > 0 ? options.max_iterations : (options.method == LearnMethod::kImplicit ? 40 : 400);
  Report report{options, &summary, start, max_iterations};
  Eigen::VectorXd theta;
  if (options.method == LearnMethod::kImplicit) {
    theta = LearnImplicit(pairs, options, &spline, problems, &report);
  } else if (options.method == LearnMethod::kNone) {
    std::vector<Eigen::VectorXd> minima;
    summary.initial_data_loss = summary.final_data_loss = SmoothAll(pairs, problems, spline, options, &minima);
    ++summary.smoothing_runs;
    summary.termination = "searches only";
    theta = spline.theta();
  } else {
    std::vector<Eigen::VectorXd> minima;
    summary.initial_data_loss = SmoothAll(pairs, problems, spline, options, &minima);
    theta = LearnInterleaved(pairs, options, &spline, problems, &report);
    summary.final_data_loss = SmoothAll(pairs, problems, spline, options, &minima);
    summary.smoothing_runs += 2;
  }
  summary.learned_data_loss = summary.final_data_loss;
  if (options.bump_search_sweeps > 0) theta = BumpSearch(pairs, options, &spline, problems, &report);
  if (options.pattern_search_sweeps > 0) theta = PatternSearch(pairs, options, &spline, problems, &report);
  summary.total_time_s = Seconds(start);
  if (summary_out != nullptr) *summary_out = std::move(summary);
  return theta;
}

}  // namespace rangebayes
