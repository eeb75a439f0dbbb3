// libFuzzer entry for Stanford range-grid PLY scans (ReadScan: ReadRangeGridScan, then MakeRangeGridScan,
// or MakeScanFromMesh for a PLY without a grid): any input reads or throws rangebayes::Error; a scan read
// has finite positions, unit rays and finite covariances for every vertex, and faces inside the vertices.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/error.h"
#include "fusion/scan.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rangebayes;
  const std::string path = fuzz::WriteScratch("scan.ply", std::string_view(reinterpret_cast<const char*>(data), size));
  Scan scan;
  try {
    scan = ReadScan(path);
  } catch (const Error&) {
    return 0;
  }
  const Mesh& mesh = scan.noisy.mesh;
  fuzz::Require(mesh.num_vertices() > 0 && mesh.num_faces() > 0, "a scan has vertices and faces");
  fuzz::RequireFinite(mesh.V, "vertex positions");
  fuzz::Require(mesh.F.minCoeff() >= 0 && mesh.F.maxCoeff() < mesh.num_vertices(), "faces index vertices");
  fuzz::Require(scan.noisy.has_covariance(), "one covariance per vertex");
  for (const auto& c : scan.noisy.covariance) fuzz::RequireFinite(c, "covariance");
  fuzz::Require(scan.ray.rows() == mesh.num_vertices(), "one ray per vertex");
  fuzz::RequireFinite(scan.ray, "rays");
  fuzz::RequireFinite(scan.normal, "normals");
  fuzz::RequireFinite(scan.mean_edge, "mean edge");
  return 0;
}
