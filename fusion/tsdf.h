// Volumetric fusion of aligned scans (Curless & Levoy 1996, docs/design.md §9): a truncated signed distance on a
// voxel grid, each measurement weighted by its information along its viewing ray, and the zero crossing
// extracted by marching cubes.
//
// Each scan vertex p (world frame, normal n facing its sensor, ray r) adds to every voxel x within the band
// |n·(x − p)| ≤ truncation and within kernel_radius of p across n: the signed distance d = n·(x − p)
// (positive in front of the surface) with weight w = cos θ / σ_ray² · exp(−ℓ²/2h²), σ_ray² = rᵀΣr the
// vertex's variance along its ray, cos θ = −n·r (Curless & Levoy's grazing-angle term), ℓ the distance
// across n and h the scan's mean edge. A voxel's value is Σwd / Σw; marching cubes runs on cells whose eight
// corners all carry weight, so no surface is invented where no scan looked.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "core/mesh.h"
#include "fusion/scan.h"

namespace rangebayes {

struct FuseOptions {
  double voxel_edges = 1.0;        // voxel size in mean scan edge lengths (mean over scans), (0, 100]
  double voxel_size = 0;           // > 0: voxel size in model units instead of voxel_edges
  double truncation_voxels = 3.0;  // half-width of the band around each surface, in voxels, [1, 50]
  double kernel_radius_edges = 1.5;  // reach of a vertex across its normal, in its scan's mean edges, (0, 10]
  double min_cos_ray = 0.1;        // measurements more grazing than this (cos θ) are left out, [0, 1)
  // A corner counts as observed when its weight reaches this share of one measurement's of the median σ.
  double min_weight_share = 0.05;  // (0, 10]
  long long max_voxels = 120'000'000;  // guard against a voxel size far too small for the scene
  void Check() const;
};

struct FuseSummary {
  double voxel_size = 0;
  Eigen::Vector3i grid = Eigen::Vector3i::Zero();
  long long observed_voxels = 0;
  int measurements = 0;   // scan vertices that contributed
  int vertices = 0, faces = 0;
  int boundary_edges = 0;  // of the fused mesh (holes and the rim of unseen parts)
  double time_s = 0;
  std::string BriefReport() const;
};

// Fuses `scans` placed by `world_from_scan` into one mesh in the world frame. The result's covariance per
// vertex is isotropic with σ² the variance of the voxels' weighted mean, Σ w_i² σ_i² / (Σ w_i)² with σ_i² a
// measurement's variance along its normal, interpolated along the cube edge (what Smooth reads). It treats the
// measurements as independent and ignores that neighbouring vertices share them.
// Throws Error on mismatched sizes, an empty scan set, or a grid larger than max_voxels.
NoisyMesh FuseScans(const std::vector<Scan>& scans, const std::vector<Eigen::Isometry3d>& world_from_scan,
                    const FuseOptions& options = {}, FuseSummary* summary = nullptr);

// Number of edges with one incident face.
int CountBoundaryEdges(const Mesh& mesh);

}  // namespace rangebayes
