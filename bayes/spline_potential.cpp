#include "bayes/spline_potential.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/error.h"

namespace rangebayes {

void SplinePotentialOptions::Check() const {
  RB_CHECK(num_knots >= 3 && num_knots <= 256, "spline potential: num_knots must be in [3, 256], got ", num_knots);
  RB_CHECK(epsilon_squared > 0.0 && epsilon_squared <= 1.0, "spline potential: epsilon_squared must be in (0, 1], got ",
           epsilon_squared);
}

SplinePotential::SplinePotential(const SplinePotentialOptions& options)
    : SplinePotential(options, SquareRootTheta(options)) {}

SplinePotential::SplinePotential(const SplinePotentialOptions& options, const Eigen::VectorXd& theta)
    : options_(options) {
  options_.Check();
  const int n = options_.num_knots;
  spacing_ = 2.0 / (n - 1);
  // Clamped cubic spline (zero end slopes) in second-derivative form:
  //   2 M_0 + M_1 = 6/h² (r_1 − r_0),  M_{k−1} + 4 M_k + M_{k+1} = 6/h² (r_{k+1} − 2 r_k + r_{k−1}),
  //   M_{N−2} + 2 M_{N−1} = −6/h² (r_{N−1} − r_{N−2}).
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(n, n);
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(n, n);
  const double s = 6.0 / (spacing_ * spacing_);
  a(0, 0) = 2.0;
  a(0, 1) = 1.0;
  b(0, 0) = -s;
  b(0, 1) = s;
  for (int k = 1; k + 1 < n; ++k) {
    a(k, k - 1) = 1.0;
    a(k, k) = 4.0;
    a(k, k + 1) = 1.0;
    b(k, k - 1) = s;
    b(k, k) = -2.0 * s;
    b(k, k + 1) = s;
  }
  a(n - 1, n - 2) = 1.0;
  a(n - 1, n - 1) = 2.0;
  b(n - 1, n - 2) = s;
  b(n - 1, n - 1) = -s;
  residual_to_m_ = a.partialPivLu().solve(b);
  SetTheta(theta);
}

Eigen::VectorXd SplinePotential::SquareRootTheta(const SplinePotentialOptions& options) {
  options.Check();
  const int n = options.num_knots;
  Eigen::VectorXd theta(n);
  for (int j = 0; j < n; ++j) {
    const double t = 2.0 * j / (n - 1);
    theta[j] = std::sqrt(t * t + options.epsilon_squared);
  }
  return theta;
}

void SplinePotential::SetTheta(const Eigen::VectorXd& theta) {
  const int n = options_.num_knots;
  RB_CHECK(theta.size() == n, "spline potential: theta has ", theta.size(), " values, num_knots is ", n);
  RB_CHECK(theta.allFinite(), "spline potential: theta has a non-finite value");
  RB_CHECK(std::abs(theta[0] - Base(0.0)) < 1e-9 && std::abs(theta[n - 1] - Base(2.0)) < 1e-9,
           "spline potential: the end values are clamped to the square root: theta[0] must be ", Base(0.0),
           " and theta[N-1] ", Base(2.0), ", got ", theta[0], " and ", theta[n - 1]);
  theta_ = theta;
  Refresh();
}

void SplinePotential::Refresh() {
  const int n = options_.num_knots;
  residual_.resize(n);
  for (int j = 0; j < n; ++j) residual_[j] = theta_[j] - Base(KnotPosition(j));
  // The ends are exactly zero by construction; rounding must not leak into the clamped boundary.
  residual_[0] = 0.0;
  residual_[n - 1] = 0.0;
  second_derivative_ = residual_to_m_ * residual_;
}

double SplinePotential::Base(double d) const { return std::sqrt(d * d + options_.epsilon_squared); }

double SplinePotential::BaseDerivative(double d) const { return d / std::sqrt(d * d + options_.epsilon_squared); }

void SplinePotential::Locate(double d, int* k, double* u) const {
  const double x = std::clamp(d, 0.0, 2.0) / spacing_;
  int index = static_cast<int>(std::floor(x));
  index = std::clamp(index, 0, options_.num_knots - 2);
  *k = index;
  *u = x - index;
}

void SplinePotential::Evaluate(double d, double* value, double* derivative) const {
  const double dc = std::clamp(d, 0.0, 2.0);
  int k = 0;
  double u = 0.0;
  Locate(dc, &k, &u);
  const double h = spacing_;
  const double v = 1.0 - u;
  const double mk = second_derivative_[k];
  const double mk1 = second_derivative_[k + 1];
  const double rk = residual_[k];
  const double rk1 = residual_[k + 1];
  const double spline = v * rk + u * rk1 + h * h / 6.0 * ((v * v * v - v) * mk + (u * u * u - u) * mk1);
  const double slope = (rk1 - rk) / h + h / 6.0 * (-(3.0 * v * v - 1.0) * mk + (3.0 * u * u - 1.0) * mk1);
  if (value != nullptr) *value = Base(dc) + spline;
  if (derivative != nullptr) *derivative = BaseDerivative(dc) + slope;
}

std::string SplinePotential::Name() const {
  return StrCat("spline(N=", options_.num_knots, ",eps2=", options_.epsilon_squared, ")");
}

void SplinePotential::Basis(int j, double d, double* value, double* derivative) const {
  const int n = options_.num_knots;
  RB_CHECK(j >= 0 && j < n, "spline potential: knot ", j, " out of range [0, ", n, ")");
  if (j == 0 || j == n - 1) {
    if (value != nullptr) *value = 0.0;
    if (derivative != nullptr) *derivative = 0.0;
    return;
  }
  int k = 0;
  double u = 0.0;
  Locate(d, &k, &u);
  const double h = spacing_;
  const double v = 1.0 - u;
  const double gk = residual_to_m_(k, j);
  const double gk1 = residual_to_m_(k + 1, j);
  const double rk = (k == j) ? 1.0 : 0.0;
  const double rk1 = (k + 1 == j) ? 1.0 : 0.0;
  if (value != nullptr) {
    *value = v * rk + u * rk1 + h * h / 6.0 * ((v * v * v - v) * gk + (u * u * u - u) * gk1);
  }
  if (derivative != nullptr) {
    *derivative = (rk1 - rk) / h + h / 6.0 * (-(3.0 * v * v - 1.0) * gk + (3.0 * u * u - 1.0) * gk1);
  }
}

void SplinePotential::ParameterGradient(double d, Eigen::VectorXd* dvalue_dtheta,
                                        Eigen::VectorXd* dderivative_dtheta) const {
  const int n = options_.num_knots;
  if (dvalue_dtheta != nullptr) dvalue_dtheta->resize(n);
  if (dderivative_dtheta != nullptr) dderivative_dtheta->resize(n);
  for (int j = 0; j < n; ++j) {
    double value = 0.0;
    double derivative = 0.0;
    Basis(j, d, &value, &derivative);
    if (dvalue_dtheta != nullptr) (*dvalue_dtheta)[j] = value;
    if (dderivative_dtheta != nullptr) (*dderivative_dtheta)[j] = derivative;
  }
}

void SecondWellOptions::Check() const {
  RB_CHECK(shoulder_min_d >= 0 && shoulder_min_d <= well_min_d && well_min_d > 0 && well_min_d < well_max_d &&
               well_max_d < right_d && right_d <= 2,
           "second well: need 0 <= shoulder_min_d <= well_min_d < well_max_d < right_d <= 2, got ", shoulder_min_d,
           ", ", well_min_d, ", ", well_max_d, ", ", right_d);
  RB_CHECK(min_depth >= 0, "second well: min_depth must be >= 0, got ", min_depth);
  RB_CHECK(sample_step > 0 && sample_step <= 0.1, "second well: sample_step must be in (0, 0.1], got ", sample_step);
}

SecondWell FindSecondWell(const Potential& potential, const SecondWellOptions& options) {
  options.Check();
  const double h = options.sample_step;
  const int count = static_cast<int>(std::ceil((2.0 - options.shoulder_min_d) / h)) + 1;
  std::vector<double> d(count), value(count);
  for (int i = 0; i < count; ++i) {
    d[i] = std::min(2.0, options.shoulder_min_d + i * h);
    value[i] = potential.Value(d[i]);
  }
  const double right_value = potential.Value(options.right_d);
  // The deepest strict local minimum of the samples in the window, and (reported when there is none) the
  // window's lowest point, e.g. its left end for a monotone φ.
  SecondWell deepest, lowest;
  deepest.depth = -std::numeric_limits<double>::infinity();
  lowest.well_value = std::numeric_limits<double>::infinity();
  double barrier_value = -std::numeric_limits<double>::infinity(), barrier_d = options.shoulder_min_d;
  for (int i = 0; i < count; ++i) {
    if (value[i] > barrier_value) {
      barrier_value = value[i];
      barrier_d = d[i];
    }
    if (d[i] < options.well_min_d - 1e-12 || d[i] > options.well_max_d + 1e-12) continue;
    SecondWell here;
    here.well_d = d[i];
    here.well_value = value[i];
    here.barrier_d = barrier_d;
    here.barrier_value = barrier_value;
    here.right_value = right_value;
    here.depth = std::min(barrier_value, right_value) - value[i];
    const bool local_minimum = i > 0 && i + 1 < count && value[i] < value[i - 1] && value[i] <= value[i + 1];
    if (local_minimum && here.depth > deepest.depth) deepest = here;
    if (value[i] < lowest.well_value) lowest = here;
  }
  SecondWell result = std::isfinite(deepest.depth) ? deepest : lowest;
  result.found = std::isfinite(deepest.depth) && deepest.depth > options.min_depth;
  return result;
}

}  // namespace rangebayes
