// Pairwise potentials φ(d) of the smoothing prior over the normal difference d = ‖n_s − n_t‖ ∈ [0, 2] of two
// faces that share an edge (paper eq. 9–11, docs/design.md §3.1). The smoother sees only this interface, so any
// potential (the learned spline of bayes/spline_potential.h included) plugs in by deriving from Potential.
#pragma once

#include <memory>
#include <string>

namespace rangebayes {

class Potential {
 public:
  virtual ~Potential() = default;

  // φ(d) and dφ/dd for d ∈ [0, 2]. Must be finite there and differentiable for d > 0.
  virtual void Evaluate(double d, double* value, double* derivative) const = 0;

  // φ(d) and w(d) = φ'(d) / d, the factor the gradient needs (∂φ(‖n_t − n_s‖)/∂n_t = w · (n_t − n_s)); it stays
  // finite as d → 0 for every potential with φ'(0) = 0 or φ' ∝ d near 0. The default divides Evaluate's
  // derivative by d and, below d = 1e-6, uses d = 1e-6 (the limit φ''(0) for a smooth φ with φ'(0) = 0);
  // built-in potentials override it with the closed form.
  virtual void EvaluateWeight(double d, double* value, double* weight) const;

  // A short name for messages ("sqrt(eps2=0.0001)").
  virtual std::string Name() const = 0;

  double Value(double d) const;
  double Derivative(double d) const;
};

// φ(d) = sqrt(d² + ε²), the paper's default (it adds 1e-4 inside the root: ε² = 1e-4). Sub-linear growth keeps
// edges sharp; ε makes it differentiable at d = 0 and sets how quadratic it is for small normal differences.
class SqrtPotential final : public Potential {
 public:
  explicit SqrtPotential(double epsilon_squared = 1e-4);  // ε² > 0
  void Evaluate(double d, double* value, double* derivative) const override;
  void EvaluateWeight(double d, double* value, double* weight) const override;
  std::string Name() const override;
  double epsilon_squared() const { return epsilon_squared_; }

 private:
  double epsilon_squared_;
};

// φ(d) = d² (a Gaussian prior on normal differences): over-smooths edges; a baseline.
class QuadraticPotential final : public Potential {
 public:
  void Evaluate(double d, double* value, double* derivative) const override;
  void EvaluateWeight(double d, double* value, double* weight) const override;
  std::string Name() const override;
};

// φ(d) = log(1 + d² / c²) (Cauchy / Lorentzian, a heavy-tailed robust potential): quadratic below d ≈ c,
// logarithmic (bounded growth) above, so large normal differences (edges) cost almost nothing more.
class CauchyPotential final : public Potential {
 public:
  explicit CauchyPotential(double scale = 0.3);  // c > 0
  void Evaluate(double d, double* value, double* derivative) const override;
  void EvaluateWeight(double d, double* value, double* weight) const override;
  std::string Name() const override;
  double scale() const { return scale_; }

 private:
  double scale_;
};

enum class PriorKind { kSqrt, kQuadratic, kCauchy };

// "sqrt", "quadratic", "cauchy" (throws Error otherwise) and back.
PriorKind ParsePriorKind(const std::string& name);
std::string PriorKindName(PriorKind kind);

}  // namespace rangebayes
