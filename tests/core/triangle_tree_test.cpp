#include "core/triangle_tree.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "core/error.h"

namespace rangebayes {
namespace {

// Brute force over every face: what the tree must return.
double NearestByBruteForce(const Mesh& mesh, const Eigen::Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
    best = std::min(best, SquaredDistanceToTriangle(p, a, b, c));
  }
  return best;
}

// A wavy grid of small faces with a few faces thousands of times larger across it (like the faces across depth
// jumps of a stereo mesh) and a few degenerate ones (a repeated corner, collinear corners).
Mesh GridWithLargeAndDegenerateFaces() {
  const int n = 40;
  Mesh mesh;
  mesh.V.resize(n * n + 3, 3);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) mesh.V.row(y * n + x) << x * 0.01, y * 0.01, 0.002 * std::sin(x * 0.7 + y * 0.3);
  }
  mesh.V.row(n * n) << -30, -30, 5;
  mesh.V.row(n * n + 1) << 30, -30, 5;
  mesh.V.row(n * n + 2) = 0.5 * (mesh.V.row(0) + mesh.V.row(1));  // on the edge of vertices 0 and 1
  std::vector<Eigen::Vector3i> faces;
  for (int y = 0; y + 1 < n; ++y) {
    for (int x = 0; x + 1 < n; ++x) {
      const int i = y * n + x;
      faces.emplace_back(i, i + 1, i + n);
      faces.emplace_back(i + 1, i + n + 1, i + n);
    }
  }
  faces.emplace_back(0, n * n, n * n + 1);          // large
  faces.emplace_back(n - 1, n * n + 1, n * n - 1);  // large
  faces.emplace_back(5, 5, 6);                      // repeated corner
  faces.emplace_back(0, n * n + 2, 1);              // collinear corners
  mesh.F.resize(static_cast<Eigen::Index>(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) mesh.F.row(static_cast<Eigen::Index>(f)) = faces[f].transpose();
  return mesh;
}

TEST(TriangleTree, NearestFaceIsThatOfBruteForce) {
  const Mesh mesh = GridWithLargeAndDegenerateFaces();
  const TriangleTree tree(mesh);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> near(-0.1, 0.5), far(-50, 50);
  for (int q = 0; q < 2000; ++q) {
    const Eigen::Vector3d p = q % 4 == 3 ? Eigen::Vector3d(far(rng), far(rng), far(rng))
                                         : Eigen::Vector3d(near(rng), near(rng), 0.1 * near(rng));
    const TriangleTree::Nearest hit = tree.Query(p);
    ASSERT_GE(hit.face, 0);
    EXPECT_EQ(hit.squared_distance, NearestByBruteForce(mesh, p)) << "query " << p.transpose();
    const Eigen::Vector3d a = mesh.V.row(mesh.F(hit.face, 0)), b = mesh.V.row(mesh.F(hit.face, 1)),
                          c = mesh.V.row(mesh.F(hit.face, 2));
    EXPECT_EQ(SquaredDistanceToTriangle(p, a, b, c), hit.squared_distance);
  }
}

TEST(TriangleTree, DistancesToOneTriangleAreExact) {
  const Eigen::Vector3d a(0, 0, 0), b(1, 0, 0), c(0, 1, 0);
  EXPECT_DOUBLE_EQ(SquaredDistanceToTriangle(Eigen::Vector3d(0.2, 0.2, 3), a, b, c), 9.0);  // above the face
  EXPECT_DOUBLE_EQ(SquaredDistanceToTriangle(Eigen::Vector3d(-1, -1, 0), a, b, c), 2.0);    // corner a
  EXPECT_DOUBLE_EQ(SquaredDistanceToTriangle(Eigen::Vector3d(0.5, -2, 0), a, b, c), 4.0);   // edge ab
  EXPECT_DOUBLE_EQ(SquaredDistanceToTriangle(Eigen::Vector3d(1, 1, 0), a, b, c), 0.5);      // edge bc
  EXPECT_DOUBLE_EQ(SquaredDistanceToTriangle(Eigen::Vector3d(2, 0, 0), a, a, b), 1.0);      // a segment
}

TEST(TriangleTree, NonFiniteInputIsLeftOutOrRefused) {
  Mesh mesh = GridWithLargeAndDegenerateFaces();
  const TriangleTree tree(mesh);
  EXPECT_EQ(tree.Query(Eigen::Vector3d(std::nan(""), 0, 0)).face, -1);
  EXPECT_TRUE(std::isinf(tree.Query(Eigen::Vector3d(0, std::numeric_limits<double>::infinity(), 0)).squared_distance));
  // A face with a NaN corner is never the nearest; a surface with only such faces has no nearest face.
  mesh.V.row(0) << std::nan(""), 0, 0;
  const TriangleTree holed(mesh);
  const TriangleTree::Nearest hit = holed.Query(Eigen::Vector3d(0, 0, 0));
  ASSERT_GE(hit.face, 0);
  for (int k = 0; k < 3; ++k) EXPECT_NE(mesh.F(hit.face, k), 0);
  Mesh nan_only;
  nan_only.V = Vertices::Constant(3, 3, std::nan(""));
  nan_only.F = Faces(1, 3);
  nan_only.F << 0, 1, 2;
  EXPECT_EQ(TriangleTree(nan_only).Query(Eigen::Vector3d::Zero()).face, -1);
  Mesh no_faces;
  no_faces.V = Vertices::Zero(3, 3);
  EXPECT_THROW(TriangleTree{no_faces}, Error);
  Mesh bad_index = nan_only;
  bad_index.F << 0, 1, 3;
  EXPECT_THROW(TriangleTree{bad_index}, Error);
}

}  // namespace
}  // namespace rangebayes
