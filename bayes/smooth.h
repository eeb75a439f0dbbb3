// Bayesian mesh smoothing: the MAP estimate of paper §3–4 (docs/design.md §3) by nonlinear conjugate gradient.
//
//   Mesh smoothed = Smooth(noisy_mesh, options, &summary);
//
// The energy is bayes/smoothing_energy.h with W_i = ½ Σ_i⁻¹ from the NoisyMesh covariances and the prior
// multiplied by β = SmoothOptions::prior_weight. For a mesh that did not come from our cameras, build the
// covariances with MakeGenericNoisyMesh (bayes/noise_model.h) first.
//
// The default rule (docs/design.md §3.2, measured in BENCHMARKS.md "Bayesian smoothing"): the data term carries all
// units (W = ½ Σ⁻¹; for a generic mesh Σ = σ² I with σ = k·l_e, so W scales with the mesh and its noise), the
// prior is unitless, and one constant β = 2.4 (square-root prior, ε² = 1e-4, each face pair counted once)
// balances them on every mesh. Why a constant works: at the MAP, a vertex moved by about σ costs O(1) in the
// data term whatever the scale, and the prior's cost of a normal deviation is scale-free too. β was chosen
// from a coarse scan (1.2, 1.7, 2.4, 3.4) over all benchmark meshes at once, not per mesh.
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "bayes/potential.h"
#include "core/mesh.h"
#include "core/progress.h"

namespace rangebayes {

// Stopping presets. default and tight stop on the estimated distance to the optimum (SmoothSummary::
// remaining_decrease relative to the energy: default 3e-4, 1e-5 on organized meshes; tight 1e-9); fast (the
// adaptive-ε pre-pass, previews) stops on the relative energy decrease per iteration (1e-4 over 5 iterations)
// or a gradient norm of 1e-2 of the start. Iteration caps 300 / 2000 / 20000.
enum class SmoothTolerance { kFast, kDefault, kTight };

// The largest pixel stride that SmoothOptions::prior_weight_per_stride divides β by (the strides measured: 1, 2, 4).
inline constexpr double kMaxStrideForPriorWeight = 4;

SmoothTolerance ParseSmoothTolerance(const std::string& name);  // "fast", "default", "tight"; Error otherwise
std::string SmoothToleranceName(SmoothTolerance tolerance);

// The largest time limit a smoothing call takes (s): about 11.6 days, far beyond any solve.
inline constexpr double kMaxSmoothTimeLimitS = 1e6;

struct SmoothOptions {
  PriorKind prior = PriorKind::kSqrt;  // used when `potential` is null
  double sqrt_epsilon_squared = 1e-4;  // ε² of the square-root potential (the paper's value), (0, 4]
  // Optional ε² per face for the built-in square-root potential (empty: sqrt_epsilon_squared everywhere); else
  // size #F, each in (0, 4]; a face pair (s, t) uses φ(d) = sqrt(d² + ½(ε_s² + ε_t²)). Only with
  // prior = kSqrt and no `potential` (Error otherwise).
  std::vector<double> face_epsilon_squared;
  double cauchy_scale = 0.3;           // c of log(1 + d²/c²), (0, 2]
  // A potential to use instead of `prior` (e.g. a learned spline); not owned, must outlive the call.
  const Potential* potential = nullptr;
  double prior_weight = 2.4;  // β, multiplies the prior sum; [0, 1e6]; 2.4 is the measured default rule
  // Organized meshes (pixel positions and covariances, as from `stereo`, `replay` and `live`): the prior sum is
  // multiplied by β / s instead, s the pixel grid's step (PixelGridStep, bayes/grid_hierarchy.h: 1 when every pixel
  // is a vertex, 4 at `--downsample 4`) clamped to [1, kMaxStrideForPriorWeight], so prior_weight is the weight at
  // every pixel. On the real stereo pairs of the train and validation scenes the best β falls with the stride
  // (BENCHMARKS.md "Real sensor noise"). false: β at every stride.
  bool prior_weight_per_stride = true;
  SmoothTolerance tolerance = SmoothTolerance::kDefault;
  // Stop when the relative energy decrease per iteration (mean over 5) falls below this; 0: the preset's
  // (fast 1e-4; default and tight: off, they stop on the distance below). [0, 1)
  double energy_tolerance = 0;
  // Stop when the estimated distance to the optimum E − E* (SmoothSummary::remaining_decrease) falls below this
  // fraction of the energy; 0: the preset's (fast: off, it stops on the decrease per iteration; default 3e-4, on
  // organized meshes 1e-5; tight 1e-9). [0, 1)
  double gap_tolerance = 0;
  // CG line search: accept a step when |φ'(α)| ≤ c2 |φ'(0)| (a Wolfe curvature condition); (0, 1), or 0: 0.5
  // where CG runs on the ray preconditioner (its directions are close to Gauss–Newton steps, which a looser line
  // search serves with fewer evaluations; chosen on four Middlebury training scenes, BENCHMARKS.md "Smoothing on
  // real stereo"), else 0.1.
  double line_search_c2 = 0;
  int max_iterations = 0;   // 0: the preset's (fast 300, default 2000, tight 20000); else [1, 1e7]
  int num_threads = 0;      // 0: all cores; else [1, 1024]. The result depends only on the input, not on this
  // Optional start of the minimiser (#V×3 positions in the caller's vertex order, finite; null: the measured
  // positions noisy.mesh.V). Not owned, must outlive the call. The energy is unchanged; used by the adaptive-ε
  // default of `rangebayes smooth` to continue from its pre-pass (bayes/adaptive_epsilon.h).
  const Vertices* initial_positions = nullptr;
  // Per-face ε² read from a fast pre-pass on curved meshes (SmoothAdaptiveEpsilon, bayes/adaptive_epsilon.h,
  // with its default rule); piecewise-flat meshes keep the global ε². On by default: this is what `rangebayes
  // smooth` runs. Applies only to the built-in square-root prior with no face_epsilon_squared, no
  // initial_positions and no epsilon_continuation_stages > 0 given, on meshes that are not organized (organized
  // meshes take the continuation below); ignored otherwise.
  bool adaptive_epsilon = true;
  // Organized meshes (NoisyMesh::pixel set, as from a depth image): solve coarse-to-fine over the pixel grid
  // (bayes/grid_hierarchy.h), each level started from the prolongated result of the coarser one. Same energy
  // and minimum; other meshes, or a given initial_positions, take the single-level solve.
  bool multilevel = true;
  // Meshes with anisotropic covariances (W_i not all the same multiple of I: stereo, range scans): CG
  // preconditioned by the Gauss–Newton matrix of the depths along each vertex's weak direction (its ray) instead of
  // the data term alone (bayes/ray_preconditioner.h), rebuilt every kRayRefreshIterations; on organized meshes
  // above kRayDirectVertices vertices by a multigrid V-cycle over the pixel grid, else by a sparse factorisation;
  // larger unorganized meshes keep the data term's preconditioner. Same energy; on stereo meshes it reaches
  // lower minima in a fraction of the iterations (BENCHMARKS.md "Smoothing on real stereo"). Each solve (stage,
  // level) builds its matrix once at least, which a live frame's 80 ms budget does not pay for: the pipeline's
  // budgeted path turns it off. false: the data term.
  bool precondition_rays = true;
  // ε continuation for the built-in square-root prior: before the solve at sqrt_epsilon_squared, solve (same
  // stopping rule as the final solve, warm-started) at ε² · 10^s for s = stages … 1, a smoother energy whose
  // minimum lies near; each stage solved to the same distance from its optimum lands the final solve in a lower
  // basin than fast stages did (the energy is not convex; BENCHMARKS.md "Smoothing on real stereo"); the
  // first stage runs coarse-to-fine when `multilevel` applies. −1 (default): 3 stages on organized meshes
  // (pixel positions and covariances, as from a depth image) without initial_positions (a warm start is
  // already near its optimum), none on others (measured: BENCHMARKS.md "Smoothing
  // on real stereo"; on generic CAD meshes continuation lands in worse minima). Stages asked for that cannot run
  // (a learned prior, face_epsilon_squared given) are reported in the summary's notices. [−1, 6]
  int epsilon_continuation_stages = -1;
  // Seconds for the whole call, continuation stages and coarse levels included (0: no limit). Checked after each
  // iteration; stage k of S continuation stages ends by k/(S+1) of what the setup (done once per call) left, so
  // the final solve at the true ε keeps at least 1/(S+1) of it, and always gets one iteration; stages not started when
  // it ran out are skipped (on the adaptive-ε path of generic meshes, each of its solves gets the limit). The result
  // then depends on the machine's speed. [0, kMaxSmoothTimeLimitS]
  double time_limit_s = 0;
  // ν of the heavy-tailed data term (SmoothingEnergy::SetRobustData): 0 = the Gaussian of the paper (the default,
  // BENCHMARKS.md "Learned disparity-noise model"); else (0, 1e6].
  double robust_data_nu = 0;
  ProgressCallback progress;  // fraction is an estimate (from the energy decrease toward the tolerance)

  void Check() const;
};

enum class SmoothTermination {
  kEnergyConverged,    // relative energy decrease below the tolerance
  kGradientConverged,  // gradient norm below the tolerance
  kOptimalityGapConverged,  // estimated distance to the optimum below the tolerance
  kMaxIterations,
  kNoProgress,         // the line search found no lower energy (numerically at a minimum)
  kTimeLimit,          // SmoothOptions::time_limit_s ran out (remaining_decrease says how far from converged)
  kNothingToDo,        // no vertices
};
std::string SmoothTerminationName(SmoothTermination termination);

// What the adaptive-ε default did (bayes/adaptive_epsilon.h).
struct AdaptiveEpsilonSummary {
  // AdaptiveEpsilonAuto only: the gate rule's median ε² on the pre-pass, and whether the mesh got per-face ε²
  // (false: read as piecewise flat, the global ε² kept; the quantiles below are then the gate rule's).
  double gate_median_epsilon_squared = 0;
  bool per_face = true;
  double median_epsilon_squared = 0;  // over faces
  double p10_epsilon_squared = 0;
  double p90_epsilon_squared = 0;
  int faces_at_minimum = 0;  // faces clamped to min_epsilon_squared (flat or beside a crease)
  double time_s = 0;         // the whole call (with the pre-pass for AdaptiveEpsilonFromPrepass)
  // AdaptiveEpsilonAuto / SmoothAdaptiveEpsilon: the pre-pass's CG iterations, evaluations and time.
  int prepass_iterations = 0;
  int prepass_evaluations = 0;
  double prepass_time_s = 0;
};

struct SmoothSummary {
  int iterations = 0;
  int evaluations = 0;             // energy + gradient evaluations
  std::vector<double> energy;      // energy[0] at the start, then after each iteration
  // E − E* at the end, estimated from the rate at which the energy fell: the decrease over the last 10
  // iterations against the 10 before, a linear rate extrapolated (windows of half the iterations when fewer
  // than 20 ran, and then at least the decrease over the last window); infinity before 4 iterations. A budget or
  // iteration cap that stops early shows here, as an estimate that can read several times too low
  // (docs/design.md, "Stopping").
  double remaining_decrease = std::numeric_limits<double>::infinity();
  double data_energy = 0;          // final parts
  double prior_energy = 0;
  double prior_weight = 0;         // β the energy used (after SmoothOptions::prior_weight_per_stride)
  double pixel_stride = 0;         // organized meshes: the pixel grid's step that β was divided by; 0: none
  // What the call repaired or could not use, one line each; e.g. pixel positions that are not one grid (the
  // mesh is then smoothed with the full β and without the grid levels).
  std::vector<std::string> notices;
  double initial_gradient_norm = 0;
  double final_gradient_norm = 0;
  SmoothTermination termination = SmoothTermination::kNothingToDo;
  double time_s = 0;               // whole call
  double setup_time_s = 0;         // topology and buffers
  int restarts = 0;
  int flipped_faces = 0;           // result faces folded over their neighbours (normal against theirs)
  int input_flipped_faces = 0;     // the same count in the input (noise folds some faces; smoothing unfolds)
  int inactive_faces = 0;          // degenerate faces left out of the prior
  int num_threads = 0;
  std::string potential_name;
  size_t memory_bytes = 0;         // solver memory beyond the input mesh (energy buffers + minimiser vectors)
  int levels = 1;                  // grid levels solved coarse to fine, in any stage (1: single level)
  int continuation_stages = 0;     // ε-continuation stages solved before the final solve
  // Evaluations before the final solve (coarse levels and continuation stages), in units of one evaluation of the
  // input (iterations and evaluations above are the final solve's).
  double coarse_work = 0;
  bool adaptive_epsilon_used = false;  // the adaptive-ε default ran (then `adaptive` says what it did)
  AdaptiveEpsilonSummary adaptive;

  // A few lines for people (what `rangebayes smooth` prints): iterations, evaluations, time, termination,
  // energies, the adaptive-ε decision and warnings (flipped faces).
  std::string BriefReport() const;
};

// Smooths `noisy`: same vertex count and order, same faces. Requires noisy.has_covariance() with symmetric
// positive definite covariances (eigenvalues below 1e-6 of the largest are raised to it); throws Error
// naming the vertex otherwise, and on non-finite positions or bad face indices. Internally the solver works on
// a copy in a cache-friendly order (vertices along a Morton curve of the input positions); the caller's order
// affects the result only through rounding.
Mesh Smooth(const NoisyMesh& noisy, const SmoothOptions& options = {}, SmoothSummary* summary = nullptr);

// The information matrix W = ½ Σ⁻¹ that the smoother uses for a covariance Σ: symmetrised, eigenvalues below 1e-6
// of the largest raised to it (rounding, or a singular Σ); σ² I gives (0.5 / σ²) I exactly (which the energy stores
// compactly). False when Σ is not finite and positive semi-definite (an eigenvalue below −1e-6 of the largest is
// not rounding) or is zero (no measurement: infinite information).
bool InformationFromCovariance(const Eigen::Matrix3d& covariance, Eigen::Matrix3d* information);
// The same; throws Error when Σ is not finite, positive semi-definite and non-zero.
Eigen::Matrix3d InformationFromCovariance(const Eigen::Matrix3d& covariance);

// A start for the smoother on an organized mesh from an earlier result at the same pixels (successive frames of
// a live run): each vertex of `noisy` whose pixel the earlier mesh also has starts at the earlier position when
// that lies within max_sigmas of its measurement under its covariance (Mahalanobis distance); the others start at
// their measurements. Fills *start (#V×3) and returns how many vertices took the earlier position (0 when
// `noisy` has no pixels or covariances). previous_pixel and previous_positions: one row per earlier vertex.
int StartFromEarlierResult(const NoisyMesh& noisy,
                           const Eigen::Matrix<float, Eigen::Dynamic, 2, Eigen::RowMajor>& previous_pixel,
                           const Vertices& previous_positions, double max_sigmas, Vertices* start);

}  // namespace rangebayes
