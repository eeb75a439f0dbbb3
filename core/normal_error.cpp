#include "core/normal_error.h"

#include <Eigen/Geometry>
#include <cmath>

#include "core/error.h"

namespace rangebayes {

double MeanAngularErrorDeg(const Mesh& result, const Mesh& ground_truth, int* skipped) {
  RB_CHECK(result.F.rows() == ground_truth.F.rows() && result.F == ground_truth.F,
           "mean angular error needs the same faces in both meshes (result has ", result.num_faces(),
           " faces, ground truth ", ground_truth.num_faces(),
           (result.F.rows() == ground_truth.F.rows() ? ", different indices" : ""), ")");
  RB_CHECK(result.num_vertices() == ground_truth.num_vertices(), "mean angular error needs the same vertices (",
           result.num_vertices(), " vs ", ground_truth.num_vertices(), ")");
  double sum = 0;
  int count = 0, bad = 0;
  for (int f = 0; f < result.num_faces(); ++f) {
    auto normal = [&](const Mesh& m) {
      const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
      return Eigen::Vector3d((b - a).cross(c - a));
    };
    const Eigen::Vector3d n = normal(result), m = normal(ground_truth);
    const double ln = n.norm(), lm = m.norm();
    if (!(ln > 0) || !(lm > 0) || !std::isfinite(ln) || !std::isfinite(lm)) {
      ++bad;
      continue;
    }
    // atan2 of |n × m| and n·m is accurate for small angles, unlike acos.
    sum += std::atan2(n.cross(m).norm(), n.dot(m)) * 180.0 / M_PI;
    ++count;
  }
  if (skipped != nullptr) *skipped = bad;
  return count > 0 ? sum / count : 0.0;
}

}  // namespace rangebayes
