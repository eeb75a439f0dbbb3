#include "core/topology.h"

#include <gtest/gtest.h>

#include <vector>

#include "core/error.h"
#include "tests/test_meshes.h"

namespace rangebayes {
namespace {

using testing::Tetrahedron;

// An open n×n grid of vertices (2(n−1)² triangles) in the z = 0 plane.
Mesh Grid(int n) { return testing::Grid(n - 1, n - 1); }

TEST(Topology, TetrahedronIsClosed) {
  const Mesh mesh = Tetrahedron();
  const EdgeTopology topology = ComputeEdgeTopology(mesh);
  EXPECT_EQ(topology.edges.rows(), 6);
  for (int e = 0; e < 6; ++e) EXPECT_EQ(topology.edge_faces.size(e), 2);
  EXPECT_EQ(ComputeFacePairs(topology).rows(), 6);
  EXPECT_TRUE(ComputeBoundaryLoops(mesh, topology).empty());
  const Adjacency neighbours = ComputeVertexNeighbours(mesh, topology);
  for (int v = 0; v < 4; ++v) EXPECT_EQ(neighbours.size(v), 3);
  EXPECT_EQ(ComputeComponents(mesh).count, 1);
}

TEST(Topology, OpenGridHasOneBoundaryLoop) {
  const Mesh mesh = Grid(3);
  const EdgeTopology topology = ComputeEdgeTopology(mesh);
  // 12 grid edges plus 4 diagonals.
  EXPECT_EQ(topology.edges.rows(), 16);
  const auto loops = ComputeBoundaryLoops(mesh, topology);
  ASSERT_EQ(loops.size(), 1u);
  EXPECT_EQ(loops[0].size(), 8u);
  // Interior edges: 16 − 8 boundary edges; each gives one face pair.
  EXPECT_EQ(ComputeFacePairs(topology).rows(), 8);
  EXPECT_NEAR(MeanEdgeLength(mesh), (12.0 + 4.0 * std::sqrt(2.0)) / 16.0, 1e-12);
}

TEST(Topology, NonManifoldFanGivesEveryPair) {
  Mesh mesh;
  mesh.V.resize(5, 3);
  mesh.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1;
  mesh.F.resize(3, 3);
  mesh.F << 0, 1, 2, 1, 0, 3, 0, 1, 4;
  const EdgeTopology topology = ComputeEdgeTopology(mesh);
  int non_manifold = 0;
  for (int e = 0; e < topology.edge_faces.rows(); ++e) non_manifold += topology.edge_faces.size(e) > 2;
  EXPECT_EQ(non_manifold, 1);
  const IndexPairs pairs = ComputeFacePairs(topology);
  ASSERT_EQ(pairs.rows(), 3);
  EXPECT_EQ(pairs(0, 0), 0);
  EXPECT_EQ(pairs(0, 1), 1);
  EXPECT_EQ(pairs(2, 0), 1);
  EXPECT_EQ(pairs(2, 1), 2);
}

TEST(Topology, TwoComponents) {
  Mesh a = Tetrahedron();
  Mesh mesh;
  mesh.V.resize(8, 3);
  mesh.V << a.V, (a.V.array() + 5.0).matrix();
  mesh.F.resize(8, 3);
  mesh.F << a.F, (a.F.array() + 4).matrix();
  const Components components = ComputeComponents(mesh);
  EXPECT_EQ(components.count, 2);
  EXPECT_EQ(components.face_label[0], 0);
  EXPECT_EQ(components.face_label[7], 1);
}

TEST(Topology, DegenerateFaceHasNoSelfEdge) {
  Mesh mesh = Tetrahedron();
  mesh.F.row(3) << 1, 1, 3;
  const EdgeTopology topology = ComputeEdgeTopology(mesh);
  EXPECT_EQ(topology.face_edges(3, 0), -1);
  EXPECT_GE(topology.face_edges(3, 1), 0);
}

TEST(Topology, OutOfRangeIndexThrows) {
  Mesh mesh = Tetrahedron();
  mesh.F(2, 1) = 17;
  EXPECT_THROW(ComputeEdgeTopology(mesh), Error);
}

// The face pairs from the vertex-face lists are ComputeFacePairs' rows, on a grid, a non-manifold fan, a fold
// (two faces sharing two edges) and a face with a repeated index; ComputeVertexFaces lists each face once.
TEST(Topology, FacePairsFromVertexFacesMatchTheEdgeTopology) {
  std::vector<Mesh> meshes = {Grid(5), Tetrahedron()};
  Mesh fan;
  fan.V.resize(5, 3);
  fan.V << 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1;
  fan.F.resize(4, 3);
  fan.F << 0, 1, 2, 1, 0, 3, 0, 1, 4, 0, 2, 1;  // the last face folds onto the first
  meshes.push_back(fan);
  Mesh degenerate = Tetrahedron();
  degenerate.F.row(3) << 1, 1, 3;
  meshes.push_back(degenerate);
  for (const Mesh& mesh : meshes) {
    const Adjacency vf = ComputeVertexFaces(mesh);
    EXPECT_EQ(ComputeFacePairs(mesh, vf), ComputeFacePairs(mesh));
    for (int v = 0; v < vf.rows(); ++v) {
      for (const int* f = vf.begin(v); f + 1 < vf.end(v); ++f) EXPECT_LT(*f, *(f + 1));
    }
  }
  const Adjacency vf = ComputeVertexFaces(degenerate);
  EXPECT_EQ(vf.size(1), 3);  // faces 0, 1 and the degenerate 3, once
}

}  // namespace
}  // namespace rangebayes
