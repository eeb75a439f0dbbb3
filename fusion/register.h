// Simultaneous alignment of many range scans that weights every correspondence by the two points'
// covariances (generalized ICP, Segal, Haehnel, Thrun 2009, extended to all scans at once: docs/design.md §9).
//
// For a correspondence (p in scan a, its nearest neighbour q in scan b) the residual r = T_a p − T_b q has
// covariance C = R_a Σ_p R_aᵀ + R_b Σ_q R_bᵀ + s²(I − n nᵀ), n the normal at q and s a sliding term across
// the surface (points of two scans never sample the same spot, so the tangential offset is not an error).
// The energy Σ ρ(rᵀ C⁻¹ r) over all overlapping pairs of scans (both directions) is minimised by Gauss–Newton
// over all poses at once, the first scan fixed; correspondences are rebuilt every iteration, coarse to fine
// (the largest accepted distance shrinks level by level) with rejection by distance, by normal angle, and of
// samples and partners near a scan's mesh boundary (boundary_rings); ρ is Cauchy's loss in σ units.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "core/progress.h"
#include "fusion/scan.h"

namespace rangebayes {

struct RegisterOptions {
  // Coarse to fine: the largest correspondence distance per level, in mean edge lengths of the scans (the
  // first level must exceed the initial misalignment: 40 edges = 2 cm on the Stanford scans).
  std::vector<double> max_distance_edges{40, 20, 10, 5, 3, 2};
  int iterations_per_level = 4;        // Gauss–Newton steps per level (each with new correspondences), [1, 1000]
  int samples_per_scan = 1000;         // source points per scan on all but the last level, [10, 1e7]
  int final_samples_per_scan = 3000;   // on the last level, [10, 1e7]
  double max_normal_angle_deg = 45.0;  // reject pairs whose normals differ more, (0, 180]
  double slide_sigma_edges = 10.0;     // s, in mean edge lengths, > 0
  double robust_scale_sigma = 3.0;     // Cauchy scale c in σ units, > 0
  // Vertices within this many edge rings of a scan's mesh boundary (silhouettes, holes: where range scanners
  // curl) are neither samples nor partners, [0, 20]. 2: measured on the bunny (docs/journal/fusion.md).
  int boundary_rings = 2;
  // A scan whose samples find partners in every other scan for less than this share after alignment is an
  // error (it does not overlap the others, or its initial pose is too far off). [0, 1)
  double min_overlap = 0.02;
  // A level stops early when no pose moves more than this (rotation in rad, translation in mean edges). ≥ 0
  double converged_step = 1e-5;
  std::uint64_t seed = 1;              // choice of the sample points
  int num_threads = 0;                 // 0: all cores
  // Called after each Gauss–Newton step of RegisterScans with the share of the levels done, stage "alignment".
  ProgressCallback progress;
  void Check() const;
};

// What the final correspondences say about one ordered pair (source scan a, target scan b).
struct PairReport {
  int a = 0, b = 0;
  int samples = 0;           // source points of a that were looked up in b
  int correspondences = 0;   // of them accepted at the last level
  double overlap = 0;        // correspondences / samples
  double rms_sigma = 0;      // RMS of the residual along n over its predicted σ (nᵀ(R_aΣ_pR_aᵀ + R_bΣ_qR_bᵀ)n)^½
  double rms_distance = 0;   // RMS of the residual along n (model units)
};

struct RegisterSummary {
  int iterations = 0;
  int levels = 0;
  std::vector<double> cost;   // robust cost after each iteration's correspondences were built
  int finest_level_start = 0;  // index in cost of the last level's first iteration (costs compare within a level)
  std::vector<PairReport> pairs;  // pairs with at least one correspondence, a < b first, then a > b
  // CheckPoses: the scans under min_overlap of whose samples found a partner at the given poses (not judged),
  // and the largest share among them.
  std::vector<int> apart;
  double apart_overlap = 0;
  double time_s = 0;
  std::string BriefReport() const;   // one line
};

// Aligns `scans` from the initial poses (world_from_scan, one per scan) and returns the refined poses; the
// first scan keeps its initial pose. Throws Error naming the scan when a scan overlaps no other scan (less
// than min_overlap of its samples find a partner), when a scan's final residuals show it is not aligned (they
// spread over the last level's correspondence gate and exceed their predicted σ many times: an initial pose
// too far off), or when sizes do not match.
std::vector<Eigen::Isometry3d> RegisterScans(const std::vector<Scan>& scans,
                                             const std::vector<Eigen::Isometry3d>& initial_world_from_scan,
                                             const RegisterOptions& options = {},
                                             RegisterSummary* summary = nullptr);

// The pair report of the scans at the given poses, without moving them (what `fuse --no-align` writes): the
// correspondences of the finest level. Returns "" when every scan passes RegisterScans' alignment test, else one
// line naming the scans that fail it. No overlap is required (a calibrated rig may place scans that meet no
// other): scans under min_overlap are not judged, and summary->apart lists them.
std::string CheckPoses(const std::vector<Scan>& scans, const std::vector<Eigen::Isometry3d>& poses,
                       const RegisterOptions& options = {}, RegisterSummary* summary = nullptr);

// Rotation angle (degrees) and translation distance of a_from_b·b_from_a⁻¹-style differences: the pose
// error of `estimate` relative to `reference`, both expressed relative to their first scan.
struct PoseError {
  double rotation_deg = 0;
  double translation = 0;
};
PoseError RelativePoseError(const Eigen::Isometry3d& estimate0, const Eigen::Isometry3d& estimate,
                            const Eigen::Isometry3d& reference0, const Eigen::Isometry3d& reference);

}  // namespace rangebayes

namespace rangebayes {

// The per-pair table of a registration, one line per ordered pair: names, samples, overlap, residual RMS in
// σ units and in model units (what `rangebayes fuse` writes to DIR/report.txt).
std::string FormatPairReport(const RegisterSummary& summary, const std::vector<Scan>& scans);

}  // namespace rangebayes
