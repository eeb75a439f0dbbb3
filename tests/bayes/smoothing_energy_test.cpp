#include "bayes/smoothing_energy.h"

#include <gtest/gtest.h>

#include <Eigen/SparseCore>

#include <cstring>
#include <memory>
#include <string>
#include <random>

#include "bayes/potential.h"
#include "core/error.h"
#include "core/topology.h"
#include "tests/bayes/test_meshes.h"

namespace rangebayes {
namespace {

std::vector<Eigen::Matrix3d> RandomInformation(int n, bool anisotropic, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  std::vector<Eigen::Matrix3d> information(static_cast<size_t>(n));
  for (auto& W : information) {
    if (anisotropic) {
      Eigen::Matrix3d A;
      for (int i = 0; i < 9; ++i) A(i / 3, i % 3) = uniform(rng);
      W = A * A.transpose() + 0.1 * Eigen::Matrix3d::Identity();
    } else {
      W = (2.0 + uniform(rng)) * Eigen::Matrix3d::Identity();
    }
  }
  return information;
}

std::vector<std::unique_ptr<Potential>> AllPotentials() {
  std::vector<std::unique_ptr<Potential>> potentials;
  potentials.push_back(std::make_unique<SqrtPotential>(1e-4));
  potentials.push_back(std::make_unique<SqrtPotential>(0.04));
  potentials.push_back(std::make_unique<QuadraticPotential>());
  potentials.push_back(std::make_unique<CauchyPotential>(0.3));
  return potentials;
}

// Central differences of E along every coordinate. Step 1e-6 on O(1) coordinates: truncation error
// ~h²·E''' ≈ 1e-12 and rounding ~1e-16·E/h ≈ 1e-9 relative, so 1e-5 relative agreement is a real check.
// ∂E/∂x against central differences of E (step 1e-6), coordinate by coordinate.
void ExpectGradientMatchesCentralDifferences(const SmoothingEnergy& energy, const Eigen::VectorXd& x) {
  Eigen::VectorXd gradient;
  energy.Evaluate(x, &gradient);
  const double h = 1e-6;
  for (Eigen::Index i = 0; i < x.size(); ++i) {
    Eigen::VectorXd xp = x, xm = x;
    xp[i] += h;
    xm[i] -= h;
    const double numeric = (energy.Evaluate(xp, nullptr).total() - energy.Evaluate(xm, nullptr).total()) / (2 * h);
    EXPECT_NEAR(gradient[i], numeric, 1e-5 * std::max(1.0, std::abs(numeric))) << "coordinate " << i;
  }
}

TEST(SmoothingEnergy, GradientMatchesCentralDifferences) {
  for (bool anisotropic : {false, true}) {
    for (const auto& potential : AllPotentials()) {
      SCOPED_TRACE(potential->Name() + (anisotropic ? " anisotropic W" : " isotropic W"));
      const Mesh measured = testing::NoisyRoof(3, 4, 0.1, 7);
      const SmoothingEnergy energy(measured, RandomInformation(measured.num_vertices(), anisotropic, 3), 1.3,
                                   *potential);
      // Evaluate away from the measurements so the data term has a gradient too.
      std::mt19937 rng(11);
      std::normal_distribution<double> gauss(0.0, 0.05);
      Eigen::VectorXd x = energy.Measurements();
      for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += gauss(rng);
      ExpectGradientMatchesCentralDifferences(energy, x);
    }
  }
}

// The per-face ε² of the square-root potential (a pair uses the mean of its two faces' ε²): same check, with
// ε² spread over two orders of magnitude so a wrong pairing of the faces' values would show.
TEST(SmoothingEnergy, PerFaceEpsilonGradientMatchesCentralDifferences) {
  const Mesh measured = testing::NoisyRoof(3, 4, 0.1, 7);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> log_uniform(std::log(1e-4), std::log(0.05));
  std::vector<double> face_e2(static_cast<size_t>(measured.num_faces()));
  for (double& e2 : face_e2) e2 = std::exp(log_uniform(rng));
  const SqrtPotential potential(1e-4);
  const SmoothingEnergy energy(measured, RandomInformation(measured.num_vertices(), true, 3), 1.3, potential,
                               &face_e2);
  std::normal_distribution<double> gauss(0.0, 0.05);
  Eigen::VectorXd x = energy.Measurements();
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += gauss(rng);
  ExpectGradientMatchesCentralDifferences(energy, x);
  // The energy is the definition: with every ε² equal to the global one it matches the plain potential.
  const std::vector<double> uniform(face_e2.size(), 0.01);
  const SqrtPotential global(0.01);
  const SmoothingEnergy per_face(measured, RandomInformation(measured.num_vertices(), true, 3), 1.3, potential,
                                 &uniform);
  const SmoothingEnergy plain(measured, RandomInformation(measured.num_vertices(), true, 3), 1.3, global);
  EXPECT_NEAR(per_face.Evaluate(x, nullptr).total(), plain.Evaluate(x, nullptr).total(),
              1e-12 * plain.Evaluate(x, nullptr).total());
  // Only with the square-root potential, and one value in (0, 4] per face.
  const QuadraticPotential quadratic;
  EXPECT_THROW(SmoothingEnergy(measured, RandomInformation(measured.num_vertices(), true, 3), 1.3, quadratic,
                               &face_e2),
               Error);
  std::vector<double> short_list(face_e2.begin(), face_e2.end() - 1);
  EXPECT_THROW(SmoothingEnergy(measured, RandomInformation(measured.num_vertices(), true, 3), 1.3, potential,
                               &short_list),
               Error);
  std::vector<double> bad = face_e2;
  bad[0] = 0;
  EXPECT_THROW(SmoothingEnergy(measured, RandomInformation(measured.num_vertices(), true, 3), 1.3, potential, &bad),
               Error);
}

// On a flat surface every normal difference is zero, so the omitted term of the Gauss–Newton matrix (the potential's
// slope times the normals' second derivatives) vanishes: RayGaussNewton is then the exact Hessian of E in the depths
// along the rays, which second differences of E check.
TEST(SmoothingEnergy, RayGaussNewtonIsTheHessianOnAFlatSurface) {
  const int width = 7, height = 6;
  const double f = 20;
  Mesh mesh;
  mesh.V.resize(width * height, 3);
  std::vector<double> rays;
  std::vector<Eigen::Matrix3d> information;
  const Eigen::Vector3d plane_normal = Eigen::Vector3d(0.2, -0.1, 1.0).normalized();
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const Eigen::Vector3d ray = Eigen::Vector3d((u - 3) / f, (v - 2.5) / f, 1.0).normalized();
      const double depth = 2.0 / plane_normal.dot(ray);
      mesh.V.row(v * width + u) = (depth * ray).transpose();
      for (int k = 0; k < 3; ++k) rays.push_back(ray[k]);
      information.push_back(0.5 * (ray * ray.transpose() / 1e-4 +
                                   (Eigen::Matrix3d::Identity() - ray * ray.transpose()) / 1e-6));
    }
  }
  mesh.F.resize(2 * (width - 1) * (height - 1), 3);
  int t = 0;
  for (int v = 0; v + 1 < height; ++v) {
    for (int u = 0; u + 1 < width; ++u) {
      const int a = v * width + u, b = a + 1, c = a + width, d = c + 1;
      mesh.F.row(t++) << a, c, b;
      mesh.F.row(t++) << b, c, d;
    }
  }
  const SqrtPotential potential(0.04);
  const SmoothingEnergy energy(mesh, information, 2.4, potential);
  const Eigen::VectorXd x = energy.Measurements();
  const SmoothingEnergy::RayPattern pattern = energy.RayGaussNewtonPattern();
  std::vector<double> values;
  energy.RayGaussNewton(x, rays, pattern, &values);
  ASSERT_EQ(values.size(), pattern.entries.size());
  std::vector<Eigen::Triplet<double>> triplets;
  for (size_t q = 0; q < values.size(); ++q) {
    triplets.emplace_back(pattern.entries[q].first, pattern.entries[q].second, values[q]);
  }
  const int nv = mesh.num_vertices();
  Eigen::SparseMatrix<double> upper(nv, nv);
  upper.setFromTriplets(triplets.begin(), triplets.end());
  const Eigen::SparseMatrix<double> a = upper.selfadjointView<Eigen::Upper>();
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  for (int trial = 0; trial < 3; ++trial) {
    Eigen::VectorXd depths(nv), direction(3 * nv);
    for (int i = 0; i < nv; ++i) {
      depths[i] = uniform(rng);
      for (int k = 0; k < 3; ++k) direction[3 * i + k] = depths[i] * rays[3 * static_cast<size_t>(i) + k];
    }
    const double h = 1e-4;
    const double second = (energy.Evaluate(x + h * direction, nullptr).total() - 2 * energy.Evaluate(x, nullptr).total() +
                           energy.Evaluate(x - h * direction, nullptr).total()) / (h * h);
    const double model = depths.dot(a * depths);
    EXPECT_NEAR(model, second, 1e-4 * second) << "trial " << trial;
  }
}

TEST(SmoothingEnergy, PartsMatchDefinition) {
  // Two triangles folded by 90°: d = √2 for their one pair.
  Mesh mesh;
  mesh.V.resize(4, 3);
  mesh.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  mesh.F.resize(2, 3);
  mesh.F << 0, 1, 2, 0, 3, 1;
  const QuadraticPotential quadratic;
  const std::vector<Eigen::Matrix3d> information(4, 2.0 * Eigen::Matrix3d::Identity());
  const SmoothingEnergy energy(mesh, information, 0.5, quadratic);
  Eigen::VectorXd x = energy.Measurements();
  EnergyParts parts = energy.Evaluate(x, nullptr);
  EXPECT_DOUBLE_EQ(parts.data, 0.0);
  EXPECT_NEAR(parts.prior, 0.5 * 2.0, 1e-12);  // β · d² with d² = 2
  x[0] += 0.1;
  parts = energy.Evaluate(x, nullptr);
  EXPECT_NEAR(parts.data, 2.0 * 0.01, 1e-12);
  EXPECT_EQ(energy.num_pairs(), 1);
}

// SetPotential (the ε stages of a continuation on one energy) gives exactly what an energy built with that
// potential gives; switching between a square root and another kind is refused.
TEST(SmoothingEnergy, SetPotentialEqualsAFreshEnergy) {
  const Mesh mesh = testing::NoisyRoof(6, 6, 0.05, 3);
  const auto information = RandomInformation(mesh.num_vertices(), true, 5);
  const SqrtPotential tight(1e-4), loose(1e-2);
  SmoothingEnergy switched(mesh, information, 2.4, tight);
  switched.SetPotential(loose);
  const SmoothingEnergy fresh(mesh, information, 2.4, loose);
  Eigen::VectorXd x = fresh.Measurements();
  x[4] += 0.03;
  Eigen::VectorXd g_switched, g_fresh;
  const EnergyParts a = switched.Evaluate(x, &g_switched);
  const EnergyParts b = fresh.Evaluate(x, &g_fresh);
  EXPECT_EQ(a.prior, b.prior);
  EXPECT_EQ(a.data, b.data);
  EXPECT_EQ(g_switched, g_fresh);
  const QuadraticPotential quadratic;
  EXPECT_THROW(switched.SetPotential(quadratic), Error);
}

// The face adjacency (built in one search per face, with a fallback for faces with more than three
// neighbours) has exactly the pairs of ComputeFacePairs, on a manifold grid and with a fin that puts three
// faces on one edge; the prior then equals the pair sum computed from that list.
TEST(SmoothingEnergy, PairsMatchComputeFacePairs) {
  for (bool fin : {false, true}) {
    Mesh mesh = testing::NoisyRoof(5, 4, 0.05, 3);
    if (fin) {
      // On the edge of a pair in the middle of the roof, so that both its faces get four neighbours.
      const IndexPairs before = ComputeFacePairs(mesh);
      const int a = before(before.rows() / 2, 0), b = before(before.rows() / 2, 1);
      std::vector<int> shared;
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
          if (mesh.F(a, i) == mesh.F(b, j)) shared.push_back(mesh.F(a, i));
        }
      }
      ASSERT_EQ(shared.size(), 2u);
      const int nv = mesh.num_vertices(), nf = mesh.num_faces();
      mesh.V.conservativeResize(nv + 1, 3);
      mesh.V.row(nv) = 0.5 * (mesh.V.row(shared[0]) + mesh.V.row(shared[1])) + Eigen::RowVector3d(0, 0, 1);
      mesh.F.conservativeResize(nf + 1, 3);
      mesh.F.row(nf) << shared[0], shared[1], nv;
    }
    const QuadraticPotential quadratic;
    const SmoothingEnergy energy(mesh, std::vector<Eigen::Matrix3d>(static_cast<size_t>(mesh.num_vertices()),
                                                                    Eigen::Matrix3d::Identity()),
                                 1.0, quadratic);
    const IndexPairs pairs = ComputeFacePairs(mesh);
    EXPECT_EQ(energy.num_pairs(), static_cast<int>(pairs.rows())) << "fin " << fin;
    const Normals normals = energy.FaceNormals(energy.Measurements());
    double expected = 0;
    for (Eigen::Index k = 0; k < pairs.rows(); ++k) {
      expected += (normals.row(pairs(k, 0)) - normals.row(pairs(k, 1))).squaredNorm();
    }
    EXPECT_NEAR(energy.Evaluate(energy.Measurements(), nullptr).prior, expected, 1e-12 * std::max(1.0, expected))
        << "fin " << fin;
  }
}

TEST(SmoothingEnergy, DegenerateFacesGiveFiniteValues) {
  Mesh mesh = testing::Grid(2, 2);
  // A face with a repeated index and a face whose three vertices are collinear.
  mesh.F.conservativeResize(mesh.num_faces() + 2, 3);
  mesh.F.row(mesh.num_faces() - 2) << 0, 0, 1;
  mesh.F.row(mesh.num_faces() - 1) << 0, 1, 2;
  const SqrtPotential potential;
  const std::vector<Eigen::Matrix3d> information(static_cast<size_t>(mesh.num_vertices()), Eigen::Matrix3d::Identity());
  const SmoothingEnergy energy(mesh, information, 1.0, potential);
  EXPECT_EQ(energy.num_inactive_faces(), 2);
  Eigen::VectorXd x = energy.Measurements();
  Eigen::VectorXd gradient;
  EXPECT_TRUE(std::isfinite(energy.Evaluate(x, &gradient).total()));
  EXPECT_TRUE(gradient.allFinite());
  // Collapse a valid face to a point during minimisation: still finite.
  x.segment<3>(3 * 4) = x.segment<3>(3 * 0);
  x.segment<3>(3 * 1) = x.segment<3>(3 * 0);
  EXPECT_TRUE(std::isfinite(energy.Evaluate(x, &gradient).total()));
  EXPECT_TRUE(gradient.allFinite());
}

// The wide kernels (AVX-512 and AVX2) must give the portable kernels' bytes: energies and every gradient entry
// equal, on a mesh of more than one reduction range (kGrain 1024 faces) whose face count is not a multiple of
// eight, with a fin (faces with four neighbours), a degenerate face, and a face collapsed during minimisation;
// for the global and the per-face ε², isotropic and anisotropic W. Where the CPU lacks an instruction set the
// run falls back to the next narrower kernels (at worst portable against portable).
TEST(SmoothingEnergy, WideKernelsGiveThePortableBytes) {
#if defined(__FMA__)
  // A build whose baseline has FMA (e.g. -march=native) may contract the portable kernels' multiply-adds.
  GTEST_SKIP() << "portable kernels compiled with FMA";
#endif
  Mesh mesh = testing::NoisyRoof(30, 41, 0.05, 11);
  const int nv = mesh.num_vertices(), nf = mesh.num_faces();
  mesh.V.conservativeResize(nv + 1, 3);
  mesh.V.row(nv) = 0.5 * (mesh.V.row(mesh.F(100, 0)) + mesh.V.row(mesh.F(100, 1))) + Eigen::RowVector3d(0, 0, 1);
  mesh.F.conservativeResize(nf + 2, 3);
  mesh.F.row(nf) << mesh.F(100, 0), mesh.F(100, 1), nv;
  mesh.F.row(nf + 1) << 3, 3, 4;
  ASSERT_NE(mesh.num_faces() % 8, 0);
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> log_uniform(std::log(1e-4), std::log(0.05));
  std::vector<double> face_e2(static_cast<size_t>(mesh.num_faces()));
  for (double& e2 : face_e2) e2 = std::exp(log_uniform(rng));
  const SqrtPotential potential(1e-3);
  Eigen::VectorXd x = Eigen::Map<const Eigen::VectorXd>(mesh.V.data(), 3 * mesh.num_vertices());
  std::normal_distribution<double> gauss(0.0, 0.02);
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += gauss(rng);
  x.segment<3>(3 * mesh.F(7, 1)) = x.segment<3>(3 * mesh.F(7, 0));
  x.segment<3>(3 * mesh.F(7, 2)) = x.segment<3>(3 * mesh.F(7, 0));
  const SmoothingKernel kernel = SmoothingKernel::kAuto;  // AVX-512 where the CPU has it
  for (bool per_face : {false, true}) {
    // Isotropic W with the global ε², anisotropic W with the per-face ε²; the second built while the portable
    // kernels are selected (the wide path then sets up its own buffers on its first evaluation).
    if (per_face) SetSmoothingKernel(SmoothingKernel::kPortable);
    const SmoothingEnergy energy(mesh, RandomInformation(mesh.num_vertices(), per_face, 4), 1.7, potential,
                                 per_face ? &face_e2 : nullptr);
    SetSmoothingKernel(SmoothingKernel::kPortable);
    Eigen::VectorXd portable_gradient, wide_gradient;
    const EnergyParts portable = energy.Evaluate(x, &portable_gradient);
    const double portable_no_gradient = energy.Evaluate(x, nullptr).total();
    SetSmoothingKernel(kernel);
    const std::string name = SmoothingKernelName();
    const EnergyParts wide = energy.Evaluate(x, &wide_gradient);
    EXPECT_EQ(wide.prior, portable.prior) << "per-face " << per_face << ", kernels " << name;
    EXPECT_EQ(wide.data, portable.data) << "per-face " << per_face << ", kernels " << name;
    EXPECT_EQ(energy.Evaluate(x, nullptr).total(), portable_no_gradient) << "per-face " << per_face << ", kernels " << name;
    ASSERT_EQ(wide_gradient.size(), portable_gradient.size());
    EXPECT_EQ(std::memcmp(wide_gradient.data(), portable_gradient.data(), sizeof(double) * wide_gradient.size()), 0)
        << "per-face " << per_face << ", kernels " << name;
    EXPECT_TRUE(wide_gradient.allFinite());
    SetSmoothingKernel(SmoothingKernel::kAuto);
  }
}

// The heavy-tailed data term: its gradient against central differences, its value against the definition
// Σ (ν/2)·log(1 + 2q_i/ν) (never above the Gaussian's Σ q_i), the same bytes from the wide kernels, and nothing
// changed by ν = 0.
TEST(SmoothingEnergy, RobustDataTerm) {
  const Mesh measured = testing::NoisyRoof(3, 4, 0.1, 7);
  const std::vector<Eigen::Matrix3d> information = RandomInformation(measured.num_vertices(), true, 3);
  const SqrtPotential potential(1e-3);
  SmoothingEnergy energy(measured, information, 1.3, potential);
  std::mt19937 rng(11);
  std::normal_distribution<double> gauss(0.0, 0.3);
  Eigen::VectorXd x = energy.Measurements();
  for (Eigen::Index i = 0; i < x.size(); ++i) x[i] += gauss(rng);
  Eigen::VectorXd g0, g1;
  const EnergyParts gaussian = energy.Evaluate(x, &g0);
  energy.SetRobustData(0.0);
  const EnergyParts off = energy.Evaluate(x, &g1);
  EXPECT_EQ(off.data, gaussian.data);
  EXPECT_EQ(std::memcmp(g0.data(), g1.data(), sizeof(double) * g0.size()), 0);
  for (double nu : {0.5, 4.0}) {
    SCOPED_TRACE(nu);
    energy.SetRobustData(nu);
    const Eigen::VectorXd z = energy.Measurements();
    double expected = 0;
    for (int i = 0; i < measured.num_vertices(); ++i) {
      const Eigen::Vector3d r = x.segment<3>(3 * i) - z.segment<3>(3 * i);
      expected += 0.5 * nu * std::log1p(2 * r.dot(information[static_cast<size_t>(i)] * r) / nu);
    }
    const EnergyParts robust = energy.Evaluate(x, nullptr);
    EXPECT_NEAR(robust.data, expected, 1e-12 * expected);
    EXPECT_LT(robust.data, gaussian.data);
    EXPECT_EQ(robust.prior, gaussian.prior);
    ExpectGradientMatchesCentralDifferences(energy, x);
    Eigen::VectorXd portable_gradient, wide_gradient;
    SetSmoothingKernel(SmoothingKernel::kPortable);
    const EnergyParts portable = energy.Evaluate(x, &portable_gradient);
    SetSmoothingKernel(SmoothingKernel::kAuto);
    const EnergyParts wide = energy.Evaluate(x, &wide_gradient);
    EXPECT_EQ(wide.data, portable.data) << SmoothingKernelName();
    EXPECT_EQ(std::memcmp(wide_gradient.data(), portable_gradient.data(), sizeof(double) * wide_gradient.size()), 0);
  }
  EXPECT_THROW(energy.SetRobustData(-1.0), Error);
}

TEST(SmoothingEnergy, RejectsBadInput) {
  Mesh mesh = testing::Grid(1, 1);
  const SqrtPotential potential;
  std::vector<Eigen::Matrix3d> information(4, Eigen::Matrix3d::Identity());
  EXPECT_THROW(SmoothingEnergy(mesh, std::vector<Eigen::Matrix3d>(3), 1.0, potential), Error);
  Mesh bad = mesh;
  bad.F(0, 0) = 17;
  EXPECT_THROW(SmoothingEnergy(bad, information, 1.0, potential), Error);
  bad = mesh;
  bad.V(0, 0) = std::nan("");
  EXPECT_THROW(SmoothingEnergy(bad, information, 1.0, potential), Error);
}

TEST(Potential, DerivativesMatchValues) {
  for (const auto& potential : AllPotentials()) {
    for (double d : {0.0, 1e-3, 0.1, 0.7, 1.4, 2.0}) {
      double value = 0, derivative = 0, weight = 0, value2 = 0;
      potential->Evaluate(d, &value, &derivative);
      potential->EvaluateWeight(d, &value2, &weight);
      EXPECT_DOUBLE_EQ(value, value2);
      if (d > 0) {
        EXPECT_NEAR(weight * d, derivative, 1e-12);
      }
      const double h = 1e-6;
      if (d >= h) {
        const double numeric = (potential->Value(d + h) - potential->Value(d - h)) / (2 * h);
        EXPECT_NEAR(derivative, numeric, 1e-6) << potential->Name();
      }
    }
  }
  EXPECT_EQ(ParsePriorKind("cauchy"), PriorKind::kCauchy);
  EXPECT_THROW(ParsePriorKind("gauss"), Error);
}

}  // namespace
}  // namespace rangebayes
