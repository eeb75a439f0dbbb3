#include "bayes/noise_model.h"

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "core/topology.h"

namespace rangebayes {
namespace {

// median(|r|) of N(0, s²) is 0.6745 s; the distance to the one-ring plane also carries the neighbours' noise
// (variance σ²(1 + 1/valence)). kCalibration maps the result to σ; it was fitted on fandisk 0.3 and bunny 0.2
// only (raw estimate / true σ = 1.12 and 1.13 there) and checked on every other benchmark mesh
// (BENCHMARKS.md "Noise estimate": within −13% … +0% of the true level).
constexpr double kMedianToSigma = 1.0 / 0.6745;
constexpr double kCalibration = 1.0 / 1.125;

Normals VertexNormals(const Mesh& mesh) {
  Normals normals = Normals::Zero(mesh.num_vertices(), 3);
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const int a = mesh.F(f, 0), b = mesh.F(f, 1), c = mesh.F(f, 2);
    const Eigen::Vector3d cross =
        (mesh.V.row(b) - mesh.V.row(a)).transpose().cross((mesh.V.row(c) - mesh.V.row(a)).transpose());
    const double length = cross.norm();
    if (!(length > 0) || !std::isfinite(length)) continue;
    // Mean of the adjacent unit face normals (not area weighted: a sliver says as much as a big face).
    for (int v : {a, b, c}) normals.row(v) += cross.transpose() / length;
  }
  return normals;
}

}  // namespace

void GenericNoiseOptions::Check() const {
  RB_CHECK(std::isnan(noise_edge_multiple) || (noise_edge_multiple > 0 && noise_edge_multiple <= 10),
           "noise: noise_edge_multiple ", noise_edge_multiple, " is outside (0, 10]");
  RB_CHECK(std::isnan(sigma) || (sigma > 0 && std::isfinite(sigma)), "noise: sigma ", sigma, " must be positive");
  RB_CHECK(across_ratio >= 1 && across_ratio <= 100, "noise: across_ratio ", across_ratio, " is outside [1, 100]");
}

double EstimateNoiseLevel(const Mesh& mesh) {
  const EdgeTopology topology = ComputeEdgeTopology(mesh);
  const double edge = MeanEdgeLength(mesh, topology);
  if (!(edge > 0)) return 0;
  const Adjacency neighbours = ComputeVertexNeighbours(mesh, topology);
  std::vector<double> distances;
  distances.reserve(static_cast<size_t>(mesh.num_vertices()));
  std::vector<int> ring2;
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    const int count = neighbours.size(v);
    if (count < 3) continue;
    // The plane's offset from the one-ring (little curvature bias), its normal from the two-ring: at high
    // noise (σ ≈ l_e) a one-ring is too small for its principal axes to find the normal.
    ring2.clear();
    for (const int* u = neighbours.begin(v); u != neighbours.end(v); ++u) {
      ring2.push_back(*u);
      for (const int* w = neighbours.begin(*u); w != neighbours.end(*u); ++w) {
        if (*w != v) ring2.push_back(*w);
      }
    }
    std::sort(ring2.begin(), ring2.end());
    ring2.erase(std::unique(ring2.begin(), ring2.end()), ring2.end());
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const int* u = neighbours.begin(v); u != neighbours.end(v); ++u) mean += mesh.V.row(*u).transpose();
    mean /= count;
    Eigen::Vector3d mean2 = Eigen::Vector3d::Zero();
    for (int u : ring2) mean2 += mesh.V.row(u).transpose();
    mean2 /= static_cast<double>(ring2.size());
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (int u : ring2) {
      const Eigen::Vector3d d = mesh.V.row(u).transpose() - mean2;
      scatter += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
    if (solver.info() != Eigen::Success) continue;
    const Eigen::Vector3d normal = solver.eigenvectors().col(0);
    const double distance = std::abs((mesh.V.row(v).transpose() - mean).dot(normal));
    if (std::isfinite(distance)) distances.push_back(distance);
  }
  if (distances.empty()) return 0;
  const size_t mid = distances.size() / 2;
  std::nth_element(distances.begin(), distances.begin() + static_cast<std::ptrdiff_t>(mid), distances.end());
  return distances[mid] * kMedianToSigma * kCalibration / edge;
}

NoisyMesh MakeGenericNoisyMesh(const Mesh& mesh, const GenericNoiseOptions& options, GenericNoiseSummary* summary) {
  options.Check();
  GenericNoiseSummary s;
  s.mean_edge_length = MeanEdgeLength(mesh);
  if (!std::isnan(options.sigma)) {
    s.sigma = options.sigma;
    s.noise_edge_multiple = s.mean_edge_length > 0 ? s.sigma / s.mean_edge_length : 0;
  } else {
    if (!std::isnan(options.noise_edge_multiple)) {
      s.noise_edge_multiple = options.noise_edge_multiple;
    } else {
      s.noise_edge_multiple = EstimateNoiseLevel(mesh);
      s.estimated = true;
    }
    s.sigma = s.noise_edge_multiple * s.mean_edge_length;
  }
  NoisyMesh noisy;
  noisy.mesh = mesh;
  const int nv = mesh.num_vertices();
  // A mesh without edges or without measurable noise still needs a positive definite covariance.
  double sigma = s.sigma;
  if (!(sigma > 0)) {
    const double diagonal = nv > 0 ? (mesh.V.colwise().maxCoeff() - mesh.V.colwise().minCoeff()).norm() : 1.0;
    sigma = 1e-6 * (diagonal > 0 ? diagonal : 1.0);
  }
  const double normal_variance = sigma * sigma;
  const double tangent_variance = normal_variance / (options.across_ratio * options.across_ratio);
  const Normals normals = VertexNormals(mesh);
  noisy.covariance.resize(static_cast<size_t>(nv));
  for (int v = 0; v < nv; ++v) {
    const Eigen::Vector3d n = normals.row(v).transpose();
    const double length = n.norm();
    if (length > 1e-12 && std::isfinite(length)) {
      const Eigen::Vector3d u = n / length;
      noisy.covariance[static_cast<size_t>(v)] =
          tangent_variance * Eigen::Matrix3d::Identity() + (normal_variance - tangent_variance) * u * u.transpose();
    } else {
      noisy.covariance[static_cast<size_t>(v)] = normal_variance * Eigen::Matrix3d::Identity();
    }
  }
  if (summary != nullptr) *summary = s;
  return noisy;
}

NoisyMesh ChooseNoiseModel(const NoisyMesh& input, const GenericNoiseOptions& options, CovarianceSource source,
                           NoiseModelChoice* choice) {
  options.Check();
  NoiseModelChoice c;
  const bool given = !std::isnan(options.noise_edge_multiple) || !std::isnan(options.sigma);
  NoisyMesh out;
  if (input.has_covariance() && !given && source == CovarianceSource::kAuto) {
    c.from_file = true;
    out = input;
  } else {
    c.replaced_file = input.has_covariance();
    out = MakeGenericNoisyMesh(input.mesh, options, &c.generic);
  }
  if (choice != nullptr) *choice = c;
  return out;
}

}  // namespace rangebayes
