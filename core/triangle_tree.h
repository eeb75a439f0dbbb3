// The nearest face of a triangle mesh to a point: a bounding-volume hierarchy of axis-aligned boxes over the faces.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <vector>

#include "core/mesh.h"

namespace rangebayes {

// Squared distance from p to the triangle abc (Ericson, Real-Time Collision Detection, 5.1.5); a triangle with
// (nearly) collinear corners counts as its three edges.
double SquaredDistanceToTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                 const Eigen::Vector3d& c);

// Faces are split at the median centroid along the widest axis of their centroids, up to 4 faces a leaf. A query
// visits the nearer child first and skips every box farther than the best face so far, so it is exact; its cost
// grows with log(faces) and not with the size of the largest face (a stereo mesh's faces across depth jumps are
// thousands of times larger than the rest, which a search among face centroids must add to every search radius).
class TriangleTree {
 public:
  struct Nearest {
    int face = -1;  // -1: the tree has no face with finite corners, or the query point is not finite
    double squared_distance = std::numeric_limits<double>::infinity();
  };

  // Throws Error when the mesh has no faces or a face refers to a vertex it does not have. Faces with a
  // non-finite corner are left out. Keeps its own copy of the corners.
  explicit TriangleTree(const Mesh& surface);

  Nearest Query(const Eigen::Vector3d& p) const;

 private:
  struct Node {
    Eigen::Vector3d lo, hi;  // box of the faces below
    int first = 0;           // leaf: its faces are leaf_face_[first, first + count)
    int count = 0;           // 0: inner node, children at index + 1 and `right`
    int right = 0;
  };
  struct Item {
    Eigen::Vector3d centroid;
    int face;
  };
  int Build(int first, int count, std::vector<Item>* items);
  double SquaredDistanceToBox(const Node& node, const Eigen::Vector3d& p) const;

  std::vector<Node> nodes_;
  std::vector<int> leaf_face_;           // face ids in leaf order
  std::vector<Eigen::Vector3d> corner_;  // 3 per entry of leaf_face_, in the same order
};

}  // namespace rangebayes
