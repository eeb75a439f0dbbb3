// Many scans to one model, the steps of `rangebayes fuse` and of the Python module's fuse() in their order:
// PlaceScans (align the scans, or check the given poses) and then FuseModel (smooth each scan with its own
// covariance, fuse, decimate). Two calls, so that a caller can keep the poses and the pair report before the
// longer second half runs.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "bayes/decimation/decimate.h"
#include "bayes/smooth.h"
#include "core/mesh.h"
#include "core/progress.h"
#include "fusion/register.h"
#include "fusion/scan.h"
#include "fusion/tsdf.h"

namespace rangebayes {

struct ModelOptions {
  // true: RegisterScans from the initial poses. false: the initial poses as they are, after CheckPoses (scans
  // they leave misaligned are an error).
  bool align = true;
  RegisterOptions registration;  // its progress is replaced by `progress` below
  // Each scan smoothed with its own ray covariance before fusion (SmoothScan): measured closer to the truth than
  // smoothing the fused mesh (docs/design.md §9).
  bool smooth = false;
  SmoothOptions smoothing;  // its progress is replaced by `progress` below
  FuseOptions fusion;
  bool decimate = false;       // Bayesian decimation of the fused mesh
  DecimateOptions decimation;  // its progress is replaced by `progress` below
  // Alignment ("alignment"), smoothing ("smoothing NAME", per scan) and decimation ("decimation") report here.
  ProgressCallback progress;
  void Check() const;
};

struct ModelSummary {
  // PlaceScans: the registration's (align) or the check's (the given poses) summary, and its pair table
  // (FormatPairReport); both empty for a single scan.
  RegisterSummary registration;
  std::string pair_report;
  // FuseModel: one per scan when smoothing, the fusion, and the decimation when asked for.
  std::vector<SmoothSummary> smoothing;
  FuseSummary fusion;
  bool decimated = false;
  DecimateSummary decimation;
  // What the caller should hear about (PlaceScans: scans the given poses place apart from every other, fused
  // there unchecked).
  std::vector<std::string> notices;
};

// The poses (world_from_scan, one per scan) at which the scans are fused. align: RegisterScans (the first scan
// keeps its pose; at least two scans). Else the initial poses themselves, after CheckPoses: when they leave scans
// misaligned, throws Error naming them, with *summary's registration and pair report already filled (the table
// says which pairs disagree). A single scan without align is returned as it is.
std::vector<Eigen::Isometry3d> PlaceScans(const std::vector<Scan>& scans,
                                          const std::vector<Eigen::Isometry3d>& initial_world_from_scan,
                                          const ModelOptions& options = {}, ModelSummary* summary = nullptr);

// The fused model in the world frame: the scans smoothed first when options.smooth, fused (FuseScans), and
// decimated when options.decimate. Throws Error when the fusion produces no surface (the scans share no observed
// voxels), besides FuseScans' own errors.
Mesh FuseModel(const std::vector<Scan>& scans, const std::vector<Eigen::Isometry3d>& world_from_scan,
               const ModelOptions& options = {}, ModelSummary* summary = nullptr);

}  // namespace rangebayes
