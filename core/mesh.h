// Triangle meshes as plain data: Mesh (positions and faces) and NoisyMesh (plus one covariance per vertex).
#pragma once

#include <Eigen/Core>
#include <vector>

namespace rangebayes {

// Row-major so that the flat unknown vector of a solver lines up with the 3×3 block of each vertex.
using Vertices = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Faces = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Normals = Vertices;

// A triangle mesh. V: #V×3 positions in model units (metres for meshes from our cameras). F: #F×3 vertex
// indices, counter-clockwise seen from outside. N: optional per-vertex normals (#V×3, or 0 rows when absent).
struct Mesh {
  Vertices V;
  Faces F;
  Normals N;

  int num_vertices() const { return static_cast<int>(V.rows()); }
  int num_faces() const { return static_cast<int>(F.rows()); }
};

// A mesh whose vertices are noisy measurements: covariance[i] is the 3×3 covariance (model units squared) of
// vertex i. pixel, when not empty (#V×2), is the (u, v) image position each vertex was triangulated from.
struct NoisyMesh {
  Mesh mesh;
  std::vector<Eigen::Matrix3d> covariance;
  Eigen::Matrix<float, Eigen::Dynamic, 2, Eigen::RowMajor> pixel;

  bool has_covariance() const {
    return !covariance.empty() && static_cast<int>(covariance.size()) == mesh.num_vertices();
  }
};

// Same vertex count and the same faces, in order (the face counts compared first: Eigen's == compares only the
// right-hand side's rows, reading past a shorter left-hand side).
inline bool SameConnectivity(const Mesh& a, const Mesh& b) {
  return a.num_vertices() == b.num_vertices() && a.F.rows() == b.F.rows() && a.F == b.F;
}

// The extent of the axis-aligned bounding box of V (max − min per axis; zero when V has no rows): .norm() is the
// bounding-box diagonal that scales tolerances and reports.
inline Eigen::RowVector3d BoundingBoxExtent(const Vertices& V) {
  if (V.rows() == 0) return Eigen::RowVector3d::Zero();
  return V.colwise().maxCoeff() - V.colwise().minCoeff();
}

// The axis-aligned bounding box of the rows of V whose coordinates are all finite; false, with lo and hi
// untouched, when there is no such row.
inline bool FiniteBoundingBox(const Vertices& V, Eigen::RowVector3d* lo, Eigen::RowVector3d* hi) {
  bool any = false;
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    if (!V.row(i).allFinite()) continue;
    *lo = any ? lo->cwiseMin(V.row(i)) : Eigen::RowVector3d(V.row(i));
    *hi = any ? hi->cwiseMax(V.row(i)) : Eigen::RowVector3d(V.row(i));
    any = true;
  }
  return any;
}

}  // namespace rangebayes
