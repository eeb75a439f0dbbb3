#include "calibration/middlebury.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include "core/error.h"
#include "core/files.h"

namespace rangebayes {
namespace {

std::string Trim(const std::string& s) {
  const auto a = s.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return "";
  const auto b = s.find_last_not_of(" \t\r\n");
  return s.substr(a, b - a + 1);
}

Eigen::Matrix3d ParseMatrix(const std::string& path, const std::string& key, const std::string& value) {
  std::string v = value;
  RB_CHECK(v.size() >= 2 && v.front() == '[' && v.back() == ']', path, ": '", key,
           "' is not a [a b c; d e f; g h i] matrix");
  for (char& c : v) {
    if (c == '[' || c == ']' || c == ';' || c == ',') c = ' ';
  }
  std::istringstream in(v);
  Eigen::Matrix3d m;
  for (int i = 0; i < 9; ++i) {
    RB_CHECK(static_cast<bool>(in >> m(i / 3, i % 3)), path, ": '", key, "' needs 9 numbers");
  }
  std::string extra;
  RB_CHECK(!(in >> extra), path, ": '", key, "' has more than 9 numbers");
  return m;
}

double ParseNumber(const std::string& path, const std::string& key, const std::string& value) {
  try {
    size_t used = 0;
    const double x = std::stod(value, &used);
    RB_CHECK(Trim(value.substr(used)).empty(), path, ": '", key, "' = '", value, "' is not a number");
    return x;
  } catch (const std::logic_error&) {
    RB_FAIL(path, ": '", key, "' = '", value, "' is not a number");
  }
}

// A whole number in [lo, hi] (image sizes, disparity counts), checked before the cast to int.
int ParseCount(const std::string& path, const std::string& key, const std::string& value, int lo, int hi) {
  const double x = ParseNumber(path, key, value);
  RB_CHECK(std::isfinite(x) && x == std::floor(x) && x >= lo && x <= hi, path, ": '", key, "' = '", value,
           "' is not a whole number in [", lo, ", ", hi, "]");
  return static_cast<int>(x);
}

}  // namespace

MiddleburyCalib ReadMiddleburyCalib(const std::string& path) {
  CheckFileToRead(path, "calib file");
  std::ifstream in(path);
  RB_CHECK(in.good(), path, ": cannot open");
  std::map<std::string, std::string> values;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    line = Trim(line);
    if (line.empty() || line[0] == '#') continue;
    const bool text = std::all_of(line.begin(), line.end(), [](char c) {
      const auto u = static_cast<unsigned char>(c);
      return u == '\t' || (u >= 0x20 && u < 0x7f);
    });
    RB_CHECK(text, path, ": line ", number, " is not text: not a Middlebury calib.txt");
    const auto eq = line.find('=');
    RB_CHECK(eq != std::string::npos, path, ": line ", number, " '", line, "' is not key=value");
    values[Trim(line.substr(0, eq))] = Trim(line.substr(eq + 1));
  }
  const auto require = [&](const char* key) -> const std::string& {
    const auto it = values.find(key);
    RB_CHECK(it != values.end(), path, ": key '", key, "' is missing");
    return it->second;
  };
  MiddleburyCalib c;
  c.cam0 = ParseMatrix(path, "cam0", require("cam0"));
  c.cam1 = ParseMatrix(path, "cam1", require("cam1"));
  c.baseline_mm = ParseNumber(path, "baseline", require("baseline"));
  c.width = ParseCount(path, "width", require("width"), 1, 1 << 16);
  c.height = ParseCount(path, "height", require("height"), 1, 1 << 16);
  if (values.count("doffs")) c.doffs_px = ParseNumber(path, "doffs", values["doffs"]);
  if (values.count("ndisp")) c.ndisp = ParseCount(path, "ndisp", values["ndisp"], 0, 1 << 16);
  if (values.count("vmin")) c.vmin = ParseNumber(path, "vmin", values["vmin"]);
  if (values.count("vmax")) c.vmax = ParseNumber(path, "vmax", values["vmax"]);
  RB_CHECK(c.cam0(0, 0) > 0 && c.cam1(0, 0) > 0, path, ": focal length must be positive");
  // The pair is rectified: one focal length and one principal row for both views, only cx may differ (doffs).
  // cam1's own values were dropped without a word.
  const auto same = [](double a, double b) { return std::abs(a - b) <= 1e-3 * std::max(std::abs(a), std::abs(b)); };
  RB_CHECK(same(c.cam0(0, 0), c.cam1(0, 0)) && same(c.cam0(1, 1), c.cam1(1, 1)) && same(c.cam0(1, 2), c.cam1(1, 2)),
           path, ": cam0 and cam1 differ in focal length or principal row (fx ", c.cam0(0, 0), " / ", c.cam1(0, 0),
           ", fy ", c.cam0(1, 1), " / ", c.cam1(1, 1), ", cy ", c.cam0(1, 2), " / ", c.cam1(1, 2),
           "): not the calibration of a rectified pair");
  RB_CHECK(c.baseline_mm > 0, path, ": baseline must be positive");
  RB_CHECK(c.width > 0 && c.height > 0, path, ": width/height must be positive");
  return c;
}

StereoRig StereoRigFromMiddlebury(const MiddleburyCalib& calib) {
  StereoRig rig;
  rig.width = calib.width;
  rig.height = calib.height;
  rig.K_left = calib.cam0;
  rig.K_right = calib.cam1;
  rig.R_right_from_left.setIdentity();
  // Rectified views have no distortion: the distortion vectors stay empty.
  const double b = calib.baseline_mm / 1000.0;
  rig.t_right_from_left_m = Eigen::Vector3d(-b, 0.0, 0.0);
  rig.is_rectified = true;
  rig.P1.setZero();
  rig.P1.leftCols<3>() = calib.cam0;
  rig.P2.setZero();
  rig.P2.leftCols<3>() = calib.cam1;
  rig.P2(0, 3) = -calib.cam1(0, 0) * b;
  rig.doffs_px = calib.doffs_px;
  // OpenCV's Q maps (x, y, d, 1) to homogeneous 3-D; with doffs, Q(3,3) = doffs / (f·B) (principal points differ).
  const double f = calib.cam0(0, 0);
  rig.Q.setZero();
  rig.Q(0, 0) = 1.0;
  rig.Q(1, 1) = 1.0;
  rig.Q(0, 3) = -calib.cam0(0, 2);
  rig.Q(1, 3) = -calib.cam0(1, 2);
  rig.Q(2, 3) = f;
  rig.Q(3, 2) = 1.0 / b;
  rig.Q(3, 3) = calib.doffs_px / b;
  return rig;
}

}  // namespace rangebayes
