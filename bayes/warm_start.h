// Warm starts for the smoothing of successive frames of a (mostly) static scene.
//
//   WarmStart warm;
//   for each frame: Vertices x0; SmoothOptions o = ...;
//                   if (warm.Initial(raw, &x0)) o.initial_positions = &x0;
//                   Mesh smoothed = Smooth(raw, o); warm.Remember(raw, smoothed);
//
// Organized meshes (NoisyMesh::pixel set) only: a vertex of the new frame whose pixel the previous frame also had,
// and whose measured position agrees with the previous measurement there within max_sigmas (Mahalanobis distance
// under the sum of the two covariances), starts at its measurement plus the previous frame's smoothing
// displacement (x_prev − z_prev); every other vertex starts at its measurement. When fewer than min_fraction of the
// vertices agree (the scene or the camera moved), there is no warm start (Smooth then takes its cold path with
// ε continuation and coarse-to-fine). The start changes only where the minimiser begins, not the energy.
#pragma once

#include <cstdint>
#include <unordered_map>

#include "core/mesh.h"

namespace rangebayes {

struct WarmStartOptions {
  double max_sigmas = 3.0;    // agreement of the two measurements, (0, 1e3]
  double min_fraction = 0.5;  // of the new frame's vertices that must agree for a warm start, [0, 1]
  void Check() const;
};

struct WarmStartStats {
  int agreed = 0;    // vertices started from the previous result
  int vertices = 0;  // vertices of the new frame
};

class WarmStart {
 public:
  explicit WarmStart(const WarmStartOptions& options = {});  // throws Error on bad options

  // Start positions for `raw` (#V×3, caller's order). False (and *initial untouched) when nothing is remembered,
  // the mesh is not organized, or too few vertices agree. `stats` (optional) says how many agreed.
  bool Initial(const NoisyMesh& raw, Vertices* initial, WarmStartStats* stats = nullptr) const;

  // Keeps `raw` and its smoothed positions for the next frame. `smoothed` must have raw's vertex count (Error).
  void Remember(const NoisyMesh& raw, const Mesh& smoothed);

  void Reset();

 private:
  WarmStartOptions options_;
  std::unordered_map<std::int64_t, int> pixel_to_vertex_;
  Vertices measured_;
  Vertices displacement_;
  std::vector<Eigen::Matrix3d> covariance_;
};

}  // namespace rangebayes
