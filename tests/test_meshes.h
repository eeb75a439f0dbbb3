// Small hand-built meshes shared by the tests of several modules.
#pragma once

#include <Eigen/Geometry>
#include <vector>

#include "core/mesh.h"

namespace rangebayes::testing {

// A (rows+1)×(cols+1) vertex grid in the z = 0 plane, spacing 1, vertex r·(cols+1) + c at (c, r, 0), two
// triangles per cell (a, b, e) and (a, e, d) for its corners a = (c, r), b = (c+1, r), d = (c, r+1), e = (c+1, r+1):
// counter-clockwise seen from +z.
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

// The unit tetrahedron (0,0,0), (1,0,0), (0,1,0), (0,0,1): closed, faces oriented outwards.
inline Mesh Tetrahedron() {
  Mesh mesh;
  mesh.V.resize(4, 3);
  mesh.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1;
  mesh.F.resize(4, 3);
  mesh.F << 0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3;
  return mesh;
}

// Unit normal of every face ((b − a) × (c − a), normalised), computed here apart from the library's kernels.
inline std::vector<Eigen::Vector3d> UnitFaceNormals(const Mesh& mesh) {
  std::vector<Eigen::Vector3d> normal(static_cast<size_t>(mesh.num_faces()));
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
    normal[static_cast<size_t>(f)] = (b - a).cross(c - a).normalized();
  }
  return normal;
}

}  // namespace rangebayes::testing
