// Supervised learning of the spline potential φ_θ from pairs (noisy z, ground truth y) (paper §5.2,
// docs/design.md §5 "Learned prior"):
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
// Two supported ways to learn θ:
// - the default (LearnPriorOptions{}, what `rangebayes learn-prior` runs): no gradient method; a bump search on
//   L, D from a cold Smooth() of every pair as at run time, over smooth Gaussian bumps of the knot values
//   centred at the knots 7–14 of 16 (Kelley's implicit filtering, see LearnPriorOptions::bump_search_sweeps).
//   It learns the paper's second well near d = √2 for right-angled objects.
// - LearnMethod::kInterleaved, the paper's scheme, kept as its reference: one nonlinear-CG step on every pair
//   per iteration, and beside it a forward finite-difference gradient of D in each free θ_j (one CG step from
//   the same state with θ_j + ε, then reverting), θ moved by a fixed step α (eq. 21–22). Eq. 21 as printed
//   subtracts the loss before the step; we subtract the loss after the unperturbed step, so that the step's own
//   progress is not counted as a gradient in every θ_j. Set bump_search_sweeps = 0 for the paper's scheme alone.
// How the default was chosen, and the alternatives measured and rejected: BENCHMARKS.md "Learned priors".
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

// The gradient method run before the bump search. kNone (the default): none, θ is learned by the bump search
// alone from the initial θ. kInterleaved: the paper's scheme (above).
enum class LearnMethod { kNone, kInterleaved };
LearnMethod ParseLearnMethod(const std::string& name);  // "none", "interleaved"; Error otherwise
std::string LearnMethodName(LearnMethod method);

struct LearnPriorOptions {
  LearnMethod method = LearnMethod::kNone;
  SplinePotentialOptions spline;                       // N knots, ε² of the square-root base
  double regularizer_weight = 1.0;                     // w of eq. 19; [0, 1e6]
  double prior_weight = SmoothOptions{}.prior_weight;  // β the smoother multiplies φ by (its default rule); (0, 1e6]
  SmoothTolerance tolerance = SmoothTolerance::kDefault;  // of every cold Smooth() of a pair
  int max_iterations = 0;                                 // interleaved: outer iterations; 0: 400; else [1, 1e6]
  double time_limit_s = 0;  // stop after this much wall time (checked per iteration and trial); 0: none; ≥ 0
  // Interleaved: fixed step α of eq. 22 and finite-difference increment ε of eq. 21.
  double interleaved_step = 0.01;     // (0, 1e6]
  double interleaved_epsilon = 1e-3;  // (0, 1]
  // After the method: implicit filtering on L over smooth bumps g_c(t_j) = exp(−(t_j − c)² / (2σ²)) of the knot
  // values, c in bump_search_centres_d (the free knots only), so that groups of neighbouring knots move together
  // and the curve stays smooth. Each sweep takes a central-difference gradient of L over the bump heights with
  // stencil size h (2 smoothings of every pair per bump), then a backtracking line search along its negative from
  // a step of 2h on the largest bump (halving down to h/4), keeping the best of the line search and the stencil
  // points; h halves on a stencil failure (no stencil point below L). The large stencil averages over the
  // roughness of L(θ) (the cold minimum jumps between nearby minima as θ moves), and the gradient direction
  // moves several bumps at once. h starts at bump_search_step; the search stops after bump_search_sweeps sweeps
  // or when h < bump_search_min_step. 0 sweeps: off. [0, 1000]
  int bump_search_sweeps = 30;
  // Bump centres in d, each in (0, 2); by default the knots 7–14 of 16 (d = 14/15 … 28/15), where the
  // right-angle face pairs and the paper's second well lie; below d ≈ 0.9 the square root is kept.
  std::vector<double> bump_search_centres_d = {14.0 / 15, 16.0 / 15, 18.0 / 15, 20.0 / 15,
                                               22.0 / 15, 24.0 / 15, 26.0 / 15, 28.0 / 15};
  double bump_search_width_d = 0.1;     // σ of the bumps in d; (0, 1]
  double bump_search_step = 0.2;        // initial stencil h in knot-value units; (0, 1]
  double bump_search_min_step = 0.005;  // stop when h is below this; (0, bump_search_step]
  int num_threads = 0;                  // smoother threads; 0: all cores
  ProgressCallback progress;            // stage names the iteration or sweep and the current loss
  void Check() const;
};

struct LearnPriorSummary {
  std::vector<double> loss;       // L after each outer iteration or sweep (on the training pairs)
  std::vector<double> data_loss;  // D after each outer iteration or sweep
  int num_pairs = 0;
  int num_knots = 0;
  int num_vertices = 0;          // training vertices (D / num_vertices: mean squared error in l_e²)
  std::vector<double> time_s;    // wall time at each entry
  double initial_data_loss = 0;  // D of the initial θ (the square root unless given)
  double final_data_loss = 0;    // D of the returned θ with full smoothing
  int iterations = 0;            // of the gradient method
  int smoothing_runs = 0;        // cold smoothings of every pair
  int bump_search_moves = 0;     // accepted bump-search sweeps
  double learned_data_loss = 0;  // D (cold smoothing) after the gradient method, before the bump search
  double total_time_s = 0;
  std::string termination;  // "max iterations", "time limit", "searches only"
  // What ran, as prior.yaml records it: "none + bump search (filtering, 6 moves)", "interleaved".
  std::string method;
  // One line: "learned 16 knots by <method> on 8 pairs (4182 vertices): mean squared vertex error A -> B l_e^2
  // (-35.2%), 0 iterations, 204.0 s (searches only)".
  std::string BriefReport() const;
};

// Learns θ from `pairs`, starting at `initial_theta` (empty: the square root). Returns N knot values.
Eigen::VectorXd LearnPrior(const std::vector<TrainingPair>& pairs, const LearnPriorOptions& options,
                           const Eigen::VectorXd& initial_theta = {}, LearnPriorSummary* summary = nullptr);

// The pieces, exposed for tests and benchmarks.

// The vertices of the crease edges of `truth`: edges whose two faces' unit normals differ by more than min_d.
// One flag per vertex.
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

enum class KeepMeshes { kNo, kYes };
// Smooths every pair under `potential` (β, tolerance and threads from options) and scores it.
PriorEvaluation EvaluatePrior(const std::vector<TrainingPair>& pairs, const Potential& potential,
                              const LearnPriorOptions& options, KeepMeshes keep_meshes = KeepMeshes::kNo);

}  // namespace rangebayes
