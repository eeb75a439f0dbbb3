// One range scan prepared for alignment and fusion: a NoisyMesh in the scan's own frame with, per vertex, the
// viewing ray and a normal that faces the sensor.
//
// Scans enter in one of three ways:
//  - MakeRangeGridScan: an organized grid (PLY `range_grid`, core/mesh_io.h), triangulated cell by cell with
//    the discontinuity cut of reconstruction/triangulate.h, and a ray-aligned covariance per vertex from the
//    scanner geometry read off the grid (see below);
//  - MakeScanFromMesh: a NoisyMesh with covariances (what `rangebayes replay` / `mesh` write): the covariance
//    is kept, the ray runs from the camera at the origin of the mesh's frame (or, where the covariances' long
//    axes cross the lines from the origin, along those axes, pointed as the faces say);
//  - MakeScanFromMesh on a plain mesh: the generic noise model (bayes/noise_model.h), rays against the normals.
#pragma once

#include <string>

#include "bayes/smooth.h"
#include "core/mesh.h"
#include "core/mesh_io.h"

namespace rangebayes {

struct Scan {
  std::string name;   // file name, for messages and pose files
  NoisyMesh noisy;    // scan frame; covariance per vertex (model units²)
  Vertices ray;       // #V×3 unit direction from the sensor towards each vertex, scan frame
  Normals normal;     // #V×3 unit vertex normals facing the sensor (n·ray < 0); zero rows for isolated vertices
  double mean_edge = 0;  // mean edge length of the triangulation (model units), the sampling scale

  int num_vertices() const { return noisy.mesh.num_vertices(); }
};

struct RangeGridScanOptions {
  // Noise of the range measurement along the ray and across it (model units; the Stanford scans are in
  // metres). 0.2 mm / 0.05 mm: the Cyberware 3030MS's inter-scan residuals (median 0.23–0.33 mm, docs/design.md §9)
  // are about √2·σ_ray; lateral position comes from a 0.25–0.5 mm grid of known motor steps.
  double sigma_range = 2e-4;    // > 0
  double sigma_lateral = 5e-5;  // > 0
  // Triangulation scanners lose range precision where the surface turns away from the ray (the laser spot
  // spreads as 1/cos θ): σ_range / max(cos θ, min_cos_incidence) along the ray, θ between the ray and the
  // normal; 1: off. (0, 1]. 0.3: measured on the bunny (docs/journal/fusion.md).
  double min_cos_incidence = 0.3;
  // Edge cut between grid neighbours a, b (as for depth images): cut when the jump along the ray exceeds
  // max_jump_sigma·sqrt(σ_a² + σ_b²) plus tan(max_slope_deg)·(their distance across the ray).
  double max_jump_sigma = 6.0;  // > 0
  double max_slope_deg = 80.0;  // [0, 89.9]
  void Check() const;
};

struct RangeGridScanSummary {
  int vertices = 0;
  int faces = 0;
  int cut_edges = 0;
  // How the rays were found: "fan" (each grid row lies on one ray through a common centre, fitted),
  // "parallel" (rows on parallel rays), or "axis" (no row could be fitted: rays along -z).
  std::string ray_model;
  Eigen::Vector3d sensor_centre = Eigen::Vector3d::Zero();  // the fan's centre (x: not used), "fan" only
  double row_fit_rms = 0;  // RMS distance of the points from their row's ray line (model units)
};

// Triangulates a range-grid scan: two triangles per 2×2 block of valid cells (split along the shorter
// diagonal), none across a cut edge, one triangle for a block of three; counter-clockwise seen from the sensor.
// Rays: on the Cyberware scans every grid row lies on one line of its column's (y, z) plane (RMS 3–14 µm), the
// laser ray of that row; the rows fan out from one centre, fitted by least squares; the ray of a vertex runs
// from that centre to it. Σ = σ² r rᵀ + σ_lateral² (I − r rᵀ), σ = σ_range / max(cos θ, min_cos_incidence)
// (σ_range for vertices without a normal). Vertices of no triangle are kept (they
// carry no normal). Throws Error naming the scan on a file without a grid or without any vertex.
Scan MakeRangeGridScan(const RangeGridScan& grid, const std::string& name, const RangeGridScanOptions& options = {},
                       RangeGridScanSummary* summary = nullptr);

// A scan from a mesh: its covariances when it has them (the sensor at the origin of its frame, as for
// meshes from depth images; rays along the covariances' long axes where those cross the lines from the origin,
// as for a range grid read as a mesh), else the generic noise model and rays opposite to the vertex normals.
// Throws Error naming the scan when it has no faces, or a covariance that is not positive along its ray.
Scan MakeScanFromMesh(const NoisyMesh& mesh, const std::string& name);

// The scan smoothed by Bayesian smoothing (bayes/smooth.h) with its own covariances, before fusion: same
// vertices, faces, rays and covariances, smoothed positions and their normals. Range-grid scans carry their grid
// cells as pixel positions, so Smooth solves them as organized meshes.
Scan SmoothScan(const Scan& scan, const SmoothOptions& options = {}, SmoothSummary* summary = nullptr);

// Reads a scan file: a PLY with a range_grid and no faces → MakeRangeGridScan; any other mesh file, a PLY that
// lists faces beside its grid included, → MakeScanFromMesh of the mesh as ReadMeshOrRangeGrid reads it.
// Throws Error naming the file when it is empty (no vertices or no faces after triangulation).
Scan ReadScan(const std::string& path, const RangeGridScanOptions& options = {},
              RangeGridScanSummary* summary = nullptr);

// A mesh file as the mesh commands (`info`, `smooth`, `decimate`, `convert`) read it: a PLY with a range_grid and
// no faces (the Stanford scans) is triangulated as MakeRangeGridScan does, with its ray-aligned covariances and its
// grid cells as pixels, so that smoothing treats it as the organized scan it is (summary->range_grid says what the
// triangulation made); any other file reads as ReadNoisyMesh reads it.
NoisyMesh ReadMeshOrRangeGrid(const std::string& path, MeshReadSummary* summary = nullptr,
                              const RangeGridScanOptions& options = {});

}  // namespace rangebayes
