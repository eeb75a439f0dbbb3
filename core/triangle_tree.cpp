#include "core/triangle_tree.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>

#include "core/error.h"

namespace rangebayes {
namespace {

constexpr int kLeafFaces = 4;

double SquaredDistanceToSegment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).squaredNorm();
}

}  // namespace

double SquaredDistanceToTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                 const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a;
  if (ab.cross(ac).squaredNorm() <= 1e-30 * (ab.squaredNorm() * ac.squaredNorm() + 1e-300)) {
    return std::min(
        {SquaredDistanceToSegment(p, a, b), SquaredDistanceToSegment(p, b, c), SquaredDistanceToSegment(p, c, a)});
  }
  const Eigen::Vector3d ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return ap.squaredNorm();
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return bp.squaredNorm();
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return (a + d1 / (d1 - d3) * ab - p).squaredNorm();
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return cp.squaredNorm();
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return (a + d2 / (d2 - d6) * ac - p).squaredNorm();
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    return (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b) - p).squaredNorm();
  }
  const double denom = 1.0 / (va + vb + vc);
  return (a + ab * (vb * denom) + ac * (vc * denom) - p).squaredNorm();
}

TriangleTree::TriangleTree(const Mesh& surface) {
  const int nf = surface.num_faces();
  RB_CHECK(nf > 0, "distance to surface: the surface has no faces");
  const int nv = surface.num_vertices();
  std::vector<Item> items;
  for (int f = 0; f < nf; ++f) {
    bool finite = true;
    for (int k = 0; k < 3; ++k) {
      const int v = surface.F(f, k);
      RB_CHECK(v >= 0 && v < nv, "distance to surface: face ", f, " refers to vertex ", v, " of ", nv);
      finite = finite && surface.V.row(v).allFinite();
    }
    if (!finite) continue;
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int k = 0; k < 3; ++k) sum += surface.V.row(surface.F(f, k)).transpose();
    items.push_back({sum / 3.0, f});
  }
  if (items.empty()) return;
  nodes_.reserve(2 * items.size() / kLeafFaces + 2);
  Build(0, static_cast<int>(items.size()), &items);
  leaf_face_.resize(items.size());
  corner_.resize(3 * items.size());
  for (size_t i = 0; i < items.size(); ++i) {
    leaf_face_[i] = items[i].face;
    for (int k = 0; k < 3; ++k) corner_[3 * i + k] = surface.V.row(surface.F(items[i].face, k)).transpose();
  }
  // The boxes, bottom-up: a child always comes after its parent, so one backward pass sees children first.
  for (int n = static_cast<int>(nodes_.size()) - 1; n >= 0; --n) {
    Node& node = nodes_[n];
    if (node.count > 0) {
      node.lo = node.hi = corner_[3 * node.first];
      for (int i = 3 * node.first; i < 3 * (node.first + node.count); ++i) {
        node.lo = node.lo.cwiseMin(corner_[i]);
        node.hi = node.hi.cwiseMax(corner_[i]);
      }
    } else {
      node.lo = nodes_[n + 1].lo.cwiseMin(nodes_[node.right].lo);
      node.hi = nodes_[n + 1].hi.cwiseMax(nodes_[node.right].hi);
    }
  }
}

int TriangleTree::Build(int first, int count, std::vector<Item>* items) {
  const int index = static_cast<int>(nodes_.size());
  nodes_.emplace_back();
  if (count <= kLeafFaces) {
    nodes_[index].first = first;
    nodes_[index].count = count;
    return index;
  }
  const auto begin = items->begin() + first, end = begin + count;
  Eigen::Vector3d lo = begin->centroid, hi = lo;
  for (auto it = begin; it != end; ++it) {
    lo = lo.cwiseMin(it->centroid);
    hi = hi.cwiseMax(it->centroid);
  }
  int axis = 0;
  (hi - lo).maxCoeff(&axis);
  const int half = count / 2;
  std::nth_element(begin, begin + half, end,
                   [axis](const Item& a, const Item& b) { return a.centroid[axis] < b.centroid[axis]; });
  Build(first, half, items);
  nodes_[index].right = Build(first + half, count - half, items);
  return index;
}

double TriangleTree::SquaredDistanceToBox(const Node& node, const Eigen::Vector3d& p) const {
  const Eigen::Vector3d outside = (node.lo - p).cwiseMax(p - node.hi).cwiseMax(0.0);
  return outside.squaredNorm();
}

TriangleTree::Nearest TriangleTree::Query(const Eigen::Vector3d& p) const {
  Nearest best;
  if (nodes_.empty() || !p.allFinite()) return best;
  // Depth-first, nearer child first, on a stack in place (no allocation per query). Median splits halve the
  // faces at each level, so the depth is at most 31 for an int count of faces, and the stack, which holds at most
  // one entry per level plus one, never reaches 64.
  struct Entry {
    int node;
    double squared_distance;
  };
  std::array<Entry, 64> stack;
  int size = 0;
  stack[size++] = {0, SquaredDistanceToBox(nodes_[0], p)};
  while (size > 0) {
    const Entry e = stack[--size];
    if (e.squared_distance >= best.squared_distance) continue;
    const Node& node = nodes_[e.node];
    if (node.count > 0) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        const double d2 = SquaredDistanceToTriangle(p, corner_[3 * i], corner_[3 * i + 1], corner_[3 * i + 2]);
        if (d2 < best.squared_distance) best = {leaf_face_[i], d2};
      }
      continue;
    }
    Entry near{e.node + 1, SquaredDistanceToBox(nodes_[e.node + 1], p)};
    Entry far{node.right, SquaredDistanceToBox(nodes_[node.right], p)};
    if (far.squared_distance < near.squared_distance) std::swap(near, far);
    if (far.squared_distance < best.squared_distance) stack[size++] = far;
    if (near.squared_distance < best.squared_distance) stack[size++] = near;
  }
  return best;
}

}  // namespace rangebayes
