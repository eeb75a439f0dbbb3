#include "core/mesh_info.h"

#include <cmath>
#include <cstdio>
#include <limits>

#include "core/error.h"
#include "core/topology.h"

namespace rangebayes {

MeshInfo DescribeMesh(const NoisyMesh& noisy) {
  const Mesh& mesh = noisy.mesh;
  MeshInfo info;
  info.vertices = mesh.num_vertices();
  info.faces = mesh.num_faces();
  info.validation = ValidateMesh(mesh);
  const EdgeTopology topology = ComputeEdgeTopology(mesh);
  info.edges = static_cast<long long>(topology.edges.rows());
  info.has_normals = mesh.N.rows() > 0;
  info.has_covariance = noisy.has_covariance();
  info.has_pixels = noisy.pixel.rows() > 0;
  info.has_bounding_box = FiniteBoundingBox(mesh.V, &info.box_min, &info.box_max);
  info.mean_edge_length =
      topology.edges.rows() > 0 ? MeanEdgeLength(mesh, topology) : std::numeric_limits<double>::quiet_NaN();
  info.components = ComputeComponents(mesh).count;
  info.boundary_loops = static_cast<int>(ComputeBoundaryLoops(mesh, topology).size());
  return info;
}

std::string MeshInfo::BriefReport() const {
  std::string out;
  char line[320];
  std::snprintf(line, sizeof(line), "vertices:         %d\nfaces:            %d\n", vertices, faces);
  out += line;
  std::snprintf(line, sizeof(line), "edges:            %lld (%lld on the boundary)\n", edges,
                static_cast<long long>(validation.boundary_edges));
  out += line;
  std::snprintf(line, sizeof(line), "per-vertex data:  normals %s, covariance %s, pixels %s\n",
                has_normals ? "yes" : "no", has_covariance ? "yes" : "no", has_pixels ? "yes" : "no");
  out += line;
  if (!has_bounding_box) {
    out += "bounding box:     none (no finite vertices)\n";
  } else {
    const Eigen::RowVector3d size = box_max - box_min;
    std::snprintf(line, sizeof(line),
                  "bounding box:     min (%.6g, %.6g, %.6g) max (%.6g, %.6g, %.6g)\n"
                  "                  size (%.6g, %.6g, %.6g)\n",
                  box_min(0), box_min(1), box_min(2), box_max(0), box_max(1), box_max(2), size(0), size(1), size(2));
    out += line;
  }
  const std::string edge_length = std::isfinite(mean_edge_length) ? StrCat(mean_edge_length)
                                  : edges == 0                    ? "n/a (no edges)"
                                                                  : "n/a (non-finite vertices)";
  std::snprintf(line, sizeof(line), "mean edge length: %s\ncomponents:       %d\nboundary loops:   %d\n",
                edge_length.c_str(), components, boundary_loops);
  out += line;
  const std::vector<std::string> findings = DescribeFindings(validation);
  if (findings.empty()) {
    out += "validation:       clean\n";
  } else {
    std::snprintf(line, sizeof(line), "validation:       %zu kinds of defect\n", findings.size());
    out += line;
    for (const std::string& f : findings) out += "  " + f + "\n";
  }
  return out;
}

const char* MeshFormatName(MeshFormat format) {
  switch (format) {
    case MeshFormat::kPly:
      return "ply";
    case MeshFormat::kObj:
      return "obj";
    case MeshFormat::kOff:
      return "off";
  }
  return "?";
}

}  // namespace rangebayes
