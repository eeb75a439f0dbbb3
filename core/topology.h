// Connectivity derived from a Mesh's faces: unique edges, face pairs, boundary loops, one-rings, components.
// Derived on demand by these functions, never stored beside the Mesh as a second truth.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "core/mesh.h"

namespace rangebayes {

using IndexPairs = Eigen::Matrix<int, Eigen::Dynamic, 2, Eigen::RowMajor>;

// Compressed rows: the items of row r are items[offsets[r] .. offsets[r+1]).
struct Adjacency {
  std::vector<int> offsets;
  std::vector<int> items;

  int rows() const { return offsets.empty() ? 0 : static_cast<int>(offsets.size()) - 1; }
  int size(int r) const { return offsets[r + 1] - offsets[r]; }
  const int* begin(int r) const { return items.data() + offsets[r]; }
  const int* end(int r) const { return items.data() + offsets[r + 1]; }
};

// Unique undirected edges and their incident faces. Corner k of face f spans the directed edge
// F(f,k) → F(f,(k+1)%3); face_edges(f,k) is its edge id, or -1 when the two indices are equal.
struct EdgeTopology {
  IndexPairs edges;       // #E×2, edges(e,0) < edges(e,1), sorted lexicographically
  Adjacency edge_faces;   // per edge, the faces that contain it (1: boundary, 2: manifold, ≥3: non-manifold)
  Faces face_edges;       // #F×3
};

// Throws Error if a face index is out of range.
EdgeTopology ComputeEdgeTopology(const Mesh& mesh);

// Every unordered pair of distinct faces that share an edge; at a non-manifold edge with k faces, all
// k(k−1)/2 pairs. Row (s, t) with s < t, sorted. These are the pairs the smoothing prior runs over.
IndexPairs ComputeFacePairs(const EdgeTopology& topology);
IndexPairs ComputeFacePairs(const Mesh& mesh);
// The same rows from the per-vertex face lists (ComputeVertexFaces(mesh)), without building the edges: a
// triangle holds an edge {a, b} (a ≠ b) exactly when it holds both vertices. Faster on large meshes.
IndexPairs ComputeFacePairs(const Mesh& mesh, const Adjacency& vertex_faces);

// Boundary loops: chains of vertices along edges with exactly one incident face. A loop is closed (its
// last vertex connects to its first). Where the boundary is not a simple cycle (a vertex with more than two
// boundary edges), loops are split at that vertex.
std::vector<std::vector<int>> ComputeBoundaryLoops(const Mesh& mesh, const EdgeTopology& topology);

// Per vertex, the neighbouring vertices across an edge, sorted ascending.
Adjacency ComputeVertexNeighbours(const Mesh& mesh, const EdgeTopology& topology);

// Per vertex, the faces that use it, sorted ascending.
Adjacency ComputeVertexFaces(const Mesh& mesh);

// Connected components of faces (two faces are connected if they share an edge or, when
// share_vertices is kSharedVertex, a vertex). Returns a label per face in [0, count).
enum class Connectivity { kSharedEdge, kSharedVertex };
struct Components {
  std::vector<int> face_label;
  int count = 0;
};
Components ComputeComponents(const Mesh& mesh, Connectivity connectivity = Connectivity::kSharedEdge);

// Mean length of the unique edges (0 for a mesh without edges).
double MeanEdgeLength(const Mesh& mesh, const EdgeTopology& topology);
double MeanEdgeLength(const Mesh& mesh);

}  // namespace rangebayes
