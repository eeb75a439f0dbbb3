// Shared synthetic scenes of the fusion tests.
#pragma once

#include <cmath>
#include <vector>

#include "fusion/scan.h"
#include "fusion/synthetic_scan.h"

namespace rangebayes::testing {

// A bumpy closed blob (no rotational symmetry, so alignment is well posed), radius about 5 cm.
inline Mesh MakeBlob() {
  Mesh mesh = MakeSphereMesh(0.05, Eigen::Vector3d::Zero(), 48);
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    const Eigen::Vector3d p = mesh.V.row(i);
    const double theta = std::acos(std::clamp(p.z() / p.norm(), -1.0, 1.0)), phi = std::atan2(p.y(), p.x());
    const double scale = 1.0 + 0.12 * std::sin(3 * theta) * std::cos(2 * phi) + 0.08 * std::cos(5 * phi) *
                                                                                      std::sin(theta);
    mesh.V.row(i) = p * scale;
  }
  return mesh;
}

// world_from_scan for a scanner at `yaw_deg` around the y axis (looking at the origin along its −z).
inline Eigen::Isometry3d ViewPose(double yaw_deg, double pitch_deg = 0) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = (Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitY()) *
                   Eigen::AngleAxisd(pitch_deg * M_PI / 180, Eigen::Vector3d::UnitX()))
                      .toRotationMatrix();
  pose.translation() = pose.linear() * Eigen::Vector3d(0, 0, 0.0);
  return pose;
}

inline std::vector<Scan> RenderViews(const Mesh& truth, const std::vector<Eigen::Isometry3d>& poses,
                                     double sigma_range, int cells = 90, double spacing = 1.4e-3) {
  std::vector<Scan> scans;
  for (size_t k = 0; k < poses.size(); ++k) {
    SyntheticScanOptions options;
    options.width = options.height = cells;
    options.spacing = spacing;
    options.sigma_range = sigma_range;
    options.seed = 10 + k;
    RangeGridScanOptions grid;
    grid.sigma_range = std::max(sigma_range, 1e-6);
    grid.sigma_lateral = grid.sigma_range / 4;
    scans.push_back(MakeRangeGridScan(RenderSyntheticScan(truth, poses[k], options), "view" + std::to_string(k),
                                      grid));
  }
  return scans;
}

}  // namespace rangebayes::testing
