#include "core/scan_poses.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "core/error.h"
#include "core/files.h"

namespace rangebayes {

std::string FileBaseName(const std::string& path) {
  const size_t slash = path.find_last_of('/');
  return slash == std::string::npos ? path : path.substr(slash + 1);
}

std::vector<ScanPose> ReadScanPoses(const std::string& path) {
  std::ifstream in(path);
  RB_CHECK(in.good(), path, ": cannot open pose file");
  std::vector<ScanPose> poses;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    std::istringstream words(line);
    std::string key;
    if (!(words >> key) || key[0] == '#') continue;
    if (key == "camera") continue;
    RB_CHECK(key == "bmesh", path, ": line ", line_number, ": unknown keyword '", key,
             "' (expected 'bmesh FILE tx ty tz qx qy qz qw')");
    ScanPose pose;
    RB_CHECK(static_cast<bool>(words >> pose.file), path, ": line ", line_number, ": 'bmesh' without a scan file");
    double v[7];
    for (int k = 0; k < 7; ++k) {
      std::string word;
      RB_CHECK(static_cast<bool>(words >> word), path, ": line ", line_number, ": scan ", pose.file, " has ", k,
               " of the 7 numbers tx ty tz qx qy qz qw");
      char* end = nullptr;
      v[k] = std::strtod(word.c_str(), &end);
      RB_CHECK(end != word.c_str() && *end == '\0', path, ": line ", line_number, ": scan ", pose.file,
               ": '", word, "' is not a number");
      RB_CHECK(std::isfinite(v[k]), path, ": line ", line_number, ": scan ", pose.file, ": value ", k + 1,
               " is ", word, " (not finite)");
    }
    std::string extra;
    RB_CHECK(!(words >> extra), path, ": line ", line_number, ": scan ", pose.file,
             ": more than 7 numbers after the file name");
    Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
    const double norm = q.norm();
    RB_CHECK(std::abs(norm - 1.0) <= 1e-3, path, ": line ", line_number, ": scan ", pose.file,
             ": quaternion (", v[3], " ", v[4], " ", v[5], " ", v[6], ") has norm ", norm, ", not 1");
    q.normalize();
    for (const ScanPose& other : poses) {
      RB_CHECK(FileBaseName(other.file) != FileBaseName(pose.file), path, ": line ", line_number, ": scan ",
               pose.file, " is listed twice");
    }
    pose.world_from_scan.linear() = q.toRotationMatrix().transpose();
    pose.world_from_scan.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
    poses.push_back(pose);
  }
  RB_CHECK(!poses.empty(), path, ": no 'bmesh FILE tx ty tz qx qy qz qw' line");
  return poses;
}

void WriteScanPoses(const std::vector<ScanPose>& poses, const std::string& path) {
  std::ostringstream out;
  out.precision(17);
  for (const ScanPose& pose : poses) {
    const Eigen::Matrix3d R = pose.world_from_scan.linear();
    const Eigen::Vector3d t = pose.world_from_scan.translation();
    RB_CHECK(R.allFinite() && t.allFinite() && (R * R.transpose() - Eigen::Matrix3d::Identity()).norm() < 1e-6 &&
                 R.determinant() > 0,
             path, ": pose of scan ", pose.file,
             " is not a finite rotation and translation");  // a mirror has no quaternion
    RB_CHECK(!pose.file.empty() && pose.file.find_first_of(" \t\n") == std::string::npos, path,
             ": scan file name '", pose.file, "' is empty or has blanks");
    // p_world = R(q)ᵀ p + t: the file's q is the conjugate of the rotation world_from_scan.
    Eigen::Quaterniond q(R.transpose());
    q.normalize();
    if (q.w() < 0) q.coeffs() *= -1.0;
    out << "bmesh " << pose.file << ' ' << t.x() << ' ' << t.y() << ' ' << t.z() << ' ' << q.x() << ' ' << q.y()
        << ' ' << q.z() << ' ' << q.w() << '\n';
  }
  WriteFileAtomically(path, out.str());
}

const ScanPose& FindScanPose(const std::vector<ScanPose>& poses, const std::string& file,
                             const std::string& pose_file) {
  const std::string name = FileBaseName(file);
  for (const ScanPose& pose : poses) {
    if (FileBaseName(pose.file) == name) return pose;
  }
  RB_FAIL(pose_file, ": no pose for scan ", name, " (the file lists ", poses.size(), " scans)");
}

}  // namespace rangebayes
