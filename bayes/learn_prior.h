// Supervised learning of the spline potential φ_θ from pairs (noisy z, ground truth y) (paper §5.2, DESIGN §5):
//
//   θ* = argmin_θ  L(θ) = D(θ) + w Σ_j (θ_{j−1} − 2θ_j + θ_{j+1})²        (paper eqs. 18–20)
//   D(θ) = Σ_pairs Σ_i ‖x̂_i(z; θ) − y_i‖² / l_e²
//
// x̂(z; θ) is the smoothing result (bayes/smooth.h) under φ_θ. The data term is the paper's squared vertex
// error G (eq. 18) summed over all training vertices as the paper does, made unit-free by the squared mean
// edge length l_e of each ground truth so that meshes of any scale weigh alike. Being a sum (a log-likelihood),
// it grows with the training set while the regulariser (a log-prior on θ) does not: more data, less smoothing
// of θ. For reading, summaries also give D per vertex (the mean squared vertex error in units of l_e²; a noisy
// input of noise level k has about k²). The regulariser's sum runs over the knots with two neighbours.
//
// Two optimisers:
// - kInterleaved, the paper's scheme: one nonlinear-CG step on every pair per iteration, and beside it a
//   forward finite-difference gradient of D in each free θ_j (one CG step from the same state with θ_j + ε,
//   then reverting), θ moved by a fixed step α (eq. 21–22). Eq. 21 as printed subtracts the loss before the
//   step; we subtract the loss after the unperturbed step, so that the step's own progress is not counted as
//   a gradient in every θ_j.
// - kImplicit: the exact gradient of D at the minimum x̂ by implicit differentiation. At x̂, ∇ₓE(x̂, θ) = 0, so
//   dD/dθ_j = −vᵀ ∂²E/∂x∂θ_j with H v = ∂D/∂x (H the Hessian of E at x̂, solved by CG with Hessian-vector
//   products from central differences of the smoother's gradient); ∂²E/∂x∂θ_j = β ∇ₓ Σ_(s,t) c_j(d_st) with c_j
//   the spline's basis function for knot j (φ is linear in θ). θ then moves by L-BFGS with a backtracking
//   line search on the true loss (each trial smooths every pair). By default every solve after the first is
//   warm-started from the last accepted minima and refined by truncated Newton to a tight gradient, so that
//   the loss the line search measures is the one whose gradient was computed (BENCHMARKS.md: it then makes
//   progress where cold solves stalled, but far slower than the interleaved scheme).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "bayes/smooth.h"
#include "bayes/spline_potential.h"
#include "core/mesh.h"
#include "core/normal_error.h"
#include "core/progress.h"

namespace rangebayes {

// One training example: the noisy mesh (with covariances, e.g. from MakeGenericNoisyMesh) and its ground
// truth, same vertex order and faces.
struct TrainingPair {
  std::string name;
  NoisyMesh noisy;
  Mesh truth;
};

// kNone: no gradient method, only the searches below from the initial θ (to study them from a saved θ).
enum class LearnMethod { kInterleaved, kImplicit, kNone };
// Interleaved scheme, how each knot's step is scaled: kFixed the paper's θ_j −= α g_j; kRms a diagonal
// preconditioner θ_j −= α g_j / sqrt(v_j), v_j a running mean of g_j² (RMSprop), so that the sparsely populated
// knots (few face pairs at their d) move at the same rate as the crowded ones.
enum class KnotStepScaling { kFixed, kRms };
enum class BumpSearchMethod { kCoordinate, kImplicitFiltering };  // LearnPriorOptions::bump_search_method
BumpSearchMethod ParseBumpSearchMethod(const std::string& name);  // "coordinate", "filtering"; Error otherwise
std::string BumpSearchMethodName(BumpSearchMethod method);
KnotStepScaling ParseKnotStepScaling(const std::string& name);  // "fixed", "rms"; Error otherwise
std::string KnotStepScalingName(KnotStepScaling scaling);
// How the pairs' squared vertex errors are summed into D: kPerVertex (every training vertex alike, the paper's
// sum) or kPerObject (each pair's mean over its vertices, times the mean vertex count per pair so that D keeps
// its magnitude against w): small objects, which hold more edges and corners per vertex, weigh as much as big ones.
enum class LossWeighting { kPerVertex, kPerObject };
LossWeighting ParseLossWeighting(const std::string& name);  // "vertex", "object"; Error otherwise
std::string LossWeightingName(LossWeighting weighting);
LearnMethod ParseLearnMethod(const std::string& name);  // "interleaved", "implicit", "none"; Error otherwise
std::string LearnMethodName(LearnMethod method);

struct LearnPriorOptions {
  // The library's default; the learn-prior command's default is kNone with the bump search (30 sweeps), which
  // learns the paper's second well near √2 (BENCHMARKS.md "Learned priors").
  LearnMethod method = LearnMethod::kInterleaved;
  SplinePotentialOptions spline;                       // N knots, ε² of the square-root base
  double regularizer_weight = 1.0;                     // w of eq. 19; [0, 1e6]
  double prior_weight = SmoothOptions{}.prior_weight;  // β the smoother multiplies φ by (its default rule); (0, 1e6]
  SmoothTolerance tolerance = SmoothTolerance::kDefault;  // inner smoothing (implicit method)
  int max_iterations = 0;   // outer iterations; 0: 40 implicit, 400 interleaved; else [1, 1e6]
  double time_limit_s = 0;  // stop after this much wall time (checked per iteration); 0: none; ≥ 0
  // Implicit: the first step's largest θ_j change, in knot-value units; (0, 1].
  double initial_step = 0.02;
  // Implicit: re-solve every pair from its previous minimum (nonlinear CG to warm_gradient_tolerance) instead
  // of a cold Smooth() from the measurements, so that x̂(θ) follows one local minimum continuously and D(θ)
  // is the smooth function whose gradient implicit differentiation computes (a cold solve lands in one of
  // several nearby minima, and D jumps between them as θ moves).
  bool warm_start = true;
  // Warm solves are truncated Newton (H p = −∇E by CG with finite-difference Hessian products).
  double warm_gradient_tolerance = 1e-7;  // warm solves stop at ‖∇E‖ ≤ this × ‖∇E(z)‖ (at the start); (0, 1)
  int warm_max_iterations = 50;           // Newton steps per warm solve; [1, 1e6]
  int hessian_cg_iterations = 200;        // implicit: CG iterations for H v = ∂D/∂x per pair; [1, 1e5]
  double hessian_cg_tolerance = 1e-3;  // implicit: relative residual; (0, 1)
  // Interleaved: fixed step α of eq. 22 and finite-difference increment ε of eq. 21.
  double interleaved_step = 0.01;     // (0, 1e6]; measured on the synthetic set (BENCHMARKS.md)
  double interleaved_epsilon = 1e-3;  // (0, 1]
  // After either method: a pattern (coordinate) search on the true loss L = D + regulariser, D from a cold
  // Smooth() of every pair as at run time: each sweep tries θ_j ± δ for every free knot and keeps a move that
  // lowers L; δ halves after a sweep without any accepted move. No gradient, so it is not misled by the
  // interleaved scheme's one-CG-step gradient or by the roughness of D(θ). 0 sweeps: off. [0, 1000]
  int pattern_search_sweeps = 0;
  double pattern_search_step = 0.04;  // initial δ in knot-value units; (0, 1]
  // After either method (and before the knot pattern search): a search on the same cold-smoothing loss L along
  // smooth bumps g_c(t_j) = exp(−(t_j − c)² / (2σ²)) over the knot values, c in bump_search_centres_d (the free
  // knots only), so that groups of neighbouring knots move together and the curve stays smooth. Each bump has
  // its own step δ_c, adapted: a sweep tries θ ± δ_c g_c, keeps the better if it lowers L and then grows δ_c by
  // 1.5 (and tries again in the same direction while L keeps falling), else halves it; the search stops after
  // bump_search_sweeps sweeps or when every δ_c < bump_search_min_step. 0 sweeps: off. [0, 1000]
  int bump_search_sweeps = 0;
  // kCoordinate: the per-bump adaptive steps above. kImplicitFiltering (Kelley's implicit filtering): each sweep
  // takes a central-difference gradient of L over the bump heights with stencil size h (2 smoothings per bump),
  // then a backtracking line search along its negative from a step of 2h on the largest bump, keeping the best of
  // the line search and the stencil points; h halves on a stencil failure (no stencil point below L). The large
  // stencil averages over the roughness of L(θ) (the cold minimum jumps between nearby minima as θ moves),
  // and the gradient direction moves several bumps at once (a dip beside a rise) where one bump alone does not
  // lower L. h starts at bump_search_step and the search stops below bump_search_min_step.
  BumpSearchMethod bump_search_method = BumpSearchMethod::kImplicitFiltering;
  // Bump centres in d, each in (0, 2); by default the knots 7–14 of 16 (d = 14/15 … 28/15), where the
  // right-angle face pairs and the paper's second well lie; below d ≈ 0.9 the square root is kept (moving those
  // knots too made block 0.4 worse on training draws 1 and 2: BENCHMARKS.md).
  std::vector<double> bump_search_centres_d = {14.0 / 15, 16.0 / 15, 18.0 / 15, 20.0 / 15,
                                               22.0 / 15, 24.0 / 15, 26.0 / 15, 28.0 / 15};
  double bump_search_width_d = 0.1;     // σ of the bumps in d; (0, 1]
  double bump_search_step = 0.2;        // initial δ_c / stencil h in knot-value units (chosen on validation); (0, 1]
  double bump_search_min_step = 0.005;  // stop when every δ_c is below this; (0, bump_search_step]
  KnotStepScaling interleaved_scaling = KnotStepScaling::kFixed;  // the paper's fixed step by default
  double interleaved_rms_decay = 0.9;                             // kRms: v_j ← ρ v_j + (1 − ρ) g_j²; [0, 1)
  // Step schedule α_t = α · τ / (τ + t) at iteration t; 0: constant α. [0, 1e9]
  double interleaved_step_decay_iterations = 0;
  LossWeighting loss_weighting = LossWeighting::kPerVertex;
  // Per-vertex weights inside each pair's squared error: the vertices of the ground truth's crease edges (an
  // edge whose two faces' normals differ by more than feature_min_d, i.e. a dihedral turn above ~29° at 0.5)
  // count feature_vertex_weight times, the others once, and the weights are rescaled to a mean of 1 per pair
  // (D keeps its magnitude against w). 1: the plain sum of the issue. Flat vertices are ~90% of a right-angled
  // training set, so the plain sum is dominated by them. [1, 1e6]
  double feature_vertex_weight = 1.0;
  double feature_min_d = 0.5;  // (0, 2)
  int num_threads = 0;         // smoother threads; 0: all cores
  ProgressCallback progress;   // stage names the iteration and the current loss
  void Check() const;
};

struct LearnPriorSummary {
  std::vector<double> loss;       // L after each outer iteration (on the training pairs)
  std::vector<double> data_loss;  // D after each outer iteration
  int num_vertices = 0;           // training vertices (D / num_vertices: mean squared error in l_e²)
  std::vector<double> time_s;     // wall time at each entry
  double initial_data_loss = 0;   // D of the square-root potential (θ at the start)
  double final_data_loss = 0;     // D of the returned θ with full smoothing
  int iterations = 0;
  int smoothing_runs = 0;         // smoothing of every pair (cold or warm)
  long long warm_iterations = 0;  // implicit with warm starts: Newton steps over all warm solves
  int pattern_search_moves = 0;   // accepted pattern-search moves
  int bump_search_moves = 0;      // accepted bump-search moves
  double learned_data_loss = 0;   // D (cold smoothing) after the gradient method, before any search
  double total_time_s = 0;
  std::string termination;  // "max iterations", "time limit", "no progress", "converged", "searches only"
};

// Learns θ from `pairs`, starting at `initial_theta` (empty: the square root). Returns N knot values.
Eigen::VectorXd LearnPrior(const std::vector<TrainingPair>& pairs, const LearnPriorOptions& options,
                           const Eigen::VectorXd& initial_theta = {}, LearnPriorSummary* summary = nullptr);

// The pieces, exposed for tests and benchmarks.

// The vertices of the crease edges of `truth`: edges whose two faces' unit normals differ by more than min_d
// (LearnPriorOptions::feature_min_d). One flag per vertex.
std::vector<bool> CreaseVertices(const Mesh& truth, double min_d);

// w Σ_j (θ_{j−1} − 2θ_j + θ_{j+1})² and its gradient.
double CurvatureRegularizer(const Eigen::VectorXd& theta, double weight, Eigen::VectorXd* gradient = nullptr);

struct PriorEvaluation {
  double mean_squared_error_le2 = 0;  // mean over pairs of Σ_i ‖x̂_i − y_i‖² / (#V l_e²)
  double mean_angular_error_deg = 0;  // mean over pairs of the mean face-normal angle to the truth
  std::vector<double> pair_mse_le2;
  std::vector<double> pair_mae_deg;
  std::vector<Mesh> smoothed;  // only when requested
};

// Smooths every pair under `potential` (β, tolerance and threads from options) and scores it.
PriorEvaluation EvaluatePrior(const std::vector<TrainingPair>& pairs, const Potential& potential,
                              const LearnPriorOptions& options, bool keep_meshes = false);

// D at θ and dD/dθ by implicit differentiation (N entries, 0 at the fixed ends); smooths every pair.
double ImplicitDataGradient(const std::vector<TrainingPair>& pairs, const Eigen::VectorXd& theta,
                            const LearnPriorOptions& options, Eigen::VectorXd* gradient);

// The same with warm starts: every pair minimised from `minima` (in/out; empty: a cold Smooth() first) to
// options.warm_gradient_tolerance, so that D is continuous in θ along one branch of minima.
double WarmDataGradient(const std::vector<TrainingPair>& pairs, const Eigen::VectorXd& theta,
                        const LearnPriorOptions& options, std::vector<Eigen::VectorXd>* minima,
                        Eigen::VectorXd* gradient);

}  // namespace rangebayes
