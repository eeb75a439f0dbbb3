#include "bayes/potential.h"

#include <cmath>

#include "core/error.h"

namespace rangebayes {

void Potential::EvaluateWeight(double d, double* value, double* weight) const {
  constexpr double kSmallest = 1e-6;
  double derivative = 0;
  Evaluate(d, value, &derivative);
  if (d >= kSmallest) {
    *weight = derivative / d;
  } else {
    double v = 0;
    Evaluate(kSmallest, &v, &derivative);
    *weight = derivative / kSmallest;
  }
}

double Potential::Value(double d) const {
  double value = 0, derivative = 0;
  Evaluate(d, &value, &derivative);
  return value;
}

double Potential::Derivative(double d) const {
  double value = 0, derivative = 0;
  Evaluate(d, &value, &derivative);
  return derivative;
}

SqrtPotential::SqrtPotential(double epsilon_squared) : epsilon_squared_(epsilon_squared) {
  RB_CHECK(epsilon_squared > 0 && std::isfinite(epsilon_squared), "sqrt potential: epsilon_squared ",
           epsilon_squared, " must be positive");
}

void SqrtPotential::Evaluate(double d, double* value, double* derivative) const {
  *value = std::sqrt(d * d + epsilon_squared_);
  *derivative = d / *value;
}

void SqrtPotential::EvaluateWeight(double d, double* value, double* weight) const {
  *value = std::sqrt(d * d + epsilon_squared_);
  *weight = 1.0 / *value;
}

std::string SqrtPotential::Name() const { return StrCat("sqrt(eps2=", epsilon_squared_, ")"); }

void QuadraticPotential::Evaluate(double d, double* value, double* derivative) const {
  *value = d * d;
  *derivative = 2 * d;
}

void QuadraticPotential::EvaluateWeight(double d, double* value, double* weight) const {
  *value = d * d;
  *weight = 2;
}

std::string QuadraticPotential::Name() const { return "quadratic"; }

CauchyPotential::CauchyPotential(double scale) : scale_(scale) {
  RB_CHECK(scale > 0 && std::isfinite(scale), "cauchy potential: scale ", scale, " must be positive");
}

void CauchyPotential::Evaluate(double d, double* value, double* derivative) const {
  const double c2 = scale_ * scale_;
  *value = std::log1p(d * d / c2);
  *derivative = 2 * d / (c2 + d * d);
}

void CauchyPotential::EvaluateWeight(double d, double* value, double* weight) const {
  const double c2 = scale_ * scale_;
  *value = std::log1p(d * d / c2);
  *weight = 2 / (c2 + d * d);
}

std::string CauchyPotential::Name() const { return StrCat("cauchy(c=", scale_, ")"); }

PriorKind ParsePriorKind(const std::string& name) {
  if (name == "sqrt") return PriorKind::kSqrt;
  if (name == "quadratic") return PriorKind::kQuadratic;
  if (name == "cauchy") return PriorKind::kCauchy;
  RB_FAIL("unknown prior '", name, "' (expected sqrt, quadratic or cauchy)");
}

std::string PriorKindName(PriorKind kind) {
  switch (kind) {
    case PriorKind::kSqrt:
      return "sqrt";
    case PriorKind::kQuadratic:
      return "quadratic";
    case PriorKind::kCauchy:
      return "cauchy";
  }
  return "sqrt";
}

}  // namespace rangebayes
