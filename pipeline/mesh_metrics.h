// Quality metrics of a smoothed (or decimated) mesh against a ground-truth mesh (docs/design.md §7).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/normal_error.h"  // MeanAngularErrorDeg

namespace rangebayes {

// Unsigned distance from each query point to the triangle surface `surface` (exact point–triangle distances through
// core/triangle_tree.h; faces with a repeated index count as segments/points, faces with a non-finite corner are
// left out). A non-finite point, or a surface without a finite face, gets +inf. Throws Error for a surface without
// faces or with a face index out of range.
Eigen::VectorXd DistanceToSurface(const Vertices& points, const Mesh& surface);

struct SurfaceErrors {
  double ev = 0;                   // Ev of Sun et al. 2007, model units: sqrt(Σ_i Σ_(f∋i) A_f d_i² / (3 Σ_f A_f)),
                                   // A_f the result's face areas, d_i the distance of result vertex i to the GT
  // Over the vertices some face uses (an unused vertex is not surface):
  double hausdorff = 0;            // symmetric Hausdorff distance over vertices (result→GT, GT→result), model units
  double bbox_diagonal = 0;        // of the ground truth
  double mean_distance = 0;        // mean result-vertex distance to the GT surface
  double ev_rel_bbox() const { return bbox_diagonal > 0 ? ev / bbox_diagonal : 0; }
  double hausdorff_rel_bbox() const { return bbox_diagonal > 0 ? hausdorff / bbox_diagonal : 0; }
};

// Connectivity-independent surface errors (works for decimated results too).
SurfaceErrors ComputeSurfaceErrors(const Mesh& result, const Mesh& ground_truth);

// What `rangebayes eval` and Python's evaluate() report: the surface errors and, with `normals`, the mean angular
// error of the face normals, which needs SameConnectivity. Error for a mesh without faces or with a vertex that is
// not finite (its distances, the bounding box and the face angles would be NaN or quietly left out).
struct MeshEvaluation {
  bool has_normal_error = false;
  double mae_deg = 0;         // mean angle between corresponding face normals, degrees
  int mae_skipped_faces = 0;  // faces left out of mae_deg (degenerate in either mesh)
  SurfaceErrors surface;
  int faces = 0;  // of the result
  int vertices = 0;
};
// The names are those of the messages (the file paths in `rangebayes eval`).
MeshEvaluation EvaluateMesh(const Mesh& result, const Mesh& ground_truth, bool normals,
                            const std::string& result_name = "the result",
                            const std::string& ground_truth_name = "the ground truth");

// The evaluation as named numbers, the names of eval's JSON line ("mae_deg", "ev", "hausdorff_rel_bbox", ...),
// in that line's order (by name). `count`: a whole number (faces, vertices, skipped faces).
struct EvaluationField {
  std::string name;
  double value = 0;
  bool count = false;
};
std::vector<EvaluationField> EvaluationFields(const MeshEvaluation& e);

}  // namespace rangebayes
