#include "bayes/smooth.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/parallel_sort.h>
#include <tbb/task_arena.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <limits>
#include <memory>
#include <optional>
#include <unordered_map>
#include <utility>

#include "bayes/adaptive_epsilon.h"
#include "bayes/grid_hierarchy.h"
#include "bayes/ray_preconditioner.h"
#include "bayes/smoothing_energy.h"
#include "core/error.h"
#include "core/validate.h"

namespace rangebayes {
namespace {

struct Preset {
  double energy;    // relative energy decrease over kWindow iterations, divided by kWindow; 0: off
  double gap;       // distance to the optimum (RemainingDecrease) relative to |E|; 0: off
  double gradient;  // ‖g‖ / ‖g_0‖
  int max_iterations;
};
constexpr int kWindow = 5;
// The default preset's distance-to-optimum tolerance: 3e-4 of the energy in general (on child it stops where the
// earlier decrease rule did: same iterations, same result), 1e-5 on organized (stereo) meshes: chosen on four
// Middlebury scenes (1e-4, 3e-5, 1e-5 against a 1e-6 reference; BENCHMARKS.md "Smoothing on real stereo"), the
// closest to the reference energy for +24% time over 1e-4. On these non-convex energies the rate-based estimate
// reads low: the true distance was up to 0.2% of E at an estimate of 1e-5.
constexpr double kOrganizedGapTolerance = 1e-5;
// Iterations between rebuilds of the ray preconditioner's matrix (SmoothOptions::precondition_rays).
constexpr int kRayRefreshIterations = 20;
// SmoothOptions::line_search_c2 = 0: the line search's curvature condition with and without the ray preconditioner.
constexpr double kRayLineSearchC2 = 0.5;
constexpr double kLineSearchC2 = 0.1;

Preset PresetFor(SmoothTolerance tolerance) {
  switch (tolerance) {
    case SmoothTolerance::kFast:
      return {1e-4, 0, 1e-2, 300};
    case SmoothTolerance::kDefault:
      return {0, 3e-4, 0, 2000};
    case SmoothTolerance::kTight:
      return {0, 1e-9, 0, 20000};
  }
  return {0, 3e-4, 0, 2000};
}

// The preset of options.tolerance with the tolerances and the iteration cap that options sets explicitly.
Preset EffectivePreset(const SmoothOptions& options) {
  Preset preset = PresetFor(options.tolerance);
  if (options.energy_tolerance > 0) preset.energy = options.energy_tolerance;
  if (options.gap_tolerance > 0) preset.gap = options.gap_tolerance;
  if (options.max_iterations > 0) preset.max_iterations = options.max_iterations;
  return preset;
}

using Clock = std::chrono::steady_clock;

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// Vector operations of the minimiser, parallel over fixed chunks (the reduction tree depends only on the
// length, so the bytes do not depend on the thread count). At 2 threads the serial versions took ~10% of a run.
constexpr Eigen::Index kVectorChunk = 8192;

double Dot(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<Eigen::Index>(0, a.size(), kVectorChunk), 0.0,
      [&](const tbb::blocked_range<Eigen::Index>& r, double sum) {
        return sum + a.segment(r.begin(), r.size()).dot(b.segment(r.begin(), r.size()));
      },
      [](double u, double v) { return u + v; });
}

// out = a + alpha · b
void Axpy(const Eigen::VectorXd& a, double alpha, const Eigen::VectorXd& b, Eigen::VectorXd* out) {
  out->resize(a.size());
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, a.size(), kVectorChunk),
                    [&](const tbb::blocked_range<Eigen::Index>& r) {
                      out->segment(r.begin(), r.size()) =
                          a.segment(r.begin(), r.size()) + alpha * b.segment(r.begin(), r.size());
                    });
}

// a·b and a·c in one pass (same fixed chunks as Dot).
std::pair<double, double> DotPair(const Eigen::VectorXd& a, const Eigen::VectorXd& b, const Eigen::VectorXd& c) {
  using Sums = std::pair<double, double>;
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<Eigen::Index>(0, a.size(), kVectorChunk), Sums{0.0, 0.0},
      [&](const tbb::blocked_range<Eigen::Index>& r, Sums sum) {
        const auto s = a.segment(r.begin(), r.size());
        return Sums{sum.first + s.dot(b.segment(r.begin(), r.size())),
                    sum.second + s.dot(c.segment(r.begin(), r.size()))};
      },
      [](Sums u, Sums v) { return Sums{u.first + v.first, u.second + v.second}; });
}

// p = alpha · p − z; returns g · p (the new direction's slope) from the same pass.
double ScaleSubtractDot(double alpha, const Eigen::VectorXd& z, const Eigen::VectorXd& g, Eigen::VectorXd* p) {
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<Eigen::Index>(0, z.size(), kVectorChunk), 0.0,
      [&](const tbb::blocked_range<Eigen::Index>& r, double sum) {
        auto segment = p->segment(r.begin(), r.size());
        segment = alpha * segment - z.segment(r.begin(), r.size());
        return sum + segment.dot(g.segment(r.begin(), r.size()));
      },
      [](double u, double v) { return u + v; });
}

// Line search on φ(α) = E(x + α p): Newton–Raphson on the directional derivative φ'(α) = g(x + α p)·p with
// the curvature from the last two derivatives (secant), guarded by the Armijo condition: a point is accepted
// only if φ(α) ≤ φ(0) + c1 α φ'(0), so the energy never rises. Stops when |φ'(α)| ≤ c2 |φ'(0)|.
struct LineSearchResult {
  bool success = false;
  double alpha = 0;
  double energy = 0;
  EnergyParts parts;
  int evaluations = 0;
};

class Problem {
 public:
  Problem(const SmoothingEnergy& energy) : energy_(energy) {}
  EnergyParts Evaluate(const Eigen::VectorXd& x, Eigen::VectorXd* g) {
    ++evaluations;
    return energy_.Evaluate(x, g);
  }
  const SmoothingEnergy& energy() const { return energy_; }
  int evaluations = 0;

 private:
  const SmoothingEnergy& energy_;
};

// Trials are evaluated straight into *x_out / *g_out (no extra state vectors: memory matters at 1M faces); if
// the last trial is not the best accepted one, the best is evaluated again (rare).
LineSearchResult LineSearch(Problem& problem, const Eigen::VectorXd& x, const Eigen::VectorXd& p, double energy0,
                            double slope0, double alpha_init, double c2, Eigen::VectorXd* x_out,
                            Eigen::VectorXd* g_out) {
  constexpr double kArmijo = 1e-4;
  constexpr int kMaxEvaluations = 20;
  LineSearchResult best;
  best.energy = energy0;
  double lo = 0, slope_lo = slope0;  // largest accepted α with negative slope
  double hi = std::numeric_limits<double>::infinity();
  double alpha = alpha_init;
  double last_alpha = -1;
  const int start_evaluations = problem.evaluations;
  for (int it = 0; it < kMaxEvaluations; ++it) {
    if (!(alpha > 0) || !std::isfinite(alpha)) break;
    Axpy(x, alpha, p, x_out);
    const EnergyParts parts = problem.Evaluate(*x_out, g_out);
    last_alpha = alpha;
    const double e = parts.total();
    if (!std::isfinite(e) || e > energy0 + kArmijo * alpha * slope0) {
      // Too far: a parabola through φ(0), φ'(0), φ(α), kept inside [0.1α, 0.5α] and above lo.
      hi = alpha;
      double next = 0.5 * alpha;
      if (std::isfinite(e)) {
        const double denom = 2 * (e - energy0 - slope0 * alpha);
        if (denom > 0) next = std::clamp(-slope0 * alpha * alpha / denom, 0.1 * alpha, 0.5 * alpha);
      }
      alpha = std::max(next, lo + 0.1 * (hi - lo));
      if (!(alpha < hi)) alpha = 0.5 * (lo + hi);
      if (hi - lo <= 1e-14 * hi) break;
      continue;
    }
    const double slope = Dot(*g_out, p);
    if (!best.success || e <= best.energy) {
      best.success = true;
      best.alpha = alpha;
      best.energy = e;
      best.parts = parts;
    }
    if (std::abs(slope) <= c2 * std::abs(slope0)) break;
    double next;
    if (slope < 0) {
      // Still descending: Newton step with the secant curvature through (lo, slope_lo) and (α, slope).
      const double denom = slope - slope_lo;
      next = denom > 0 ? alpha - slope * (alpha - lo) / denom : 4 * alpha;
      lo = alpha;
      slope_lo = slope;
      next = std::min(next, 4 * alpha);
      next = std::max(next, 1.1 * alpha);
      if (std::isfinite(hi) && !(next < hi)) next = 0.5 * (lo + hi);
    } else {
      // Passed the minimum: the secant root between lo and α.
      hi = alpha;
      const double denom = slope - slope_lo;
      next = denom > 0 ? lo - slope_lo * (alpha - lo) / denom : 0.5 * (lo + alpha);
      const double width = alpha - lo;
      next = std::clamp(next, lo + 0.05 * width, alpha - 0.05 * width);
    }
    if (std::isfinite(hi) && hi - lo <= 1e-14 * hi) break;
    alpha = next;
  }
  if (best.success && last_alpha != best.alpha) {
    Axpy(x, best.alpha, p, x_out);
    best.parts = problem.Evaluate(*x_out, g_out);
    best.energy = best.parts.total();
  }
  best.evaluations = problem.evaluations - start_evaluations;
  return best;
}

std::unique_ptr<Potential> MakePotential(const SmoothOptions& options) {
  switch (options.prior) {
    case PriorKind::kSqrt:
      return std::make_unique<SqrtPotential>(options.sqrt_epsilon_squared);
    case PriorKind::kQuadratic:
      return std::make_unique<QuadraticPotential>();
    case PriorKind::kCauchy:
      return std::make_unique<CauchyPotential>(options.cauchy_scale);
  }
  return std::make_unique<SqrtPotential>(options.sqrt_epsilon_squared);
}

// Progress estimate: how far the (log) relative decrease has come from its first value to the tolerance.
double ProgressFraction(double first_decrease, double decrease, double tolerance, int iteration, int max_iterations) {
  double by_energy = 0;
  if (first_decrease > tolerance && decrease > 0) {
    by_energy = std::log(first_decrease / decrease) / std::log(first_decrease / tolerance);
  }
  const double by_iterations = static_cast<double>(iteration) / max_iterations;
  return std::clamp(std::max(by_energy, by_iterations), 0.0, 0.99);
}

// The energy still to lose, E − E*, extrapolated from the energy history: with the mean decrease per iteration Δ
// over the last window of w iterations and Δ' over the w before (w = kRateWindow, or half the iterations so far
// when fewer have run, at least 2), a linear rate ρ = (Δ/Δ')^(1/w) leaves Δ·ρ/(1 − ρ). A slow plateau (ρ → 1)
// reads as far from the optimum, not as converged, which is what a rule on the decrease per iteration gets
// wrong. Infinity before 4 iterations; 0 when the energy stopped falling.
//
// Windows shorter than kRateWindow do not carry a rate: right after a warm start (a new ε, the previous frame)
// fast first steps followed by slower ones read as a geometric tail with little left — a continuation stage on
// tsukuba stopped after 4 iterations in which 2% of E fell. So with a short window the estimate is at least the
// decrease observed over that window (what is left of a tail whose window ratio ρ^w is at least ½).
constexpr int kRateWindow = 10;
double RemainingDecrease(const std::vector<double>& energy) {
  const int k = static_cast<int>(energy.size()) - 1;
  const int w = std::min(kRateWindow, k / 2);
  if (w < 2) return std::numeric_limits<double>::infinity();
  const double recent = energy[static_cast<size_t>(k - w)] - energy[static_cast<size_t>(k)];
  const double older = energy[static_cast<size_t>(k - 2 * w)] - energy[static_cast<size_t>(k - w)];
  if (!(recent > 0)) return 0.0;
  const double ratio = older > 0 ? std::min(recent / older, 1.0) : 1.0;
  const double rho = std::min(std::pow(ratio, 1.0 / w), 0.9999);
  const double extrapolated = recent / w * rho / (1 - rho);
  return w < kRateWindow ? std::max(extrapolated, recent) : extrapolated;
}

struct MinimiseResult {
  Eigen::VectorXd x;
  EnergyParts parts;
};

// M⁻¹ of Minimise's CG. M = blockdiag(2 W_i), the data term's Hessian (exact and constant), or with `ray` the
// Gauss–Newton matrix of the depths along the rays. It removes the conditioning that anisotropic stereo
// covariances add; when every W_i is the same multiple of I it is a global scale, which CG does not need (then
// active is false and z = M⁻¹ g is kept implicit: zᵀg = scale · gᵀg).
//
// Stiff vertices: where faces are slivers (real scans have faces of 1e-9 of the mean area), the prior's stiffness
// at a vertex, which goes as |e|²/|c|², exceeds the rest of the mesh's by up to 1e9, and a step along −(2W)⁻¹g
// that suits the rest turns those faces' normals over: the solve stalled at its start ("no further decrease").
// Vertices whose prior stiffness (SmoothingEnergy::StiffVertices, trace) exceeds kStiffRatio times the median
// vertex's take M_i = 2W_i + B_i instead (block Jacobi); on meshes without such vertices nothing changes. When the
// start has any, the set is rebuilt every kRayRefreshIterations (slivers of the input open up as it smooths; a
// start without any is not searched again, so generic meshes pay nothing for it). Largest / median stiffness: ≤ 1.2e3
// on 25 noisy and clean benchmark meshes (igea; most below 200), 3.5e8 on the GuidedDenoising iron scan and 4e8 on
// camelhead, which stalled before and converge with a cut of 1e4 or 1e5 (1e6 still stalls the iron scan):
// docs/journal/reliability.md.
constexpr double kStiffRatio = 1e4;

struct CgPreconditioner {
  const SmoothingEnergy& energy;
  bool active = false;
  double scale = 0;
  RayPreconditioner* ray = nullptr;
  std::vector<int> stiff;                    // vertices with M_i = 2W_i + B_i
  std::vector<Eigen::Matrix3d> stiff_prior;    // their B_i
  std::vector<Eigen::Matrix3d> stiff_inverse;  // their M_i⁻¹

  // pᵀ M p: the model's curvature along p.
  double Curvature(const Eigen::VectorXd& p) const {
    double sum = energy.DataCurvature(p);
    for (size_t j = 0; j < stiff.size(); ++j) {
      const auto pi = p.segment<3>(3 * static_cast<Eigen::Index>(stiff[j]));
      sum += pi.dot(stiff_prior[j] * pi);
    }
    return sum;
  }

  void Apply(const Eigen::VectorXd& v, Eigen::VectorXd* out) const {
    if (ray != nullptr) {
      ray->Apply(v, out);
      return;
    }
    energy.ApplyDataInverse(v, out);
    for (size_t j = 0; j < stiff.size(); ++j) {
      const Eigen::Index i = 3 * static_cast<Eigen::Index>(stiff[j]);
      out->segment<3>(i) = stiff_inverse[j] * v.segment<3>(i);
    }
  }

  // Finds the stiff vertices at x; true when there are any.
  bool UpdateStiff(const Eigen::VectorXd& x) {
    std::vector<int> vertices;
    std::vector<Eigen::Matrix3d> blocks;
    energy.StiffVertices(x, kStiffRatio, &vertices, &blocks);
    stiff.clear();
    stiff_prior.clear();
    stiff_inverse.clear();
    for (size_t j = 0; j < vertices.size(); ++j) {
      const Eigen::Matrix3d data = 2 * energy.InformationMatrix(vertices[j]);
      const Eigen::Matrix3d& prior = blocks[j];
      if (!prior.allFinite()) continue;
      // M⁻¹ with 2W = L Lᵀ: L⁻ᵀ (I + C)⁻¹ L⁻¹, C = L⁻¹ B L⁻ᵀ = V Λ Vᵀ with Λ clamped at 0 (B is semi-definite, and
      // its small eigenvalues carry the rounding of its large ones: B's entries reach 1e19 where 2W's are 1e2).
      const Eigen::LLT<Eigen::Matrix3d> llt(data);
      if (llt.info() != Eigen::Success) continue;
      const Eigen::Matrix3d l_inverse = llt.matrixL().solve(Eigen::Matrix3d::Identity());
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(l_inverse * prior * l_inverse.transpose());
      const Eigen::Vector3d scale = (Eigen::Vector3d::Ones() + eigen.eigenvalues().cwiseMax(0.0)).cwiseInverse();
      const Eigen::Matrix3d v = l_inverse.transpose() * eigen.eigenvectors();
      stiff.push_back(vertices[j]);
      stiff_prior.push_back(prior);
      stiff_inverse.push_back(v * scale.asDiagonal() * v.transpose());
    }
    return !stiff.empty();
  }
};

CgPreconditioner MakeCgPreconditioner(const SmoothingEnergy& energy, const SmoothOptions& options,
                                      RayPreconditioner* ray, const Eigen::VectorXd& x) {
  CgPreconditioner m{energy, false, 0.0, nullptr, {}, {}, {}};
  m.active = !energy.uniform_isotropic();
  m.scale = m.active ? 0.0 : energy.UniformDataInverseScale();
  if (m.active && options.precondition_rays && ray != nullptr && ray->Update(x)) m.ray = ray;
  if (m.ray == nullptr && m.UpdateStiff(x)) m.active = true;
  return m;
}

// The first step length tried along p: the last step scaled by the slopes' ratio; with the ray preconditioner
// p = −M⁻¹g with M ≈ the Hessian, so 1 (a Gauss–Newton step); else the minimum of the model pᵀMp along p.
double InitialStep(double alpha_prev, double slope_prev, double slope, const CgPreconditioner& m,
                   const Eigen::VectorXd& p) {
  if (alpha_prev > 0 && slope_prev < 0) return alpha_prev * std::min(slope_prev / slope, 10.0);
  if (m.ray != nullptr) return 1;
  const double curvature = m.Curvature(p);
  return curvature > 0 ? -slope / curvature : 1.0 / std::sqrt(-slope);
}

// PR+ (preconditioned): β = max(0, z_newᵀ(g_new − g) / zᵀg), z = M⁻¹ g (z = g without a preconditioner). Returns
// β before the max; z becomes M⁻¹ g_new, gg its ‖g_new‖², zg its z_newᵀg_new.
double PolakRibiere(const CgPreconditioner& m, const Eigen::VectorXd& g_new, const Eigen::VectorXd& g,
                    Eigen::VectorXd* z, double* gg, double* zg) {
  if (m.active) {
    m.Apply(g_new, z);
    const auto [zg_next, zg_cross] = DotPair(*z, g_new, g);
    const double beta = (zg_next - zg_cross) / *zg;
    *zg = zg_next;
    *gg = Dot(g_new, g_new);
    return beta;
  }
  const auto [gg_new, gg_cross] = DotPair(g_new, g_new, g);
  const double beta = (gg_new - gg_cross) / *gg;
  *gg = gg_new;
  *zg = m.scale * *gg;
  return beta;
}

// After an iteration that reached energy e (already in summary->energy): records the distance estimate,
// reports progress, and returns the termination that ends the solve now, if any. The estimate extrapolates the
// rate of decrease, which early in a solve can exceed all there is to gain: it is capped at e − energy_floor
// (SmoothingEnergy::LowerBound; the energy itself for the built-in potentials).
std::optional<SmoothTermination> StopAfter(const Preset& preset, const SmoothOptions& options, int iteration,
                                           double e, double energy_floor, double gradient_stop,
                                           Clock::time_point deadline, double* first_remaining,
                                           SmoothSummary* summary) {
  double remaining = RemainingDecrease(summary->energy);
  if (std::isfinite(remaining)) remaining = std::min(remaining, std::max(0.0, e - energy_floor));
  summary->remaining_decrease = remaining;
  const double relative_remaining = remaining / std::max(std::abs(e), 1e-300);
  if (*first_remaining < 0 && std::isfinite(relative_remaining)) *first_remaining = relative_remaining;
  const int count = static_cast<int>(summary->energy.size());
  double decrease = -1;
  if (count > kWindow) {
    const double old = summary->energy[static_cast<size_t>(count - 1 - kWindow)];
    decrease = (old - e) / std::max(std::abs(e), 1e-300) / kWindow;
  }
  if (options.progress) {
    options.progress(ProgressFraction(*first_remaining, relative_remaining, preset.gap > 0 ? preset.gap : preset.energy,
                                      iteration, preset.max_iterations),
                     "smoothing");
  }
  if (preset.gap > 0 && relative_remaining <= preset.gap) {
    return SmoothTermination::kOptimalityGapConverged;
  }
  if (preset.energy > 0 && decrease >= 0 && decrease < preset.energy) return SmoothTermination::kEnergyConverged;
  if (summary->final_gradient_norm <= gradient_stop) return SmoothTermination::kGradientConverged;
  if (Clock::now() >= deadline) return SmoothTermination::kTimeLimit;
  return std::nullopt;
}

MinimiseResult Minimise(Problem& problem, const SmoothOptions& options, Clock::time_point deadline,
                        SmoothSummary* summary, const Eigen::VectorXd* start = nullptr,
                        RayPreconditioner* ray = nullptr) {
  const Preset preset = EffectivePreset(options);
  const SmoothingEnergy& energy = problem.energy();
  const Eigen::Index n = 3 * static_cast<Eigen::Index>(energy.num_vertices());
  const int restart_every = std::max(50, static_cast<int>(n));

  Eigen::VectorXd x = start != nullptr ? *start : energy.Measurements();
  Eigen::VectorXd g(n), g_new(n), x_new(n), p(n);
  EnergyParts parts = problem.Evaluate(x, &g);
  double e = parts.total();
  summary->energy.push_back(e);
  // ‖g‖² (and zᵀg with a preconditioner) are carried from one iteration to the next, and the dot products
  // are fused with the passes that produce their vectors: same values, same bytes, four fewer sweeps each.
  double gg = Dot(g, g);
  summary->initial_gradient_norm = std::sqrt(gg);
  summary->final_gradient_norm = summary->initial_gradient_norm;
  summary->termination = SmoothTermination::kMaxIterations;
  CgPreconditioner m = MakeCgPreconditioner(energy, options, ray, x);
  Eigen::VectorXd z;
  if (m.active) m.Apply(g, &z);
  const Eigen::VectorXd& zg = m.active ? z : g;  // the preconditioned gradient (g itself without)
  double zg_old = m.active ? Dot(z, g) : m.scale * gg;
  if (!(summary->initial_gradient_norm > 0)) {
    summary->termination = SmoothTermination::kGradientConverged;
    return {x, parts};
  }
  const double gradient_stop = preset.gradient * summary->initial_gradient_norm;
  const double energy_floor = energy.LowerBound();

  p = -zg;
  double alpha_prev = 0, slope_prev = 0;
  bool slope_known = false;
  double known_slope = 0;
  double first_remaining = -1;
  int since_restart = 0;
  for (int iteration = 1; iteration <= preset.max_iterations; ++iteration) {
    // g·p comes from the pass that built p (ScaleSubtractDot) when there was one.
    double slope = slope_known ? known_slope : Dot(g, p);
    slope_known = false;
    if (!(slope < 0)) {
      p = -zg;
      slope = -Dot(g, zg);
      ++summary->restarts;
      since_restart = 0;
    }
    const double alpha_init = InitialStep(alpha_prev, slope_prev, slope, m, p);
    const double c2 = options.line_search_c2 > 0 ? options.line_search_c2
                                                  : m.ray != nullptr ? kRayLineSearchC2 : kLineSearchC2;
    LineSearchResult step = LineSearch(problem, x, p, e, slope, alpha_init, c2, &x_new, &g_new);
    if (!step.success) {
      if (since_restart == 0) {
        summary->termination = SmoothTermination::kNoProgress;
        break;
      }
      // Retry once from (preconditioned) steepest descent before giving up.
      p = -zg;
      since_restart = 0;
      alpha_prev = 0;
      ++summary->restarts;
      --iteration;
      continue;
    }
    summary->iterations = iteration;
    x.swap(x_new);
    // A new M (the Gauss–Newton matrix at the current state) every kRayRefreshIterations: CG restarts on it.
    const bool refreshed = (m.ray != nullptr || !m.stiff.empty()) && iteration % kRayRefreshIterations == 0;
    if (refreshed) {
      if (m.ray != nullptr) {
        if (!m.ray->Update(x)) m.ray = nullptr;
      } else {
        m.UpdateStiff(x);
      }
      since_restart = restart_every;
    }
    const double beta_pr = PolakRibiere(m, g_new, g, &z, &gg, &zg_old);
    g.swap(g_new);
    alpha_prev = refreshed ? 0 : step.alpha;
    slope_prev = slope;
    e = step.energy;
    parts = step.parts;
    summary->energy.push_back(e);
    summary->final_gradient_norm = std::sqrt(gg);
    ++since_restart;

    if (const auto stop = StopAfter(preset, options, iteration, e, energy_floor, gradient_stop, deadline,
                                    &first_remaining, summary)) {
      summary->termination = *stop;
      break;
    }
    if (since_restart >= restart_every) {
      p = -zg;
      since_restart = 0;
      ++summary->restarts;
    } else {
      known_slope = ScaleSubtractDot(std::max(0.0, beta_pr), zg, g, &p);
      slope_known = true;
    }
  }
  if (m.ray != nullptr) summary->memory_bytes += m.ray->MemoryBytes();
  summary->memory_bytes += static_cast<size_t>(n) * sizeof(double) * 5 + sizeof(double) * static_cast<size_t>(z.size());
  return {x, parts};
}

// Spreads the low 21 bits of v to every third bit (Morton / Z-order interleave).
uint64_t SpreadBits(uint64_t v) {
  v &= 0x1fffff;
  v = (v | v << 32) & 0x1f00000000ffffULL;
  v = (v | v << 16) & 0x1f0000ff0000ffULL;
  v = (v | v << 8) & 0x100f00f00f00f00fULL;
  v = (v | v << 4) & 0x10c30c30c30c30c3ULL;
  v = (v | v << 2) & 0x1249249249249249ULL;
  return v;
}

// The solver's internal order: vertices along a Morton (Z-order) curve of their measured positions, faces by
// their smallest new vertex index. Meshes are often stored in scan order or shuffled (the NLLR files are), and
// every energy evaluation gathers neighbours' normals and positions: in a spatially coherent order those hit
// the cache (measured 1.8× less CPU per evaluation on child). The order depends only on the input, so the
// result stays the same whatever the thread count. Returns new → old indices; the mesh must be finite.
void SolverOrder(const Mesh& mesh, std::vector<int>* vertex_order, std::vector<int>* face_order) {
  const int nv = mesh.num_vertices(), nf = mesh.num_faces();
  vertex_order->resize(static_cast<size_t>(nv));
  face_order->resize(static_cast<size_t>(nf));
  if (nv == 0) return;
  const Eigen::RowVector3d lo = mesh.V.colwise().minCoeff(), hi = mesh.V.colwise().maxCoeff();
  const Eigen::RowVector3d scale = (hi - lo).cwiseMax(1e-300).cwiseInverse() * 2097151.0;
  std::vector<std::pair<uint64_t, int>> keys(static_cast<size_t>(nv));
  tbb::parallel_for(tbb::blocked_range<int>(0, nv, 4096), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i != r.end(); ++i) {
      uint64_t key = 0;
      for (int k = 0; k < 3; ++k) {
        const double q = std::clamp((mesh.V(i, k) - lo[k]) * scale[k], 0.0, 2097151.0);
        key |= SpreadBits(static_cast<uint64_t>(q)) << k;
      }
      keys[static_cast<size_t>(i)] = {key, i};
    }
  });
  // (key, index) pairs are distinct, so the sorted order is unique whatever the sort and thread count.
  tbb::parallel_sort(keys.begin(), keys.begin() + nv);
  std::vector<int> new_index(static_cast<size_t>(nv));
  for (int n = 0; n < nv; ++n) {
    (*vertex_order)[static_cast<size_t>(n)] = keys[static_cast<size_t>(n)].second;
    new_index[static_cast<size_t>(keys[static_cast<size_t>(n)].second)] = n;
  }
  std::vector<std::pair<uint64_t, int>>().swap(keys);
  // Faces by (smallest new vertex, old index): a counting sort by the vertex, stable in the old index.
  std::vector<int> first(static_cast<size_t>(nv) + 1, 0);
  std::vector<int> smallest(static_cast<size_t>(nf));
  for (int f = 0; f < nf; ++f) {
    const int m = std::min({new_index[static_cast<size_t>(mesh.F(f, 0))], new_index[static_cast<size_t>(mesh.F(f, 1))],
                            new_index[static_cast<size_t>(mesh.F(f, 2))]});
    smallest[static_cast<size_t>(f)] = m;
    ++first[static_cast<size_t>(m) + 1];
  }
  for (int v = 0; v < nv; ++v) first[static_cast<size_t>(v) + 1] += first[static_cast<size_t>(v)];
  for (int f = 0; f < nf; ++f) (*face_order)[static_cast<size_t>(first[static_cast<size_t>(smallest[static_cast<size_t>(f)])]++)] = f;
}

// One mesh's energy in the solver order (SolverOrder) with the maps back to the caller's order. The energy refers
// to `ordered` (and to the potential), so a PreparedEnergy is built in place and never moved.
struct PreparedEnergy {
  Mesh ordered;
  std::vector<int> vertex_order;  // solver index → caller's index
  std::vector<double> face_epsilon_squared;
  std::unique_ptr<Potential> owned_potential;
  const Potential* potential = nullptr;  // the energy's own (options.potential or owned_potential)
  std::unique_ptr<SmoothingEnergy> energy;

  // #V×3 positions in the caller's order → the solver's state vector, and back.
  Eigen::VectorXd ToSolver(const Vertices& positions) const {
    const int nv = static_cast<int>(vertex_order.size());
    Eigen::VectorXd x(3 * static_cast<Eigen::Index>(nv));
    for (int n = 0; n < nv; ++n) {
      for (int k = 0; k < 3; ++k) x[3 * n + k] = positions(vertex_order[static_cast<size_t>(n)], k);
    }
    return x;
  }
  Vertices ToCaller(const Eigen::VectorXd& x) const {
    const int nv = static_cast<int>(vertex_order.size());
    Vertices out(nv, 3);
    for (int n = 0; n < nv; ++n) {
      const int i = vertex_order[static_cast<size_t>(n)];
      for (int k = 0; k < 3; ++k) out(i, k) = x[3 * n + k];
    }
    return out;
  }
};

// Checks `noisy` (and options that refer to its size), computes W_i = ½ Σ_i⁻¹, reorders and builds the energy;
// fills summary's potential name, inactive faces and memory. Call inside the solve's task arena.
std::unique_ptr<PreparedEnergy> Prepare(const NoisyMesh& noisy, const SmoothOptions& options, SmoothSummary* summary) {
  const Mesh& mesh = noisy.mesh;
  RB_CHECK(static_cast<int>(noisy.covariance.size()) == mesh.num_vertices(), "smooth: the mesh has ",
           noisy.covariance.size(), " covariances for ", mesh.num_vertices(),
           " vertices (use MakeGenericNoisyMesh for a plain mesh)");
  // The energy's buffers index coordinates and face corners as int (3 and 9 entries per vertex and face).
  constexpr int kMaxElements = std::numeric_limits<int>::max() / 9;
  RB_CHECK(mesh.num_vertices() <= kMaxElements && mesh.num_faces() <= kMaxElements, "smooth: ", mesh.num_vertices(),
           " vertices and ", mesh.num_faces(), " faces; at most ", kMaxElements, " of each");
  auto prepared = std::make_unique<PreparedEnergy>();
  const Potential* potential = options.potential;
  if (potential == nullptr) {
    prepared->owned_potential = MakePotential(options);
    potential = prepared->owned_potential.get();
  }
  prepared->potential = potential;
  summary->potential_name = potential->Name();
  // Checked here, before the reordering, so that messages name the caller's indices.
  CheckComputableScale(mesh.V, "smoothing");
  for (int f = 0; f < mesh.num_faces(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.F(f, k);
      RB_CHECK(v >= 0 && v < mesh.num_vertices(), "smoothing: face ", f, " refers to vertex ", v,
               ", but the mesh has ", mesh.num_vertices(), " vertices");
    }
  }
  RB_CHECK(options.face_epsilon_squared.empty() ||
               static_cast<int>(options.face_epsilon_squared.size()) == mesh.num_faces(),
           "smooth: ", options.face_epsilon_squared.size(), " per-face epsilon_squared values for ",
           mesh.num_faces(), " faces");
  RB_CHECK(options.initial_positions == nullptr ||
               (options.initial_positions->rows() == mesh.num_vertices() && options.initial_positions->cols() == 3 &&
                options.initial_positions->allFinite()),
           "smooth: initial_positions must be a finite ", mesh.num_vertices(), " x 3 matrix");

  std::vector<Eigen::Matrix3d> information(noisy.covariance.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, information.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      if (!InformationFromCovariance(noisy.covariance[i], &information[i])) information[i].setConstant(std::nan(""));
    }
  });
  for (size_t i = 0; i < information.size(); ++i) {
    RB_CHECK(information[i].allFinite(), "smooth: the covariance of vertex ", i,
             " is not finite, positive semi-definite and non-zero");
  }
  // The solver works on a reordered copy (SolverOrder); results go back to the input's order.
  std::vector<int> face_order;
  SolverOrder(mesh, &prepared->vertex_order, &face_order);
  const int nv = mesh.num_vertices(), nf = mesh.num_faces();
  Mesh& ordered = prepared->ordered;
  ordered.V.resize(nv, 3);
  ordered.F.resize(nf, 3);
  std::vector<int> new_index(static_cast<size_t>(nv));
  {
    std::vector<Eigen::Matrix3d> ordered_information(information.size());
    tbb::parallel_for(tbb::blocked_range<int>(0, nv, 4096), [&](const tbb::blocked_range<int>& r) {
      for (int n = r.begin(); n != r.end(); ++n) {
        const int i = prepared->vertex_order[static_cast<size_t>(n)];
        ordered.V.row(n) = mesh.V.row(i);
        new_index[static_cast<size_t>(i)] = n;
        ordered_information[static_cast<size_t>(n)] = information[static_cast<size_t>(i)];
      }
    });
    information.swap(ordered_information);
    tbb::parallel_for(tbb::blocked_range<int>(0, nf, 4096), [&](const tbb::blocked_range<int>& r) {
      for (int m = r.begin(); m != r.end(); ++m) {
        const int f = face_order[static_cast<size_t>(m)];
        for (int k = 0; k < 3; ++k) ordered.F(m, k) = new_index[static_cast<size_t>(mesh.F(f, k))];
      }
    });
  }
  std::vector<double>& face_epsilon_squared = prepared->face_epsilon_squared;
  if (!options.face_epsilon_squared.empty()) {
    face_epsilon_squared.resize(static_cast<size_t>(nf));
    for (int m = 0; m < nf; ++m) {
      face_epsilon_squared[static_cast<size_t>(m)] =
          options.face_epsilon_squared[static_cast<size_t>(face_order[static_cast<size_t>(m)])];
    }
  }
  prepared->energy = std::make_unique<SmoothingEnergy>(ordered, information, options.prior_weight, *potential,
                                                       face_epsilon_squared.empty() ? nullptr : &face_epsilon_squared);
  if (options.robust_data_nu > 0) prepared->energy->SetRobustData(options.robust_data_nu);
  summary->inactive_faces = prepared->energy->num_inactive_faces();
  summary->memory_bytes += prepared->energy->MemoryBytes() + sizeof(double) * static_cast<size_t>(ordered.V.size()) +
                           sizeof(int) * (static_cast<size_t>(ordered.F.size()) + static_cast<size_t>(nv)) +
                           sizeof(double) * face_epsilon_squared.size();
  return prepared;
}

Mesh SmoothWithin(const NoisyMesh& noisy, const SmoothOptions& options, Clock::time_point deadline,
                  SmoothSummary* summary_out);

// The caller's summary gets `summary` with the whole call's time and the work done before the last solve.
Mesh Finish(Mesh result, SmoothSummary summary, Clock::time_point start, double earlier_work,
            SmoothSummary* summary_out) {
  summary.coarse_work += earlier_work;
  summary.time_s = Seconds(start);
  if (summary_out != nullptr) *summary_out = std::move(summary);
  return result;
}

}  // namespace

SmoothTolerance ParseSmoothTolerance(const std::string& name) {
  if (name == "fast") return SmoothTolerance::kFast;
  if (name == "default") return SmoothTolerance::kDefault;
  if (name == "tight") return SmoothTolerance::kTight;
  RB_FAIL("unknown tolerance '", name, "' (expected fast, default or tight)");
}

std::string SmoothToleranceName(SmoothTolerance tolerance) {
  switch (tolerance) {
    case SmoothTolerance::kFast:
      return "fast";
    case SmoothTolerance::kDefault:
      return "default";
    case SmoothTolerance::kTight:
      return "tight";
  }
  return "default";
}

std::string SmoothTerminationName(SmoothTermination termination) {
  switch (termination) {
    case SmoothTermination::kEnergyConverged:
      return "energy converged";
    case SmoothTermination::kGradientConverged:
      return "gradient converged";
    case SmoothTermination::kOptimalityGapConverged:
      return "converged (optimality gap)";
    case SmoothTermination::kMaxIterations:
      return "iteration limit";
    case SmoothTermination::kNoProgress:
      return "no further decrease (line search)";
    case SmoothTermination::kTimeLimit:
      return "time limit";
    case SmoothTermination::kNothingToDo:
      return "nothing to do";
  }
  return "unknown";
}

void SmoothOptions::Check() const {
  RB_CHECK(sqrt_epsilon_squared > 0 && sqrt_epsilon_squared <= 4, "smooth: sqrt_epsilon_squared ",
           sqrt_epsilon_squared, " is outside (0, 4]");
  RB_CHECK(cauchy_scale > 0 && cauchy_scale <= 2, "smooth: cauchy_scale ", cauchy_scale, " is outside (0, 2]");
  RB_CHECK(prior_weight >= 0 && prior_weight <= 1e6, "smooth: prior_weight ", prior_weight, " is outside [0, 1e6]");
  RB_CHECK(max_iterations >= 0 && max_iterations <= 10000000, "smooth: max_iterations ", max_iterations,
           " is outside [0, 1e7]");
  RB_CHECK(energy_tolerance >= 0 && energy_tolerance < 1, "smooth: energy_tolerance ", energy_tolerance,
           " is outside [0, 1)");
  RB_CHECK(line_search_c2 == 0 || (line_search_c2 > 0 && line_search_c2 < 1), "smooth: line_search_c2 ",
           line_search_c2, " is outside (0, 1) (0: automatic)");
  RB_CHECK(epsilon_continuation_stages >= -1 && epsilon_continuation_stages <= 6,
           "smooth: epsilon_continuation_stages ", epsilon_continuation_stages, " is outside [-1, 6]");
  RB_CHECK(gap_tolerance >= 0 && gap_tolerance < 1, "smooth: gap_tolerance ", gap_tolerance, " is outside [0, 1)");
  RB_CHECK(robust_data_nu >= 0 && robust_data_nu <= 1e6, "smooth: robust_data_nu ", robust_data_nu,
           " is outside {0} ∪ (0, 1e6]");
  RB_CHECK(face_epsilon_squared.empty() || (prior == PriorKind::kSqrt && potential == nullptr),
           "smooth: face_epsilon_squared needs the built-in square-root prior");
  RB_CHECK(num_threads >= 0 && num_threads <= 1024, "smooth: num_threads ", num_threads, " is outside [0, 1024]");
  RB_CHECK(time_limit_s >= 0 && time_limit_s <= kMaxSmoothTimeLimitS, "smooth: time_limit_s ", time_limit_s,
           " is outside [0, ", kMaxSmoothTimeLimitS, "]");
}

std::string SmoothSummary::BriefReport() const {
  std::string out;
  char line[512];
  if (adaptive_epsilon_used) {
    const AdaptiveEpsilonSummary& a = adaptive;
    std::snprintf(line, sizeof(line), "%d iterations, %d evaluations, %.3f s, rules %.3f s", a.prepass_iterations,
                  a.prepass_evaluations, a.prepass_time_s, a.time_s - a.prepass_time_s);
    const std::string prepass = line;
    if (a.per_face) {
      std::snprintf(line, sizeof(line),
                    "adaptive:   per-face eps2 p10 %.3g, median %.3g, p90 %.3g (curved: gate %.3g; fast pre-pass %s; "
                    "final solve started from it)\n",
                    a.p10_epsilon_squared, a.median_epsilon_squared, a.p90_epsilon_squared,
                    a.gate_median_epsilon_squared, prepass.c_str());
    } else {
      std::snprintf(line, sizeof(line),
                    "adaptive:   global eps2 kept (piecewise flat: gate %.3g < %.3g; fast pre-pass %s)\n",
                    a.gate_median_epsilon_squared, AutoAdaptiveEpsilonOptions{}.min_gate_median_epsilon_squared,
                    prepass.c_str());
    }
    out += line;
  }
  if (pixel_stride > 1) {
    std::snprintf(line, sizeof(line), "stride:     pixel grid step %g: prior weight beta %.4g (the given beta / %g)\n",
                  pixel_stride, prior_weight, std::min(pixel_stride, kMaxStrideForPriorWeight));
    out += line;
  }
  if (levels > 1 || continuation_stages > 0) {
    std::string what;
    if (continuation_stages > 0) what = StrCat(continuation_stages, " eps continuation stage(s)");
    if (levels > 1) what += StrCat(what.empty() ? "" : ", ", levels, " grid levels (coarse to fine)");
    std::snprintf(line, sizeof(line), "earlier:    %s: %.1f input evaluations before the final solve\n", what.c_str(),
                  coarse_work);
    out += line;
  }
  std::snprintf(line, sizeof(line), "summary:    %d iterations, %d evaluations, %.3f s (setup %.3f s), %s\n",
                iterations, evaluations, time_s, setup_time_s, SmoothTerminationName(termination).c_str());
  out += line;
  if (std::isfinite(remaining_decrease) && !energy.empty()) {
    std::snprintf(line, sizeof(line), "distance:   E - E* estimated %.3g (%.2g of the energy, from the rate of decrease)\n",
                  remaining_decrease, remaining_decrease / std::max(std::abs(energy.back()), 1e-300));
    out += line;
  }
  if (!energy.empty()) {
    std::snprintf(line, sizeof(line), "energy:     %.6g -> %.6g (data %.6g, prior %.6g)\n", energy.front(),
                  energy.back(), data_energy, prior_energy);
    out += line;
  }
  if (inactive_faces > 0) {
    std::snprintf(line, sizeof(line), "degenerate: %d zero-area faces left out of the prior\n", inactive_faces);
    out += line;
  }
  for (const std::string& notice : notices) out += "notice:     " + notice + "\n";
  return out;
}

bool InformationFromCovariance(const Eigen::Matrix3d& c, Eigen::Matrix3d* information) {
  if (c(0, 0) > 0 && std::isfinite(c(0, 0)) && c(0, 0) == c(1, 1) && c(1, 1) == c(2, 2) && c(0, 1) == 0 &&
      c(1, 0) == 0 && c(0, 2) == 0 && c(2, 0) == 0 && c(1, 2) == 0 && c(2, 1) == 0) {
    *information = Eigen::Matrix3d::Identity() * (0.5 / c(0, 0));  // σ² I (every generic mesh)
    return true;
  }
  if (!c.allFinite()) return false;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(0.5 * (c + c.transpose()));
  const Eigen::Vector3d values = solver.eigenvalues();
  if (solver.info() != Eigen::Success || !(values.maxCoeff() > 0)) return false;
  if (values.minCoeff() < -1e-6 * values.maxCoeff()) return false;  // indefinite: no covariance
  *information = solver.eigenvectors() * (0.5 * values.cwiseMax(1e-6 * values.maxCoeff()).cwiseInverse()).asDiagonal() *
                 solver.eigenvectors().transpose();
  return true;
}

Eigen::Matrix3d InformationFromCovariance(const Eigen::Matrix3d& covariance) {
  Eigen::Matrix3d information;
  RB_CHECK(InformationFromCovariance(covariance, &information),
           "covariance is not finite, positive semi-definite and non-zero");
  return information;
}

Mesh Smooth(const NoisyMesh& noisy, const SmoothOptions& options, SmoothSummary* summary_out) {
  options.Check();
  const Clock::time_point deadline =
      options.time_limit_s > 0
          ? Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(options.time_limit_s))
          : Clock::time_point::max();
  return SmoothWithin(noisy, options, deadline, summary_out);
}

namespace {

// The solves of one call on one prepared energy (information, order and adjacency built once per level): the
// `stages` ε-continuation stages at ε² · 10^s, s = stages … 1 (each warm-started from the one before; the built-in
// square-root prior only), then the solve at the caller's potential. The first solve that starts from the
// measurements runs coarse-to-fine over the pixel grid when `options.multilevel` applies (organized meshes):
// each coarse level solved from the prolongation of the coarser one's result (the coarsest from its
// measurements), then the input. Under a time limit, stage k of S ends by the k/(S+1) mark of the time the setup
// left, so the final solve keeps at least 1/(S+1) of it; stages not started when it ran out are skipped. The summary is
// the final solve's, with the earlier solves' work in coarse_work.
Mesh SolveStages(const NoisyMesh& noisy, const SmoothOptions& options, bool organized, int stages,
                 Clock::time_point deadline, SmoothSummary* summary_out) {
  const auto start = Clock::now();
  SmoothSummary summary;
  summary.prior_weight = options.prior_weight;
  tbb::task_arena arena(options.num_threads > 0 ? options.num_threads : tbb::task_arena::automatic);
  summary.num_threads = arena.max_concurrency();
  Mesh result;
  double earlier_work = 0;
  arena.execute([&] {
    const std::unique_ptr<PreparedEnergy> fine = Prepare(noisy, options, &summary);
    SmoothingEnergy& energy = *fine->energy;
    const int nv = energy.num_vertices();
    summary.setup_time_s = Seconds(start);
    result.F = noisy.mesh.F;
    if (nv == 0) {
      result.V = noisy.mesh.V;
      summary.termination = SmoothTermination::kNothingToDo;
      return;
    }
    Eigen::VectorXd x;  // the current state in the solver order (empty: the measurements)
    if (options.initial_positions != nullptr) x = fine->ToSolver(*options.initial_positions);
    // The pixel-grid hierarchy serves the coarse-to-fine start and the ray preconditioner's multigrid.
    const bool want_coarse_to_fine = options.multilevel && options.initial_positions == nullptr;
    const bool want_multigrid = options.precondition_rays && nv > kRayDirectVertices;
    std::vector<GridLevel> levels;
    if (organized && (want_coarse_to_fine || want_multigrid)) levels = BuildGridHierarchy(noisy);
    const bool coarse_to_fine = want_coarse_to_fine && !levels.empty();
    RayPreconditioner fine_ray(energy, ProlongationMatrices(levels, 0, fine->vertex_order));
    // Under a time limit the stages share what the setup left.
    const bool limited = deadline != Clock::time_point::max();
    const Clock::time_point solve_start = Clock::now();
    const Clock::duration left = limited ? deadline - solve_start : Clock::duration::zero();
    std::vector<SqrtPotential> stage_potentials;  // outlive their use by the energy
    stage_potentials.reserve(static_cast<size_t>(stages));
    // The caller's progress covers the whole call: solve k of the stages + 1 solves reports within
    // [k, k + 1] / (stages + 1) (they take similar times: docs/journal/smoothing-real-stereo.md, round 7), and
    // what is reported never goes back (each solve's own estimate moves both ways with the rate of decrease).
    double reported = 0;
    auto progress_of_solve = [&](int k) -> ProgressCallback {
      if (!options.progress) return nullptr;
      return [&reported, &options, k, stages](double fraction, std::string_view stage) {
        reported = std::max(reported, (k + std::clamp(fraction, 0.0, 1.0)) / (stages + 1));
        options.progress(reported, stage);
      };
    };
    for (int s = stages; s >= 0; --s) {
      const bool last = s == 0;
      if (!last && Clock::now() >= deadline) continue;
      SmoothOptions o = options;
      o.progress = progress_of_solve(stages - s);
      if (!last) {
        o.sqrt_epsilon_squared = std::min(4.0, options.sqrt_epsilon_squared * std::pow(10.0, s));
        stage_potentials.emplace_back(o.sqrt_epsilon_squared);
      }
      energy.SetPotential(last ? *fine->potential : stage_potentials.back());
      const Clock::time_point until =
          last || !limited ? deadline : solve_start + left * (stages - s + 1) / (stages + 1);
      double level_work = 0;
      if (x.size() == 0 && coarse_to_fine) {
        Vertices coarse_x;
        for (int k = static_cast<int>(levels.size()) - 1; k >= 0; --k) {
          SmoothOptions coarse = o;
          coarse.progress = nullptr;
          coarse.face_epsilon_squared.clear();
          coarse.initial_positions = nullptr;
          SmoothSummary cs;
          const std::unique_ptr<PreparedEnergy> level = Prepare(levels[static_cast<size_t>(k)].mesh, coarse, &cs);
          const bool coarsest = k + 1 == static_cast<int>(levels.size());
          const Eigen::VectorXd level_start = coarsest ? Eigen::VectorXd() : level->ToSolver(coarse_x);
          Problem problem(*level->energy);
          RayPreconditioner level_ray(*level->energy, ProlongationMatrices(levels, k + 1, level->vertex_order));
          const MinimiseResult r = Minimise(problem, coarse, until, &cs, coarsest ? nullptr : &level_start, &level_ray);
          level_work += problem.evaluations * static_cast<double>(level->energy->num_vertices()) / nv;
          const NoisyMesh& finer = k == 0 ? noisy : levels[static_cast<size_t>(k) - 1].mesh;
          coarse_x = ProlongPositions(levels[static_cast<size_t>(k)], finer, level->ToCaller(r.x));
        }
        x = fine->ToSolver(coarse_x);
        summary.levels = static_cast<int>(levels.size()) + 1;
      }
      Problem problem(energy);
      SmoothSummary stage_summary;
      MinimiseResult m =
          Minimise(problem, o, until, last ? &summary : &stage_summary, x.size() > 0 ? &x : nullptr, &fine_ray);
      x = std::move(m.x);
      if (!last) {
        earlier_work += problem.evaluations + level_work;
        ++summary.continuation_stages;
        continue;
      }
      summary.coarse_work = level_work;
      summary.evaluations = problem.evaluations;
      summary.data_energy = m.parts.data;
      summary.prior_energy = m.parts.prior;
    }
    summary.flipped_faces = energy.CountFoldedFaces(x);
    summary.input_flipped_faces = energy.CountFoldedFaces(energy.Measurements());
    result.V = fine->ToCaller(x);
  });
  return Finish(std::move(result), std::move(summary), start, earlier_work, summary_out);
}

// Smooth() with an absolute deadline shared by all its stages and levels.
Mesh SmoothWithin(const NoisyMesh& noisy, const SmoothOptions& caller_options, Clock::time_point deadline,
                  SmoothSummary* summary_out) {
  const auto start = Clock::now();
  const bool organized = noisy.has_covariance() && noisy.mesh.num_vertices() > 0 &&
                         noisy.pixel.rows() == noisy.mesh.num_vertices();
  SmoothOptions options = caller_options;
  if (organized && options.tolerance == SmoothTolerance::kDefault && options.gap_tolerance == 0) {
    options.gap_tolerance = kOrganizedGapTolerance;  // organized meshes stop closer to the optimum by default
  }
  std::string not_a_grid;
  const double grid_step = organized ? PixelGridStep(noisy, &not_a_grid) : 0.0;
  const double stride = options.prior_weight_per_stride ? grid_step : 0.0;
  if (stride > 0) options.prior_weight /= std::clamp(stride, 1.0, kMaxStrideForPriorWeight);
  const int continuation_stages = options.epsilon_continuation_stages >= 0
                                      ? options.epsilon_continuation_stages
                                      : (organized && options.initial_positions == nullptr ? 3 : 0);
  // Continuation asked for explicitly is a global-ε path: it takes precedence over the per-face ε of the
  // adaptive rule (whose pre-pass and final solve would otherwise drop it).
  if (options.adaptive_epsilon && !organized && options.prior == PriorKind::kSqrt && options.potential == nullptr &&
      options.face_epsilon_squared.empty() && options.initial_positions == nullptr &&
      options.epsilon_continuation_stages <= 0) {
    SmoothOptions plain = options;
    plain.adaptive_epsilon = false;
    AdaptiveEpsilonSummary adaptive;
    SmoothSummary summary;
    Mesh result = SmoothAdaptiveEpsilon(noisy, plain, AutoAdaptiveEpsilonOptions{}, &adaptive, &summary);
    summary.adaptive_epsilon_used = true;
    summary.adaptive = adaptive;
    return Finish(std::move(result), std::move(summary), start, 0, summary_out);
  }
  const bool continuation = continuation_stages > 0 && options.prior == PriorKind::kSqrt &&
                            options.potential == nullptr && options.face_epsilon_squared.empty();
  Mesh result = SolveStages(noisy, options, organized, continuation ? continuation_stages : 0, deadline, summary_out);
  if (summary_out != nullptr) {
    summary_out->pixel_stride = stride;
    if (options.epsilon_continuation_stages > 0 && !continuation) {
      summary_out->notices.push_back(
          StrCat("no epsilon continuation: it needs the square-root prior with one global "
                 "epsilon (the ",
                 continuation_stages, " stages asked for were not run)"));
    }
    if (organized && grid_step == 0) {
      summary_out->notices.push_back(StrCat("the pixel positions are not one grid (", not_a_grid,
                                            "): smoothed without the pixel-stride prior weight and the grid levels"));
    }
  }
  return result;
}

}  // namespace

int StartFromEarlierResult(const NoisyMesh& noisy,
                           const Eigen::Matrix<float, Eigen::Dynamic, 2, Eigen::RowMajor>& previous_pixel,
                           const Vertices& previous_positions, double max_sigmas, Vertices* start) {
  RB_CHECK(previous_pixel.rows() == previous_positions.rows(), "warm start: ", previous_pixel.rows(),
           " earlier pixels for ", previous_positions.rows(), " earlier positions");
  RB_CHECK(max_sigmas > 0.0 && std::isfinite(max_sigmas), "warm start: max_sigmas ", max_sigmas, " must be > 0");
  *start = noisy.mesh.V;
  const int nv = noisy.mesh.num_vertices();
  if (noisy.pixel.rows() != nv || !noisy.has_covariance() || previous_pixel.rows() == 0) return 0;
  auto key = [](float x, float y) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(std::lround(x))) << 32) |
           static_cast<std::uint32_t>(std::lround(y));
  };
  auto usable = [](float x, float y) {
    return std::isfinite(x) && std::isfinite(y) && x >= 0 && y >= 0 && x < 4e9f && y < 4e9f;
  };
  std::unordered_map<std::uint64_t, int> earlier;
  earlier.reserve(static_cast<size_t>(previous_pixel.rows()));
  for (int j = 0; j < previous_pixel.rows(); ++j) {
    const float x = previous_pixel(j, 0), y = previous_pixel(j, 1);
    if (usable(x, y)) earlier.emplace(key(x, y), j);
  }
  const double gate = max_sigmas * max_sigmas;
  int taken = 0;
  for (int i = 0; i < nv; ++i) {
    if (!usable(noisy.pixel(i, 0), noisy.pixel(i, 1))) continue;
    const auto found = earlier.find(key(noisy.pixel(i, 0), noisy.pixel(i, 1)));
    if (found == earlier.end()) continue;
    const Eigen::Vector3d p = previous_positions.row(found->second).transpose();
    const Eigen::Vector3d r = p - noisy.mesh.V.row(i).transpose();
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(noisy.covariance[static_cast<size_t>(i)]);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) continue;
    const double q = r.dot(ldlt.solve(r));
    if (!(q <= gate)) continue;  // also skips NaN
    start->row(i) = p.transpose();
    ++taken;
  }
  return taken;
}

}  // namespace rangebayes
