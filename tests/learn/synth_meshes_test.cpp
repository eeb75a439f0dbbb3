#include "bayes/learning/synth_meshes.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "core/topology.h"

namespace rangebayes {
namespace {

double SignedVolume(const Mesh& mesh) {
  double volume = 0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0));
    const Eigen::Vector3d b = mesh.V.row(mesh.F(f, 1));
    const Eigen::Vector3d c = mesh.V.row(mesh.F(f, 2));
    volume += a.dot(b.cross(c)) / 6.0;
  }
  return volume;
}

TEST(SynthMeshes, EveryShapeIsAClosedOutwardManifold) {
  for (int s = 0; s < 4; ++s) {
    for (std::uint64_t seed : {1u, 2u, 3u}) {
      RightAngledObjectOptions options;
      options.shape = static_cast<RightAngledShape>(s);
      const Mesh mesh = MakeRightAngledObject(options, seed);
      const EdgeTopology topology = ComputeEdgeTopology(mesh);
      for (int e = 0; e < topology.edge_faces.rows(); ++e) {
        ASSERT_EQ(topology.edge_faces.size(e), 2) << RightAngledShapeName(options.shape) << " edge " << e;
      }
      EXPECT_GT(SignedVolume(mesh), 0.0) << RightAngledShapeName(options.shape);
      // Euler characteristic 2: a sphere-like closed surface (none of the shapes has a hole).
      EXPECT_EQ(mesh.num_vertices() - topology.edges.rows() + mesh.num_faces(), 2);
      // Unit squares cut in two, jittered by ≤ 0.2: edges between 0.6 and 1.9.
      const double le = MeanEdgeLength(mesh, topology);
      EXPECT_GT(le, 1.0);
      EXPECT_LT(le, 1.3);
      // Every face normal of a right-angled object is parallel or orthogonal to every other.
      const Eigen::Vector3d n0 = (Eigen::Vector3d(mesh.V.row(mesh.F(0, 1)) - mesh.V.row(mesh.F(0, 0)))
                                      .cross(Eigen::Vector3d(mesh.V.row(mesh.F(0, 2)) - mesh.V.row(mesh.F(0, 0)))))
                                     .normalized();
      for (int f = 0; f < mesh.num_faces(); ++f) {
        const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0));
        const Eigen::Vector3d n = (Eigen::Vector3d(mesh.V.row(mesh.F(f, 1))) - a)
                                      .cross(Eigen::Vector3d(mesh.V.row(mesh.F(f, 2))) - a)
                                      .normalized();
        const double c = std::abs(n.dot(n0));
        ASSERT_TRUE(c < 1e-9 || c > 1 - 1e-9) << f;
      }
    }
  }
}

TEST(SynthMeshes, DeterministicAndDisjoint) {
  SynthMeshSetOptions options;
  options.num_train = 4;
  options.num_test = 4;
  const SynthMeshSet a = MakeSynthMeshSet(options);
  const SynthMeshSet b = MakeSynthMeshSet(options);
  ASSERT_EQ(a.train.size(), 4u);
  ASSERT_EQ(a.test.size(), 4u);
  for (size_t i = 0; i < a.train.size(); ++i) {
    EXPECT_EQ(a.train[i].noisy.mesh.V, b.train[i].noisy.mesh.V);
    EXPECT_EQ(a.train[i].name, b.train[i].name);
  }
  for (const auto& test : a.test) {
    for (const auto& train : a.train) {
      EXPECT_FALSE(test.clean.num_vertices() == train.clean.num_vertices() && test.clean.F == train.clean.F)
          << test.name << " " << train.name;
    }
  }
  options.seed = 2;
  const SynthMeshSet c = MakeSynthMeshSet(options);
  const Mesh& c0 = c.train[0].noisy.mesh;
  const Mesh& a0 = a.train[0].noisy.mesh;
  EXPECT_FALSE(c0.V.rows() == a0.V.rows() && c0.V == a0.V);
}

// A validation set (for choosing hyper-parameters) leaves the training and held-out draws as they were and shares
// no object with either.
TEST(SynthMeshes, ValidationSetIsDisjointAndLeavesTheOthers) {
  SynthMeshSetOptions options;
  options.num_train = 4;
  options.num_test = 2;
  const SynthMeshSet plain = MakeSynthMeshSet(options);
  options.num_validation = 4;
  const SynthMeshSet set = MakeSynthMeshSet(options);
  ASSERT_EQ(set.validation.size(), 4u);
  EXPECT_TRUE(plain.validation.empty());
  for (size_t i = 0; i < set.train.size(); ++i) EXPECT_EQ(set.train[i].noisy.mesh.V, plain.train[i].noisy.mesh.V);
  for (size_t i = 0; i < set.test.size(); ++i) EXPECT_EQ(set.test[i].noisy.mesh.V, plain.test[i].noisy.mesh.V);
  for (const auto& v : set.validation) {
    EXPECT_EQ(v.name.rfind("validation_", 0), 0u) << v.name;
    for (const auto* others : {&set.train, &set.test}) {
      for (const auto& o : *others) {
        EXPECT_FALSE(v.clean.num_vertices() == o.clean.num_vertices() && v.clean.F == o.clean.F)
            << v.name << " " << o.name;
      }
    }
  }
}

TEST(SynthMeshes, NoiseHasTheRequestedSize) {
  RightAngledObjectOptions object;
  object.min_cells = object.max_cells = 20;
  const Mesh clean = MakeRightAngledObject(object, 5);
  const double le = MeanEdgeLength(clean);
  for (SynthNoise kind : {SynthNoise::kNormal, SynthNoise::kScanner}) {
    SynthNoiseOptions noise;
    noise.kind = kind;
    noise.k = 0.4;
    const NoisyMesh noisy = AddSynthNoise(clean, noise, 9);
    const double rms = std::sqrt((noisy.mesh.V - clean.V).rowwise().squaredNorm().mean());
    // ~2400 vertices: the sample RMS is within a few % of σ (scanner adds σ/10 laterally: √1.02).
    EXPECT_NEAR(rms / le, 0.4 * (kind == SynthNoise::kScanner ? std::sqrt(1.02) : 1.0), 0.02);
    EXPECT_EQ(noisy.has_covariance(), kind == SynthNoise::kScanner);
    EXPECT_EQ(noisy.mesh.F, clean.F);
  }
}

TEST(SynthMeshes, NoiseMixtureSpreadsLevelsAndCarriesCovariances) {
  SynthMeshSetOptions options;
  options.num_train = 8;
  options.num_test = 2;
  options.object.min_cells = 4;
  options.object.max_cells = 6;
  options.noise.k = 0.2;
  options.noise_k_max = 0.5;
  const SynthMeshSet set = MakeSynthMeshSet(options);
  std::vector<double> levels;
  for (const SynthPair& pair : set.train) {
    ASSERT_TRUE(pair.noisy.has_covariance()) << pair.name;
    EXPECT_GE(pair.k, 0.2);
    EXPECT_LE(pair.k, 0.5);
    // The stored covariance is the generic isotropic σ²·I at this pair's own level, σ = k·l_e (noisy mesh).
    const double sigma = pair.k * MeanEdgeLength(pair.noisy.mesh);
    EXPECT_NEAR(pair.noisy.covariance[0](0, 0), sigma * sigma, 1e-9 * sigma * sigma) << pair.name;
    levels.push_back(pair.k);
  }
  std::sort(levels.begin(), levels.end());
  // Golden-ratio spread: 8 levels cover the range with no gap wider than 2.5× the even spacing 0.3/8.
  EXPECT_LT(levels.front(), 0.25);
  EXPECT_GT(levels.back(), 0.45);
  for (size_t i = 1; i < levels.size(); ++i) EXPECT_LT(levels[i] - levels[i - 1], 2.5 * 0.3 / 8);
  // Without a mixture every copy carries the one level.
  options.noise_k_max = 0;
  for (const SynthPair& pair : MakeSynthMeshSet(options).train) EXPECT_EQ(pair.k, 0.2);
}

// A set of no objects at all is refused (the command wrote empty pair lists and then told the user to train on
// them).
TEST(SynthMeshes, EmptySetIsRefused) {
  SynthMeshSetOptions options;
  options.num_train = 0;
  options.num_test = 0;
  EXPECT_THROW(MakeSynthMeshSet(options), Error);
  options.num_test = 1;
  EXPECT_EQ(MakeSynthMeshSet(options).test.size(), 1u);
}

}  // namespace
}  // namespace rangebayes

