// Pose files of multi-scan sets in the Stanford `.conf` format (bun.conf): one line per scan,
//   bmesh FILE tx ty tz qx qy qz qw
// meaning p_world = R(q)ᵀ·p_scan + t, R(q) the rotation matrix of the unit quaternion (x, y, z, w): the file's
// quaternion rotates by its conjugate (measured on the Stanford bunny, docs/design.md §9). A `camera ...` line (a
// viewer setting) is ignored on reading and not written.
#pragma once

#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace rangebayes {

struct ScanPose {
  std::string file;                  // as written in the pose file (a name relative to the file's folder)
  Eigen::Isometry3d world_from_scan = Eigen::Isometry3d::Identity();
};

// Reads a pose file. Throws Error with the file, line and scan named on: a line with another keyword or the
// wrong number of fields, a number that does not parse or is not finite, a quaternion whose norm is not 1
// within 1e-3 (it is renormalised when within), the same scan listed twice, or no scan at all.
std::vector<ScanPose> ReadScanPoses(const std::string& path);

// Writes `poses` in the same format (17 significant digits, quaternion with qw ≥ 0). Throws Error when the
// file cannot be written or a pose is not a finite rigid transform.
void WriteScanPoses(const std::vector<ScanPose>& poses, const std::string& path);

// The pose of the scan named `file` among `poses`, matched on the file name without its folder. Throws Error
// naming the scan and the pose file when it is missing.
const ScanPose& FindScanPose(const std::vector<ScanPose>& poses, const std::string& file,
                             const std::string& pose_file);

// The file name without its folder ("a/b/bun000.ply" → "bun000.ply").
std::string FileBaseName(const std::string& path);

}  // namespace rangebayes
