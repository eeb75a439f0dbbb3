#include "pipeline/mesh_metrics.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "core/error.h"
#include "core/triangle_tree.h"
#include "core/validate.h"

namespace rangebayes {
namespace {

Eigen::Vector3d Row(const Vertices& V, int i) { return V.row(i).transpose(); }

// Per vertex, whether some face uses it: the surface. An unused vertex (a stereo mesh's pixel whose triangles were
// cut, a file's stray point) is not, and counted as surface it set the Hausdorff distance and the box's diagonal.
std::vector<char> UsedVertices(const Mesh& mesh) {
  std::vector<char> used(static_cast<size_t>(mesh.num_vertices()), 0);
  for (int f = 0; f < mesh.num_faces(); ++f) {
    for (int k = 0; k < 3; ++k) used[static_cast<size_t>(mesh.F(f, k))] = 1;
  }
  return used;
}

Vertices Select(const Vertices& V, const std::vector<char>& keep) {
  Vertices out(std::count(keep.begin(), keep.end(), 1), 3);
  Eigen::Index row = 0;
  for (Eigen::Index v = 0; v < V.rows(); ++v) {
    if (keep[static_cast<size_t>(v)]) out.row(row++) = V.row(v);
  }
  return out;
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
  const Vertices gt_surface = Select(ground_truth.V, UsedVertices(ground_truth));
  errors.bbox_diagonal = BoundingBoxExtent(gt_surface).norm();
  const std::vector<char> result_used = UsedVertices(result);
  const Eigen::VectorXd to_gt = DistanceToSurface(result.V, ground_truth);
  const Eigen::VectorXd to_result = DistanceToSurface(gt_surface, result);
  double to_gt_max = 0.0, to_gt_sum = 0.0;
  int used = 0;
  for (Eigen::Index v = 0; v < to_gt.size(); ++v) {
    if (!result_used[static_cast<size_t>(v)]) continue;
    to_gt_max = std::max(to_gt_max, to_gt[v]);
    to_gt_sum += to_gt[v];
    ++used;
  }
  errors.hausdorff = std::max(to_gt_max, to_result.size() > 0 ? to_result.maxCoeff() : 0.0);
  errors.mean_distance = used > 0 ? to_gt_sum / used : 0.0;
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

MeshEvaluation EvaluateMesh(const Mesh& result, const Mesh& ground_truth, bool normals, const std::string& result_name,
                            const std::string& ground_truth_name) {
  for (const auto& [name, mesh] : {std::pair<const std::string&, const Mesh&>{ground_truth_name, ground_truth},
                                   std::pair<const std::string&, const Mesh&>{result_name, result}}) {
    RB_CHECK(mesh.num_faces() > 0, name, ": no faces (eval compares surfaces)");
    CheckComputableScale(mesh.V, name);
  }
  MeshEvaluation e;
  if (normals) {
    RB_CHECK(SameConnectivity(result, ground_truth), result_name, " and ", ground_truth_name,
             " do not share connectivity (needed for the normal error)");
    e.has_normal_error = true;
    e.mae_deg = MeanAngularErrorDeg(result, ground_truth, &e.mae_skipped_faces);
  }
  e.surface = ComputeSurfaceErrors(result, ground_truth);
  e.faces = result.num_faces();
  e.vertices = result.num_vertices();
  return e;
}

std::vector<EvaluationField> EvaluationFields(const MeshEvaluation& e) {
  std::vector<EvaluationField> fields = {
      {"bbox_diagonal", e.surface.bbox_diagonal}, {"ev", e.surface.ev},
      {"ev_rel_bbox", e.surface.ev_rel_bbox()},   {"faces", static_cast<double>(e.faces), true},
      {"hausdorff", e.surface.hausdorff},         {"hausdorff_rel_bbox", e.surface.hausdorff_rel_bbox()},
  };
  if (e.has_normal_error) {
    fields.push_back({"mae_deg", e.mae_deg});
    fields.push_back({"mae_skipped_faces", static_cast<double>(e.mae_skipped_faces), true});
  }
  fields.push_back({"mean_distance", e.surface.mean_distance});
  fields.push_back({"vertices", static_cast<double>(e.vertices), true});
  return fields;
}

}  // namespace rangebayes
