#include "pipeline/mesh_metrics.h"

#include <flann/flann.hpp>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"

namespace rangebayes {
namespace {

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5); degenerate triangles
// fall back to the closest of their three edges.
double SquaredDistanceToSegment(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).squaredNorm();
}

double SquaredDistanceToTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                 const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a;
  if (ab.cross(ac).squaredNorm() <= 1e-30 * (ab.squaredNorm() * ac.squaredNorm() + 1e-300)) {
    return std::min({SquaredDistanceToSegment(p, a, b), SquaredDistanceToSegment(p, b, c),
                     SquaredDistanceToSegment(p, c, a)});
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

Eigen::Vector3d Row(const Vertices& V, int i) { return V.row(i).transpose(); }

double BoundingBoxDiagonal(const Vertices& V) {
  if (V.rows() == 0) return 0;
  return (V.colwise().maxCoeff() - V.colwise().minCoeff()).norm();
}

}  // namespace

Eigen::VectorXd DistanceToSurface(const Vertices& points, const Mesh& surface) {
  const int nf = surface.num_faces();
  RB_CHECK(nf > 0, "distance to surface: the surface has no faces");
  for (int f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      RB_CHECK(surface.F(f, k) >= 0 && surface.F(f, k) < surface.num_vertices(), "distance to surface: face ", f,
               " refers to vertex ", surface.F(f, k), " of ", surface.num_vertices());
    }
  }
  std::vector<double> centroids(3 * static_cast<size_t>(nf));
  double max_radius = 0;
  for (int f = 0; f < nf; ++f) {
    const Eigen::Vector3d c =
        (Row(surface.V, surface.F(f, 0)) + Row(surface.V, surface.F(f, 1)) + Row(surface.V, surface.F(f, 2))) / 3.0;
    for (int k = 0; k < 3; ++k) {
      centroids[3 * static_cast<size_t>(f) + k] = c[k];
      max_radius = std::max(max_radius, (Row(surface.V, surface.F(f, k)) - c).norm());
    }
  }
  flann::Matrix<double> dataset(centroids.data(), static_cast<size_t>(nf), 3);
  flann::Index<flann::L2<double>> index(dataset, flann::KDTreeSingleIndexParams(10));
  index.buildIndex();

  Eigen::VectorXd distances(points.rows());
  std::vector<std::vector<size_t>> indices;
  std::vector<std::vector<double>> dists;
  flann::SearchParams params(flann::FLANN_CHECKS_UNLIMITED, 0, false);
  for (Eigen::Index i = 0; i < points.rows(); ++i) {
    Eigen::Vector3d p = points.row(i).transpose();
    if (!p.allFinite()) {
      distances[i] = std::numeric_limits<double>::infinity();
      continue;
    }
    double query[3] = {p.x(), p.y(), p.z()};
    flann::Matrix<double> q(query, 1, 3);
    index.knnSearch(q, indices, dists, 1, params);
    const int nearest = static_cast<int>(indices[0][0]);
    double best2 = SquaredDistanceToTriangle(p, Row(surface.V, surface.F(nearest, 0)),
                                             Row(surface.V, surface.F(nearest, 1)),
                                             Row(surface.V, surface.F(nearest, 2)));
    // Any triangle within distance D of p has its centroid within D + max_radius of p.
    const double radius = std::sqrt(best2) + max_radius;
    index.radiusSearch(q, indices, dists, static_cast<float>(radius * radius * (1 + 1e-9)), params);
    for (size_t j : indices[0]) {
      const int f = static_cast<int>(j);
      best2 = std::min(best2, SquaredDistanceToTriangle(p, Row(surface.V, surface.F(f, 0)), Row(surface.V, surface.F(f, 1)),
                                                        Row(surface.V, surface.F(f, 2))));
    }
    distances[i] = std::sqrt(best2);
  }
  return distances;
}

SurfaceErrors ComputeSurfaceErrors(const Mesh& result, const Mesh& ground_truth) {
  SurfaceErrors errors;
  errors.bbox_diagonal = BoundingBoxDiagonal(ground_truth.V);
  const Eigen::VectorXd to_gt = DistanceToSurface(result.V, ground_truth);
  const Eigen::VectorXd to_result = DistanceToSurface(ground_truth.V, result);
  errors.hausdorff = std::max(to_gt.size() > 0 ? to_gt.maxCoeff() : 0.0, to_result.size() > 0 ? to_result.maxCoeff() : 0.0);
  errors.mean_distance = to_gt.size() > 0 ? to_gt.mean() : 0.0;
  double weighted = 0, area_sum = 0;
  for (int f = 0; f < result.num_faces(); ++f) {
    const Eigen::Vector3d a = Row(result.V, result.F(f, 0)), b = Row(result.V, result.F(f, 1)),
                          c = Row(result.V, result.F(f, 2));
    const double area = 0.5 * (b - a).cross(c - a).norm();
    if (!std::isfinite(area)) continue;
    area_sum += area;
    for (int k = 0; k < 3; ++k) weighted += area * to_gt[result.F(f, k)] * to_gt[result.F(f, k)];
  }
  errors.ev = area_sum > 0 ? std::sqrt(weighted / (3 * area_sum)) : 0.0;
  return errors;
}

}  // namespace rangebayes
