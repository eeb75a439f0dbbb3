// Synthetic range-grid scans of a known mesh, for tests and benchmarks: an orthographic range scanner looking
// along −z of its own frame (parallel rays, like the Cyberware's motion axis), noise along the ray.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>

#include "core/mesh.h"
#include "core/mesh_io.h"

namespace rangebayes {

struct SyntheticScanOptions {
  int width = 200;            // grid cells, [2, 10000]
  int height = 200;           // [2, 10000]
  double spacing = 1e-3;      // grid pitch (model units), > 0; the grid is centred on the scan frame's z axis
  double sigma_range = 1e-4;  // Gaussian noise along the ray (model units), ≥ 0
  std::uint64_t seed = 1;
  void Check() const;
};

// The first surface of `mesh` (world frame) seen from `world_from_scan`, as a grid scan in the scan frame:
// cell (x, y) at ((x − (w−1)/2)·spacing, (y − (h−1)/2)·spacing) holds the nearest hit along −z, its z moved by
// the noise. The result has no faces (MakeRangeGridScan triangulates it).
RangeGridScan RenderSyntheticScan(const Mesh& mesh, const Eigen::Isometry3d& world_from_scan,
                                  const SyntheticScanOptions& options = {});

// A UV sphere (radius, centre) with `rings` × 2·`rings` quads split into triangles, outward-facing.
Mesh MakeSphereMesh(double radius, const Eigen::Vector3d& centre, int rings = 64);

}  // namespace rangebayes
