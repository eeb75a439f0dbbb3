// What `rangebayes mesh info` reports about a mesh: counts, per-vertex data, extent, edge length, components,
// boundary loops and the validation findings (core/validate.h).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "core/mesh_io.h"
#include "core/validate.h"

namespace rangebayes {

struct MeshInfo {
  int vertices = 0;
  int faces = 0;
  long long edges = 0;
  bool has_normals = false;
  bool has_covariance = false;
  bool has_pixels = false;
  // Over finite vertices only (one NaN must not hide the extent of the rest); false when none is finite.
  bool has_bounding_box = false;
  Eigen::RowVector3d box_min = Eigen::RowVector3d::Zero();
  Eigen::RowVector3d box_max = Eigen::RowVector3d::Zero();
  double mean_edge_length = 0;  // NaN without edges
  int components = 0;
  int boundary_loops = 0;
  MeshValidation validation;

  // The lines `rangebayes mesh info` prints (validation findings included), each ending in a newline.
  std::string BriefReport() const;
};

// The readers reject out-of-range face indices, so any mesh they return can be described.
MeshInfo DescribeMesh(const NoisyMesh& mesh);

const char* MeshFormatName(MeshFormat format);  // "ply", "obj", "off"

}  // namespace rangebayes
