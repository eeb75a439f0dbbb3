// Organized triangulation of a depth image into a NoisyMesh with the ray-aligned covariance of docs/design.md §2.
//
// PCL's OrganizedFastMesh does the same grid triangulation, but it cannot carry a covariance per vertex and
// its discontinuity test is a fixed length (or a fixed angle), not a threshold scaled by each pixel's depth
// noise, so this is our own.
#pragma once

#include <string>

#include "calibration/disparity_noise_model.h"
#include "core/mesh.h"
#include "stereo/depth_frame.h"

namespace rangebayes {

struct TriangulateOptions {
  int downsample = 1;               // 1–64: use every n-th pixel in x and y (live previews)
  // An edge between neighbouring grid vertices a, b is cut when
  //   |Z_a − Z_b| > max_jump_sigma · sqrt(σ_Z,a² + σ_Z,b²) + (Z_a + Z_b)/2 · step/f · tan(max_slope_deg),
  // i.e. when the jump is far outside the expected depth noise AND steeper than a surface seen at
  // max_slope_deg from the viewing direction (without the slope term a tilted plane whose depth changes by
  // more than a few σ per pixel would be cut into pieces). σ_Z is the frame's edge_sigma_depth_m where it has one.
  double max_jump_sigma = 6.0;      // > 0
  double max_slope_deg = 80.0;      // 0–89.9
  double default_sigma_disparity_px = 0.5;  // > 0: σ_d for pixels whose σ is NaN (matchers without σ)
  double sigma_pixel_px = -1.0;             // lateral pixel σ, > 0; < 0: the frame's sigma_pixel_px (0 is refused)
  void Check() const;
};

struct TriangulateSummary {
  int vertices = 0;
  int faces = 0;
  int cut_edges = 0;   // grid edges between two valid vertices that were cut as discontinuities
  double time_ms = 0;  // wall time of TriangulateDepth

  // One line for people: "mesh: V vertices, F faces, C edges cut at discontinuities, triangulated in T ms".
  std::string BriefReport() const;
};

// One vertex per valid (finite depth) grid pixel, in the rectified left camera frame (metres, x right,
// y down, z forward): X = (u − cx)·Z/fx, Y = (v − cy)·Z/fy. Two triangles per 2×2 block of valid vertices
// (split along the shorter 3-D diagonal), none with a cut edge; a block with three valid vertices and no cut
// edge among them gives one triangle. Faces are counter-clockwise seen from the camera.
// Covariance per vertex: Σ = σ_ray² r rᵀ + σ_lat² (I − r rᵀ), r the unit ray, σ_ray = σ_Z / r_z (σ_Z =
// Z²/(f·B)·σ_d is along the optical axis; along the ray it is longer by 1/cos) and σ_lat² = (Z·σ_px/f)²·
// (Z² + |p|²)/(2|p|²): half the trace of the pixel error's covariance (σ_px per image axis, the point moved by
// Z/f·δ at its depth) across the ray, i.e. docs/design.md §2's Z/f·σ_px on the axis, ≈ 7% less at 53° off it.
// NoisyMesh::pixel holds each vertex's (u, v) at full resolution. Throws Error on an empty frame or
// inconsistent sizes.
// A calibrated constant noise model (`rangebayes calibrate noise`) gives the σ_d of pixels without one; other
// forms leave the options as they are (their σ_d comes with the matcher's σ).
void ApplyDisparityNoiseModel(const DisparityNoiseModel& model, TriangulateOptions* options);

NoisyMesh TriangulateDepth(const DepthFrame& frame, const TriangulateOptions& options = {},
                           TriangulateSummary* summary = nullptr);

}  // namespace rangebayes
