#include "pipeline/mesh_metrics.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vector>

#include "core/error.h"
#include "core/triangle_tree.h"

namespace rangebayes {
namespace {

Eigen::Vector3d Row(const Vertices& V, int i) { return V.row(i).transpose(); }

double BoundingBoxDiagonal(const Vertices& V) {
  if (V.rows() == 0) return 0;
  return (V.colwise().maxCoeff() - V.colwise().minCoeff()).norm();
}

}  // namespace

Eigen::VectorXd DistanceToSurface(const Vertices& points, const Mesh& surface) {
  const TriangleTree tree(surface);
  Eigen::VectorXd distances(points.rows());
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, points.rows(), 1024),
                    [&](const tbb::blocked_range<Eigen::Index>& range) {
                      for (Eigen::Index i = range.begin(); i < range.end(); ++i) {
                        distances[i] = std::sqrt(tree.Query(points.row(i).transpose()).squared_distance);
                      }
                    });
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
