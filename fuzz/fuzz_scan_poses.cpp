// libFuzzer entry for bun.conf-style pose files (ReadScanPoses): any input reads or throws
// rangebayes::Error; poses read are finite rigid transforms that survive a write/read round trip.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/error.h"
#include "core/scan_poses.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rangebayes;
  const std::string path = fuzz::WriteScratch("in.conf", std::string_view(reinterpret_cast<const char*>(data), size));
  std::vector<ScanPose> poses;
  try {
    poses = ReadScanPoses(path);
  } catch (const Error&) {
    return 0;
  }
  fuzz::Require(!poses.empty(), "at least one pose");
  for (const ScanPose& pose : poses) {
    fuzz::RequireFinite(pose.world_from_scan.matrix(), "pose");
    const Eigen::Matrix3d R = pose.world_from_scan.linear();
    fuzz::Require((R * R.transpose() - Eigen::Matrix3d::Identity()).norm() < 1e-9, "rotation is orthonormal");
  }
  const std::string written = fuzz::ScratchDir() + "/out.conf";
  WriteScanPoses(poses, written);
  const std::vector<ScanPose> back = ReadScanPoses(written);
  fuzz::Require(back.size() == poses.size(), "round trip keeps every pose");
  for (size_t i = 0; i < poses.size(); ++i) {
    fuzz::Require(back[i].file == poses[i].file, "round trip keeps the file names");
    fuzz::Require((back[i].world_from_scan.matrix() - poses[i].world_from_scan.matrix()).norm() <=
                      1e-9 * (1 + poses[i].world_from_scan.matrix().norm()),
                  "round trip keeps the pose");
  }
  return 0;
}
