// Small hand-built meshes for the bayes tests.
#pragma once

#include <random>

#include "core/mesh.h"

namespace rangebayes::testing {

// A (rows+1)×(cols+1) vertex grid in the z = 0 plane, spacing 1, two triangles per cell (CCW from +z).
inline Mesh Grid(int rows, int cols) {
  Mesh mesh;
  mesh.V.resize((rows + 1) * (cols + 1), 3);
  for (int r = 0; r <= rows; ++r) {
    for (int c = 0; c <= cols; ++c) mesh.V.row(r * (cols + 1) + c) << c, r, 0;
  }
  mesh.F.resize(2 * rows * cols, 3);
  int f = 0;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const int a = r * (cols + 1) + c, b = a + 1, d = a + cols + 1, e = d + 1;
      mesh.F.row(f++) << a, b, e;
      mesh.F.row(f++) << a, e, d;
    }
  }
  return mesh;
}

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

}  // namespace rangebayes::testing
