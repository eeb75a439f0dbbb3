// A learnable pairwise potential φ_θ(d) over the normal difference d = ‖n_s − n_t‖ ∈ [0, 2] (paper §5.1).
#pragma once

#include <Eigen/Core>
#include <string>

#include "bayes/potential.h"

namespace rangebayes {

struct SplinePotentialOptions {
  int num_knots = 16;             // N, knots equally spaced over [0, 2]; range [3, 256]
  double epsilon_squared = 1e-4;  // ε² of the square-root base sqrt(d² + ε²) (the paper's offset); range (0, 1]
  void Check() const;
};

// φ_θ(d) = b(d) + S(d), b(d) = sqrt(d² + ε²) the paper's square-root potential, S the cubic spline through the
// residuals r_j = θ_j − b(t_j) at the knots t_j = 2j/(N−1), clamped to zero slope at both ends.
//
// So θ_j is exactly the value φ(t_j) at knot j (the paper's parameters), and φ matches the square root's value
// and slope at d = 0 and d = 2 as the paper clamps it: θ_0 = b(0) and θ_{N−1} = b(2) are fixed, the N − 2
// interior values are free. Between knots the curve follows the square root plus a cubic correction (rather
// than a plain cubic), so θ_j = b(t_j) reproduces the square-root potential exactly, including its sharp
// bend below the first knot that a plain cubic over a knot spacing of 2/(N−1) cannot represent.
// φ is linear in θ; ∂φ/∂θ_j does not depend on θ.
class SplinePotential final : public Potential {
 public:
  // The square-root potential (θ_j = b(t_j)).
  explicit SplinePotential(const SplinePotentialOptions& options = {});
  // θ has N entries; its first and last must equal b(0) and b(2) (within 1e-9), else Error.
  SplinePotential(const SplinePotentialOptions& options, const Eigen::VectorXd& theta);

  const SplinePotentialOptions& options() const { return options_; }
  int num_knots() const { return options_.num_knots; }
  const Eigen::VectorXd& theta() const { return theta_; }
  // Replaces θ (same N; ends fixed as above).
  void SetTheta(const Eigen::VectorXd& theta);

  double KnotPosition(int j) const { return j * spacing_; }
  // The square-root base b(d) and its derivative.
  double Base(double d) const;
  double BaseDerivative(double d) const;

  // φ(d) and dφ/dd (Potential::Value and Derivative give one of them); d is clamped to [0, 2].
  void Evaluate(double d, double* value, double* derivative) const override;
  // "spline(N=16,eps2=0.0001)"
  std::string Name() const override;

  // ∂φ(d)/∂θ_j for all j (N entries; 0 for the fixed ends), and ∂²φ/∂d∂θ_j.
  void ParameterGradient(double d, Eigen::VectorXd* dvalue_dtheta, Eigen::VectorXd* dderivative_dtheta) const;
  // The same for one knot j (cardinal basis function c_j and its slope).
  void Basis(int j, double d, double* value, double* derivative) const;

  // θ of the square-root potential for these options (the starting point of learning).
  static Eigen::VectorXd SquareRootTheta(const SplinePotentialOptions& options);

 private:
  void Refresh();
  // Interval index k and local coordinate u ∈ [0, 1] of d.
  void Locate(double d, int* k, double* u) const;

  SplinePotentialOptions options_;
  double spacing_ = 0.0;
  Eigen::VectorXd theta_;
  Eigen::VectorXd residual_;           // r_j = θ_j − b(t_j)
  Eigen::VectorXd second_derivative_;  // M = G r
  Eigen::MatrixXd residual_to_m_;      // G, N×N: knot second derivatives of S from the residuals
};

// The "second well near d = √2" of the paper's learned potential for right angles, as a test on the curve.
// φ is sampled every sample_step on [shoulder_min_d, 2]. A well is a strict local minimum d* of the samples in
// [well_min_d, well_max_d] whose value lies below (by more than min_depth) both the maximum of φ on
// [shoulder_min_d, d*] (a barrier on its left) and φ(right_d) (it rises again to the right); the deepest one is
// reported. A monotone φ never passes (it has no local minimum).
struct SecondWellOptions {
  double shoulder_min_d = 0.9;  // left end of the barrier search; [0, well_min_d]
  double well_min_d = 1.2;      // window of the well; 0 < well_min_d < well_max_d < right_d ≤ 2
  double well_max_d = 1.6;
  double right_d = 1.8;       // φ must be higher here than at the well
  double min_depth = 1e-6;    // strictness margin in φ units (rounding); ≥ 0
  double sample_step = 1e-3;  // sampling of d; (0, 0.1]
  void Check() const;
};

struct SecondWell {
  bool found = false;
  double well_d = 0, well_value = 0;        // d* and φ(d*) (no local minimum: the window's lowest point)
  double barrier_d = 0, barrier_value = 0;  // argmax and max of φ on [shoulder_min_d, d*]
  double right_value = 0;                   // φ(right_d)
  double depth = 0;                         // min(barrier_value, right_value) − well_value (> min_depth: found)
};

SecondWell FindSecondWell(const Potential& potential, const SecondWellOptions& options = {});

}  // namespace rangebayes
