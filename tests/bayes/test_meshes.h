// Small hand-built meshes for the bayes tests.
#pragma once

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>

#include "bayes/smooth.h"
#include "core/mesh.h"
#include "tests/test_meshes.h"  // Grid, Tetrahedron

namespace rangebayes::testing {

// The grid folded along x = cols/2 into a roof (a sharp edge), plus seeded Gaussian noise of std `noise`.
inline Mesh NoisyRoof(int rows, int cols, double noise, unsigned seed) {
  Mesh mesh = Grid(rows, cols);
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, noise);
  for (int v = 0; v < mesh.num_vertices(); ++v) {
    const double x = mesh.V(v, 0);
    mesh.V(v, 2) = 0.5 * (cols / 2.0 - std::abs(x - cols / 2.0));
    for (int k = 0; k < 3; ++k) mesh.V(v, k) += gauss(rng);
  }
  return mesh;
}

// A synthetic range image as our stereo path makes it (reconstruction/triangulate.h): one vertex per pixel of a
// width×height grid seen by a pinhole camera (f = 100 px, centre in the middle), a tilted plane at about 2 m with
// a ridge along v, depth noise along each ray of std sigma_ray_m (seeded), ray-aligned covariances
// σ_ray² r rᵀ + σ_lat² (I − r rᵀ), NoisyMesh::pixel set, two CCW faces per cell seen from the camera.
inline NoisyMesh RangeGrid(int width, int height, double sigma_ray_m, double sigma_lat_m, unsigned seed) {
  NoisyMesh out;
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const double f = 100, cx = 0.5 * (width - 1), cy = 0.5 * (height - 1);
  const int nv = width * height;
  out.mesh.V.resize(nv, 3);
  out.pixel.resize(nv, 2);
  out.covariance.resize(static_cast<size_t>(nv));
  for (int v = 0; v < height; ++v) {
    for (int u = 0; u < width; ++u) {
      const int i = v * width + u;
      const Eigen::Vector3d ray = Eigen::Vector3d((u - cx) / f, (v - cy) / f, 1.0);
      const double x = (u - cx) / f;
      const double depth = 2.0 + 0.3 * x + 0.15 * std::max(0.0, 0.25 - std::abs(x));  // plane with a ridge
      const Eigen::Vector3d r = ray.normalized();
      const Eigen::Vector3d p = depth * ray + sigma_ray_m * gauss(rng) * r;
      out.mesh.V.row(i) = p.transpose();
      out.pixel.row(i) << static_cast<float>(u), static_cast<float>(v);
      out.covariance[static_cast<size_t>(i)] = sigma_ray_m * sigma_ray_m * r * r.transpose() +
                                               sigma_lat_m * sigma_lat_m * (Eigen::Matrix3d::Identity() - r * r.transpose());
    }
  }
  out.mesh.F.resize(2 * (width - 1) * (height - 1), 3);
  int t = 0;
  for (int v = 0; v + 1 < height; ++v) {
    for (int u = 0; u + 1 < width; ++u) {
      const int a = v * width + u, b = a + 1, c = a + width, d = c + 1;
      // Image y points down, so (a, c, b) is counter-clockwise seen from the camera.
      out.mesh.F.row(t++) << a, c, b;
      out.mesh.F.row(t++) << b, c, d;
    }
  }
  return out;
}

// E at positions x under the energy that `options` define for `noisy`, read from a one-iteration solve started
// there (its first recorded energy; no adaptive-ε pre-pass, one grid level).
inline double EnergyOf(const NoisyMesh& noisy, const Vertices& x, const SmoothOptions& options) {
  SmoothOptions probe = options;
  probe.adaptive_epsilon = false;
  probe.multilevel = false;
  probe.max_iterations = 1;
  probe.initial_positions = &x;
  SmoothSummary summary;
  Smooth(noisy, probe, &summary);
  return summary.energy.front();
}

}  // namespace rangebayes::testing
