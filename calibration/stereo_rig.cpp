#include "calibration/stereo_rig.h"

#include <Eigen/LU>
#include <cmath>
#include <exception>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>

#include "calibration/opencv_yaml.h"
#include "core/error.h"
#include "core/files.h"

namespace rangebayes {
namespace {

template <typename EigenType>
void ReadMatrix(const cv::FileStorage& fs, const std::string& path, const char* name, EigenType* out,
                bool required) {
  const cv::FileNode node = fs[name];
  if (node.empty()) {
    RB_CHECK(!required, path, ": field '", name, "' is missing");
    return;
  }
  // Checked before OpenCV reads the matrix, which allocates rows·cols first: a rig's matrices are small.
  RB_CHECK(node.isMap() && node["rows"].isInt() && node["cols"].isInt(), path, ": field '", name,
           "' is not an OpenCV matrix (rows, cols, dt, data)");
  const int rows = static_cast<int>(node["rows"]), cols = static_cast<int>(node["cols"]);
  const size_t values = node["data"].isSeq() ? node["data"].size() : 0;
  RB_CHECK(rows >= 0 && cols >= 0 && rows <= 16 && cols <= 16 &&
               values == static_cast<size_t>(rows) * static_cast<size_t>(cols),
           path, ": field '", name, "' is ", rows, "x", cols, " with ", values,
           " values (a rig matrix has at most 16x16, one value per entry)");
  cv::Mat m;
  node >> m;
  if constexpr (EigenType::RowsAtCompileTime != Eigen::Dynamic && EigenType::ColsAtCompileTime != Eigen::Dynamic) {
    RB_CHECK(!m.empty(), path, ": field '", name, "' is not a matrix");
  } else if (m.empty()) {
    // An empty distortion vector (no distortion) is what WriteStereoRig writes for a rig without one.
    out->resize(0);
    return;
  }
  m.convertTo(m, CV_64F);
  if constexpr (EigenType::RowsAtCompileTime != Eigen::Dynamic && EigenType::ColsAtCompileTime != Eigen::Dynamic) {
    RB_CHECK(m.rows == EigenType::RowsAtCompileTime && m.cols == EigenType::ColsAtCompileTime, path, ": field '",
             name, "' is ", m.rows, "x", m.cols, ", expected ", EigenType::RowsAtCompileTime, "x",
             EigenType::ColsAtCompileTime);
    cv::cv2eigen(m, *out);
  } else {
    m = m.reshape(1, static_cast<int>(m.total()));
    Eigen::MatrixXd tmp;
    cv::cv2eigen(m, tmp);
    *out = tmp;
  }
  RB_CHECK(out->allFinite(), path, ": field '", name, "' has non-finite entries");
}

template <typename EigenType>
cv::Mat ToMat(const EigenType& e) {
  cv::Mat m;
  cv::eigen2cv(Eigen::MatrixXd(e), m);
  return m;
}

}  // namespace

CameraIntrinsics StereoRig::RectifiedLeft() const {
  CameraIntrinsics k;
  k.width = width;
  k.height = height;
  const bool have_p1 = P1(0, 0) > 0.0;
  k.fx_px = have_p1 ? P1(0, 0) : K_left(0, 0);
  k.fy_px = have_p1 ? P1(1, 1) : K_left(1, 1);
  k.cx_px = have_p1 ? P1(0, 2) : K_left(0, 2);
  k.cy_px = have_p1 ? P1(1, 2) : K_left(1, 2);
  return k;
}

double StereoRig::baseline_m() const { return t_right_from_left_m.norm(); }

void StereoRig::Check() const {
  RB_CHECK(width > 0 && height > 0, "image size ", width, "x", height, " is not positive");
  RB_CHECK(K_left.allFinite() && K_right.allFinite() && distortion_left.allFinite() && distortion_right.allFinite() &&
               R_right_from_left.allFinite() && t_right_from_left_m.allFinite() && R1.allFinite() && R2.allFinite() &&
               P1.allFinite() && P2.allFinite() && Q.allFinite() && std::isfinite(doffs_px),
           "the rig has non-finite entries");
  // OpenCV's models: none, 4, 5, 8, 12 or 14 coefficients (another length failed deep in the rectification maps).
  for (const auto& [name, d] : {std::pair<const char*, const Eigen::VectorXd&>{"D_left", distortion_left},
                                std::pair<const char*, const Eigen::VectorXd&>{"D_right", distortion_right}}) {
    const Eigen::Index n = d.size();
    RB_CHECK(n == 0 || n == 4 || n == 5 || n == 8 || n == 12 || n == 14, name, " has ", n,
             " coefficients; OpenCV's distortion models have 4, 5, 8, 12 or 14");
  }
  RB_CHECK(K_left(0, 0) > 0 && K_left(1, 1) > 0, "K_left has a non-positive focal length");
  RB_CHECK(K_right(0, 0) > 0 && K_right(1, 1) > 0, "K_right has a non-positive focal length");
  RB_CHECK(baseline_m() > 0, "T (baseline) is zero");
  // R turns left-camera coordinates into right-camera ones; a scaled, sheared or mirrored matrix would bend every
  // depth.
  const Eigen::Matrix3d& R = R_right_from_left;
  const double off = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  RB_CHECK(off <= 1e-3 && R.determinant() > 0, "R is not a rotation (RᵀR differs from I by ", off, ", det ",
           R.determinant(), ")");
}

StereoRig ReadStereoRig(const std::string& path) {
  CheckFileToRead(path, "rig file");
  CheckOpenCvYamlSubset(path, "rig file");
  cv::FileStorage fs;
  try {
    fs.open(path, cv::FileStorage::READ);
  } catch (const cv::Exception& e) {
    RB_FAIL(path, ": not a readable OpenCV YAML rig file (", e.err, ")");
  } catch (const std::exception& e) {
    // OpenCV's YAML parser lets std::length_error out on some malformed files (fuzz_rig_yaml).
    RB_FAIL(path, ": not a readable OpenCV YAML rig file (", e.what(), ")");
  }
  RB_CHECK(fs.isOpened(), path, ": not a readable OpenCV YAML rig file");
  StereoRig rig;
  try {
    const cv::FileNode w = fs["image_width"], h = fs["image_height"];
    RB_CHECK(!w.empty() && !h.empty(), path, ": fields 'image_width'/'image_height' are missing");
    rig.width = static_cast<int>(w);
    rig.height = static_cast<int>(h);
    RB_CHECK(rig.width > 0 && rig.height > 0, path, ": image size ", rig.width, "x", rig.height, " is not positive");
    ReadMatrix(fs, path, "K_left", &rig.K_left, true);
    ReadMatrix(fs, path, "K_right", &rig.K_right, true);
    ReadMatrix(fs, path, "D_left", &rig.distortion_left, false);
    ReadMatrix(fs, path, "D_right", &rig.distortion_right, false);
    ReadMatrix(fs, path, "R", &rig.R_right_from_left, true);
    ReadMatrix(fs, path, "T", &rig.t_right_from_left_m, true);
    ReadMatrix(fs, path, "R1", &rig.R1, false);
    ReadMatrix(fs, path, "R2", &rig.R2, false);
    ReadMatrix(fs, path, "P1", &rig.P1, false);
    ReadMatrix(fs, path, "P2", &rig.P2, false);
    ReadMatrix(fs, path, "Q", &rig.Q, false);
    if (!fs["is_rectified"].empty()) rig.is_rectified = static_cast<int>(fs["is_rectified"]) != 0;
    if (!fs["doffs_px"].empty()) rig.doffs_px = static_cast<double>(fs["doffs_px"]);
    if (!fs["rms_left_px"].empty()) rig.rms_left_px = static_cast<double>(fs["rms_left_px"]);
    if (!fs["rms_right_px"].empty()) rig.rms_right_px = static_cast<double>(fs["rms_right_px"]);
    if (!fs["rms_stereo_px"].empty()) rig.rms_stereo_px = static_cast<double>(fs["rms_stereo_px"]);
    if (!fs["epipolar_error_px"].empty()) rig.epipolar_error_px = static_cast<double>(fs["epipolar_error_px"]);
    if (!fs["view_names"].empty()) fs["view_names"] >> rig.view_names;
    if (!fs["view_rms_stereo_px"].empty()) fs["view_rms_stereo_px"] >> rig.view_rms_stereo_px;
  } catch (const cv::Exception& e) {
    RB_FAIL(path, ": malformed rig file (", e.err, ")");
  } catch (const Error&) {
    throw;
  } catch (const std::exception& e) {
    RB_FAIL(path, ": malformed rig file (", e.what(), ")");
  }
  try {
    rig.Check();
  } catch (const Error& e) {
    RB_FAIL(path, ": ", e.what());
  }
  return rig;
}

void WriteStereoRig(const StereoRig& rig, const std::string& path) {
  try {
    rig.Check();
  } catch (const Error& e) {
    RB_FAIL(path, ": not written: ", e.what());
  }
  cv::FileStorage fs(path, cv::FileStorage::WRITE);
  RB_CHECK(fs.isOpened(), path, ": cannot open for writing");
  fs << "image_width" << rig.width << "image_height" << rig.height;
  fs << "K_left" << ToMat(rig.K_left) << "D_left" << ToMat(rig.distortion_left);
  fs << "K_right" << ToMat(rig.K_right) << "D_right" << ToMat(rig.distortion_right);
  fs << "R" << ToMat(rig.R_right_from_left) << "T" << ToMat(rig.t_right_from_left_m);
  fs << "is_rectified" << static_cast<int>(rig.is_rectified);
  fs << "R1" << ToMat(rig.R1) << "R2" << ToMat(rig.R2) << "P1" << ToMat(rig.P1) << "P2" << ToMat(rig.P2)
     << "Q" << ToMat(rig.Q);
  fs << "doffs_px" << rig.doffs_px;
  fs << "rms_left_px" << rig.rms_left_px << "rms_right_px" << rig.rms_right_px << "rms_stereo_px"
     << rig.rms_stereo_px;
  fs << "epipolar_error_px" << rig.epipolar_error_px;
  if (!rig.view_names.empty()) fs << "view_names" << rig.view_names;
  if (!rig.view_rms_stereo_px.empty()) fs << "view_rms_stereo_px" << rig.view_rms_stereo_px;
}

}  // namespace rangebayes
