#include "core/validate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "core/error.h"
#include "core/topology.h"
#include "tests/test_meshes.h"

namespace rangebayes {
namespace {

Mesh MakeMesh(const std::vector<Eigen::RowVector3d>& points, const std::vector<Eigen::RowVector3i>& faces) {
  Mesh mesh;
  mesh.V.resize(static_cast<Eigen::Index>(points.size()), 3);
  for (size_t i = 0; i < points.size(); ++i) mesh.V.row(static_cast<Eigen::Index>(i)) = points[i];
  mesh.F.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) mesh.F.row(static_cast<Eigen::Index>(f)) = faces[f];
  return mesh;
}

using testing::Tetrahedron;

// An n×n grid of vertices in the z = 0 plane.
Mesh Grid(int n) { return testing::Grid(n - 1, n - 1); }

void ExpectClean(const MeshValidation& v) {
  EXPECT_TRUE(v.clean());
  EXPECT_TRUE(DescribeFindings(v).empty());
}

TEST(ValidateMesh, TetrahedronIsCleanAndClosed) {
  const MeshValidation v = ValidateMesh(Tetrahedron());
  ExpectClean(v);
  EXPECT_EQ(v.boundary_edges, 0);
}

TEST(ValidateMesh, OpenGridIsCleanWithBoundary) {
  const MeshValidation v = ValidateMesh(Grid(4));
  ExpectClean(v);
  EXPECT_EQ(v.boundary_edges, 4 * 3);
}

TEST(ValidateMesh, EmptyMeshIsClean) { ExpectClean(ValidateMesh(Mesh{})); }

TEST(ValidateMesh, FlippedFaceGivesThreeInconsistentEdges) {
  Mesh mesh = Tetrahedron();
  std::swap(mesh.F(3, 0), mesh.F(3, 1));
  const MeshValidation v = ValidateMesh(mesh);
  EXPECT_EQ(v.inconsistent_edges, 3);
  EXPECT_EQ(v.non_manifold_edges, 0);
  EXPECT_FALSE(v.clean());
}

TEST(ValidateMesh, FanOfThreeFacesOnOneEdgeIsNonManifold) {
  const Mesh mesh = MakeMesh({{0, 0, 0}, {1, 0, 0}, {0.5, 1, 0}, {0.5, -1, 0}, {0.5, 0, 1}},
                             {{0, 1, 2}, {1, 0, 3}, {0, 1, 4}});
  const MeshValidation v = ValidateMesh(mesh);
  EXPECT_EQ(v.non_manifold_edges, 1);
  EXPECT_EQ(v.non_manifold_vertices, 0);  // each end vertex still has one fan
  EXPECT_EQ(v.boundary_edges, 6);
  EXPECT_EQ(v.duplicate_faces, 0);
}

TEST(ValidateMesh, TwoComponentsAreClean) {
  Mesh a = Tetrahedron();
  Mesh mesh;
  mesh.V.resize(8, 3);
  mesh.V << a.V, a.V.array() + 5.0;
  mesh.F.resize(8, 3);
  mesh.F << a.F, a.F.array() + 4;
  ExpectClean(ValidateMesh(mesh));
}

TEST(ValidateMesh, BowTieVertexIsNonManifold) {
  // Two triangles that touch only at vertex 0.
  const Mesh mesh = MakeMesh({{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {-1, 0, 0}, {-1, -1, 0}}, {{0, 1, 2}, {0, 3, 4}});
  const MeshValidation v = ValidateMesh(mesh);
  EXPECT_EQ(v.non_manifold_vertices, 1);
  EXPECT_EQ(v.non_manifold_edges, 0);
}

TEST(ValidateMesh, CountsFaceAndVertexDefects) {
  Mesh mesh = MakeMesh({{0, 0, 0},
                        {1, 0, 0},
                        {0, 1, 0},
                        {2, 0, 0},  // collinear with 0 and 1
                        {std::numeric_limits<double>::quiet_NaN(), 0, 0},
                        {9, 9, 9}},  // unreferenced
                       {{0, 1, 2},
                        {2, 1, 0},    // duplicate of face 0 (reversed)
                        {0, 1, 3},    // zero area
                        {0, 0, 2},    // degenerate
                        {3, 1, 4},    // uses the NaN vertex
                        {0, 7, -1}}); // two indices out of range
  const MeshValidation v = ValidateMesh(mesh);
  EXPECT_EQ(v.out_of_range_indices, 2);
  EXPECT_EQ(v.degenerate_faces, 1);
  EXPECT_EQ(v.zero_area_faces, 1);
  EXPECT_EQ(v.duplicate_faces, 1);
  EXPECT_EQ(v.non_finite_vertices, 1);
  EXPECT_EQ(v.unreferenced_vertices, 1);
  EXPECT_FALSE(v.clean());
  EXPECT_EQ(DescribeFindings(v).size(), 7u);  // plus the non-manifold edge 0-1 (faces 0, 1, 2)
  EXPECT_EQ(v.non_manifold_edges, 1);
}

// A unit square's two triangles moved to a scale (1e300: `info` read a mean edge length of "n/a (no edges)" and two
// zero-area faces; 1e-200: a mean edge length of 0 and `smooth` returned the input as converged).
Mesh SquareAtScale(double scale) {
  return MakeMesh({{0, 0, 0}, {scale, 0, 0}, {0, scale, 0}, {scale, scale, 0}}, {{0, 1, 2}, {1, 3, 2}});
}

TEST(ValidateMesh, MeshesBeyondTheComputableScaleAreNamed) {
  for (const double scale : {1e300, 1e-200}) {
    SCOPED_TRACE(scale);
    const Mesh mesh = SquareAtScale(scale);
    const MeshValidation v = ValidateMesh(mesh);
    EXPECT_EQ(v.zero_area_faces, 0);  // areas are compared in a scaled copy
    EXPECT_EQ(v.out_of_scale_vertices, scale > 1 ? 3 : 0);
    EXPECT_EQ(v.below_scale_extent, scale < 1 ? 1 : 0);
    EXPECT_FALSE(v.clean());
    ASSERT_EQ(DescribeFindings(v).size(), 1u);
    EXPECT_NE(DescribeFindings(v)[0].find("rescale the mesh"), std::string::npos) << DescribeFindings(v)[0];
    EXPECT_NEAR(MeanEdgeLength(mesh) / scale, (4.0 + std::sqrt(2.0)) / 5.0, 1e-12);
    try {
      CheckComputableScale(mesh.V, "square");
      ADD_FAILURE() << "no error";
    } catch (const Error& e) {
      const std::string why = e.what();
      EXPECT_NE(why.find(scale > 1 ? "square: vertex 1 lies at (1e+300, 0, 0), beyond ±1e+60"
                                   : "square: the mesh spans only 1.41421e-200, below 1e-60"),
                std::string::npos)
          << why;
    }
  }
  // Just within the scale, and a mesh whose positions all coincide: clean as far as the scale goes.
  EXPECT_NO_THROW(CheckComputableScale(SquareAtScale(kMaxCoordinate).V, "square"));
  EXPECT_NO_THROW(CheckComputableScale(SquareAtScale(kMinExtent).V, "square"));
  EXPECT_NO_THROW(CheckComputableScale(SquareAtScale(0).V, "square"));
  EXPECT_EQ(ValidateMesh(SquareAtScale(kMaxCoordinate)).out_of_scale_vertices, 0);
  EXPECT_EQ(ValidateMesh(SquareAtScale(kMinExtent)).below_scale_extent, 0);
}

TEST(ValidateMesh, RejectsBadOptions) {
  ValidateMeshOptions options;
  options.zero_area_relative = -1;
  EXPECT_THROW(ValidateMesh(Tetrahedron(), options), Error);
}

}  // namespace
}  // namespace rangebayes
