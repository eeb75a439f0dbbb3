#include "stereo/disparity_io.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "calibration/middlebury.h"
#include "core/error.h"
#include "core/files.h"
#include "stereo/pfm.h"

namespace rangebayes {

namespace fs = std::filesystem;

bool EndsWithPfm(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".pfm";
}

cv::Mat ReadDisparityMap(const std::string& path, double scale) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  if (EndsWithPfm(path)) {
    // It was divided by a scale > 0 and read as stored for any other, where the help and the docs said PNG only.
    RB_CHECK(scale == 1.0, path, ": a PFM holds disparities; a scale (", scale, ") is for PNG/PGM maps");
    CheckFileToRead(path, "disparity map");
    cv::Mat d = ReadPfm(path);
    RB_CHECK(d.channels() == 1, path, ": disparity PFM must have one channel");
    for (int y = 0; y < d.rows; ++y) {
      float* p = d.ptr<float>(y);
      for (int x = 0; x < d.cols; ++x) {
        if (!std::isfinite(p[x])) p[x] = nan;
      }
    }
    return d;
  }
  RB_CHECK(scale > 0.0, path, ": a disparity image needs a positive scale (got ", scale, ")");
  cv::Mat image = ReadImage(path, cv::IMREAD_UNCHANGED);
  if (image.channels() > 1) {
    // A grey map stored with equal channels is read; a colour picture (stereo's disparity.png) was read as data
    // from its first channel and scored without a word.
    std::vector<cv::Mat> channels;
    cv::split(image, channels);
    for (size_t c = 1; c < std::min<size_t>(channels.size(), 3); ++c) {
      RB_CHECK(cv::countNonZero(channels[c] != channels[0]) == 0, path,
               ": a colour image, not a disparity map (its channels differ; the disparity.png that `stereo` writes "
               "is a picture: use its disparity.pfm)");
    }
    image = channels[0];
  }
  cv::Mat d;
  image.convertTo(d, CV_32F, 1.0 / scale);
  d.setTo(nan, image == 0);
  return d;
}

cv::Mat ReadMask(const std::string& path, int value) {
  cv::Mat image = ReadImage(path, cv::IMREAD_UNCHANGED);
  if (image.channels() > 1) cv::extractChannel(image, image, 0);
  cv::Mat mask = image == value;
  return mask;
}

MiddleburyScene ReadMiddleburyScene(const std::string& folder) {
  RB_CHECK(fs::is_directory(folder), folder, ": scene folder not found");
  const auto has = [&](const char* name) { return fs::is_regular_file(fs::path(folder) / name); };
  const auto at = [&](const char* name) { return (fs::path(folder) / name).string(); };
  MiddleburyScene scene;
  scene.folder = folder;
  double scale = 0.0;
  std::string left, right, gt, mask;
  if (has("im0.png") && has("im1.png")) {
    scene.layout = "2014";
    left = at("im0.png");
    right = at("im1.png");
    if (has("disp0GT.pfm")) gt = at("disp0GT.pfm");
    if (has("mask0nocc.png")) mask = at("mask0nocc.png");
    scale = 1.0;
    if (has("calib.txt")) {
      const MiddleburyCalib calib = ReadMiddleburyCalib(at("calib.txt"));
      scene.num_disparities = calib.ndisp;
      scene.rig = StereoRigFromMiddlebury(calib);
    }
  } else if (has("imL.png") && has("imR.png")) {
    scene.layout = "v2";
    left = at("imL.png");
    right = at("imR.png");
    if (has("groundtruth.png")) gt = at("groundtruth.png");
    if (has("nonocc.png")) mask = at("nonocc.png");
    RB_CHECK(has("info.txt"), folder, ": v2 layout without info.txt (scale, disparity levels)");
    std::ifstream info(at("info.txt"));
    RB_CHECK(static_cast<bool>(info >> scale >> scene.num_disparities) && scale > 0, at("info.txt"),
             ": expected two numbers (scale, disparity levels)");
  } else if (has("view1.png") && has("view5.png")) {
    scene.layout = "2005";
    left = at("view1.png");
    right = at("view5.png");
    if (has("disp1.png")) gt = at("disp1.png");
    scale = 3.0;
  } else if (has("im2.ppm") && has("im6.ppm")) {
    scene.layout = "2001";
    left = at("im2.ppm");
    right = at("im6.ppm");
    if (has("disp2.pgm")) gt = at("disp2.pgm");
    scale = 8.0;
  } else if (has("im2.png") && has("im6.png")) {
    scene.layout = "2003";
    left = at("im2.png");
    right = at("im6.png");
    if (has("disp2.png")) gt = at("disp2.png");
    scale = 4.0;
  } else {
    RB_FAIL(folder, ": not a Middlebury scene folder (no im0/im1, imL/imR, view1/view5 or im2/im6 images)");
  }
  scene.left = ReadImage(left, cv::IMREAD_COLOR);
  scene.right = ReadImage(right, cv::IMREAD_COLOR);
  RB_CHECK(scene.left.size() == scene.right.size(), folder, ": left and right images differ in size");
  if (!gt.empty()) {
    scene.gt_disparity_px = ReadDisparityMap(gt, scale);
    RB_CHECK(scene.gt_disparity_px.size() == scene.left.size(), gt, ": ground truth size differs from the images");
  }
  if (!mask.empty()) {
    scene.mask_nonocc = ReadMask(mask, 255);
    RB_CHECK(scene.mask_nonocc.size() == scene.left.size(), mask, ": mask size differs from the images");
  }
  if (scene.num_disparities <= 0 && !scene.gt_disparity_px.empty()) {
    double hi = 0.0;
    cv::Mat finite = scene.gt_disparity_px == scene.gt_disparity_px;
    cv::minMaxLoc(scene.gt_disparity_px, nullptr, &hi, nullptr, nullptr, finite);
    scene.num_disparities = static_cast<int>(std::ceil(hi)) + 1;
  }
  return scene;
}

}  // namespace rangebayes
