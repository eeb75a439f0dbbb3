#include "bayes/spline_potential.h"

#include <gtest/gtest.h>

#include <cmath>
#include <initializer_list>
#include <random>

#include "core/error.h"

namespace rangebayes {
namespace {

// A θ away from the square root, with the clamped ends kept.
Eigen::VectorXd WigglyTheta(const SplinePotentialOptions& options, unsigned seed) {
  Eigen::VectorXd theta = SplinePotential::SquareRootTheta(options);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> jitter(-0.3, 0.3);
  for (int j = 1; j + 1 < theta.size(); ++j) theta[j] += jitter(rng);
  return theta;
}

TEST(SplinePotential, DefaultIsTheSquareRoot) {
  const SplinePotential phi;
  for (double d = 0.0; d <= 2.0; d += 0.0137) {
    const double expected = std::sqrt(d * d + 1e-4);
    // Exact up to rounding: the residual spline is identically zero.
    EXPECT_NEAR(phi.Value(d), expected, 1e-12) << d;
    EXPECT_NEAR(phi.Derivative(d), d / expected, 1e-12) << d;
  }
}

TEST(SplinePotential, InterpolatesKnotsAndKeepsSquareRootEnds) {
  SplinePotentialOptions options;
  options.num_knots = 9;
  const SplinePotential phi(options, WigglyTheta(options, 3));
  for (int j = 0; j < options.num_knots; ++j) {
    EXPECT_NEAR(phi.Value(phi.KnotPosition(j)), phi.theta()[j], 1e-12) << j;
  }
  EXPECT_NEAR(phi.Value(0.0), std::sqrt(1e-4), 1e-12);
  EXPECT_NEAR(phi.Value(2.0), std::sqrt(4.0 + 1e-4), 1e-12);
  EXPECT_NEAR(phi.Derivative(0.0), 0.0, 1e-12);
  EXPECT_NEAR(phi.Derivative(2.0), 2.0 / std::sqrt(4.0 + 1e-4), 1e-12);
}

TEST(SplinePotential, SlopeMatchesFiniteDifferences) {
  const SplinePotentialOptions options;
  const SplinePotential phi(options, WigglyTheta(options, 7));
  const double step = 1e-6;
  // Away from d = 0, where the base sqrt(d² + 1e-4) bends on a 1e-2 scale.
  for (double d = 0.05; d < 1.99; d += 0.0311) {
    const double numeric = (phi.Value(d + step) - phi.Value(d - step)) / (2 * step);
    // Central differences of a C² function with |φ'''| ≲ 1e3 here: error ≲ step² · 1e3 plus rounding 1e-16/step.
    EXPECT_NEAR(phi.Derivative(d), numeric, 1e-7) << d;
  }
}

TEST(SplinePotential, ParameterGradientMatchesFiniteDifferences) {
  SplinePotentialOptions options;
  options.num_knots = 12;
  const Eigen::VectorXd theta = WigglyTheta(options, 11);
  const SplinePotential phi(options, theta);
  const double step = 1e-5;
  for (double d : {0.0, 0.031, 0.2, 0.77, 1.0, 1.4142, 1.9, 2.0}) {
    Eigen::VectorXd dvalue;
    Eigen::VectorXd dslope;
    phi.ParameterGradient(d, &dvalue, &dslope);
    for (int j = 1; j + 1 < options.num_knots; ++j) {
      Eigen::VectorXd plus = theta;
      Eigen::VectorXd minus = theta;
      plus[j] += step;
      minus[j] -= step;
      const SplinePotential p(options, plus);
      const SplinePotential m(options, minus);
      // φ is linear in θ, so central differences are exact up to rounding (1e-16 / 1e-5).
      EXPECT_NEAR(dvalue[j], (p.Value(d) - m.Value(d)) / (2 * step), 1e-9) << d << " " << j;
      EXPECT_NEAR(dslope[j], (p.Derivative(d) - m.Derivative(d)) / (2 * step), 1e-9) << d << " " << j;
    }
    EXPECT_EQ(dvalue[0], 0.0);
    EXPECT_EQ(dvalue[options.num_knots - 1], 0.0);
  }
}

TEST(SplinePotential, RejectsUnclampedEnds) {
  const SplinePotentialOptions options;
  Eigen::VectorXd theta = SplinePotential::SquareRootTheta(options);
  theta[0] += 0.1;
  EXPECT_THROW(SplinePotential(options, theta), Error);
  EXPECT_THROW(SplinePotential(options, Eigen::VectorXd::Zero(3)), Error);
  SplinePotentialOptions bad;
  bad.num_knots = 2;
  EXPECT_THROW(bad.Check(), Error);
}

Eigen::VectorXd Theta16(std::initializer_list<double> values) {
  Eigen::VectorXd theta(static_cast<Eigen::Index>(values.size()));
  int j = 0;
  for (double v : values) theta[j++] = v;
  return theta;
}

TEST(SecondWell, SquareRootAndAShoulderHaveNone) {
  const SplinePotentialOptions options;
  const SecondWell root = FindSecondWell(SplinePotential(options));
  EXPECT_FALSE(root.found);
  EXPECT_NEAR(root.well_d, 1.2, 1e-12);  // increasing: the window's left end
  EXPECT_LE(root.depth, 0.0);
  // The mixture prior of BENCHMARKS.md (session 2, 400 fixed-step iterations): φ − sqrt dips around 1.5 but φ
  // itself keeps rising, so no well.
  const Eigen::VectorXd shoulder = Theta16({0.0100, 0.1891, 0.3930, 0.5794, 0.7282, 0.8451, 0.9368, 1.0235, 1.1272,
                                            1.2582, 1.3536, 1.4731, 1.6067, 1.7564, 1.8875, 2.0000});
  Eigen::VectorXd clamped = shoulder;  // the ends exactly b(0), b(2) (printed to 4 digits)
  clamped[0] = SplinePotential::SquareRootTheta(options)[0];
  clamped[15] = SplinePotential::SquareRootTheta(options)[15];
  const SplinePotential phi(options, clamped);
  EXPECT_FALSE(FindSecondWell(phi).found);
  EXPECT_FALSE(FindSecondWell(phi, SecondWellOptions{.min_depth = 0}).found);
}

TEST(SecondWell, FindsADipNearRoot2) {
  const SplinePotentialOptions options;
  Eigen::VectorXd theta = SplinePotential::SquareRootTheta(options);
  // Knots at 1.200 and 1.333 (indices 9, 10): φ(1.2) = 1.35 above φ(1.333) = 1.20, then the square root's 1.47.
  theta[9] = 1.35;
  theta[10] = 1.20;
  const SecondWell well = FindSecondWell(SplinePotential(options, theta));
  EXPECT_TRUE(well.found);
  EXPECT_GT(well.well_d, 1.25);
  EXPECT_LT(well.well_d, 1.45);
  EXPECT_LT(well.barrier_d, well.well_d);
  EXPECT_GT(well.depth, 0.05);
  // The same dip made shallower than the margin does not count.
  EXPECT_FALSE(FindSecondWell(SplinePotential(options, theta), SecondWellOptions{.min_depth = 1.0}).found);
}

// A local well whose bottom lies above φ(1.2) still counts: φ rises to a barrier at 1.33, falls to a minimum
// near 1.45 and rises again.
TEST(SecondWell, FindsALocalWellAboveTheWindowStart) {
  const SplinePotentialOptions options;
  Eigen::VectorXd theta = SplinePotential::SquareRootTheta(options);
  theta[10] = 1.45;  // d = 1.333
  theta[11] = 1.30;  // d = 1.467
  const SplinePotential phi(options, theta);
  const SecondWell well = FindSecondWell(phi);
  EXPECT_TRUE(well.found);
  EXPECT_GT(well.well_d, 1.35);
  EXPECT_LT(well.well_d, 1.55);
  EXPECT_GT(well.well_value, phi.Value(1.2));
  EXPECT_GT(well.barrier_d, 1.25);
  EXPECT_LT(well.barrier_d, well.well_d);
}

TEST(SecondWell, IgnoresAWellElsewhere) {
  const SplinePotentialOptions options;
  Eigen::VectorXd theta = SplinePotential::SquareRootTheta(options);
  theta[4] = 0.2;  // a dip at d = 0.533 (below the window), φ increasing from 0.9 on
  EXPECT_FALSE(FindSecondWell(SplinePotential(options, theta)).found);
  theta = SplinePotential::SquareRootTheta(options);
  theta[14] = 1.5;  // a dip at d = 1.867 (right of φ(1.8)): φ increasing on [0.9, 1.8]
  EXPECT_FALSE(FindSecondWell(SplinePotential(options, theta)).found);
}

TEST(SecondWell, RejectsBadWindows) {
  EXPECT_THROW(SecondWellOptions{.well_min_d = 1.7}.Check(), Error);
  EXPECT_THROW(SecondWellOptions{.sample_step = 0}.Check(), Error);
}

}  // namespace
}  // namespace rangebayes
