// Reading disparity maps and Middlebury scenes (2001, 2003, 2005/2006, v2 evaluation and 2014 layouts).
#pragma once

#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "calibration/image_read.h"  // ReadImage, for the readers here and their callers
#include "calibration/stereo_rig.h"

namespace rangebayes {

// Reads a disparity map as CV_32F pixels with NaN where unknown. PFM: values as stored, non-finite → NaN (scale
// must be 1). PNG/PGM/PPM (8 or 16 bit; one channel, or channels that are all equal): value / scale, 0 → NaN
// (Middlebury's "unknown"); scale must be > 0 for these. Throws Error naming the file when it is missing or
// unreadable, a colour image, or a PFM given a scale.
cv::Mat ReadDisparityMap(const std::string& path, double scale = 1.0);

bool EndsWithPfm(const std::string& path);  // the .pfm extension, in any case

// Reads a mask image (8/16-bit): returns CV_8U with 255 where the pixel equals `value` (e.g. 255 in
// Middlebury's nonocc masks), 0 elsewhere. Throws Error naming the file.
cv::Mat ReadMask(const std::string& path, int value = 255);

// One Middlebury scene folder.
struct MiddleburyScene {
  std::string folder;
  std::string layout;             // "2014", "v2", "2005", "2001", "2003"
  cv::Mat left, right;            // as stored (colour, BGR)
  cv::Mat gt_disparity_px;        // CV_32F, NaN unknown; empty when the folder has none
  cv::Mat mask_nonocc;            // CV_8U, 255 = non-occluded pixel to evaluate; empty when the folder has none
  int num_disparities = 0;        // search range from calib.txt/info.txt, else from the ground truth (max + 1)
  std::optional<StereoRig> rig;   // 2014 only (calib.txt): rectified rig with doffs
};

// Detects the layout by its file names:
//   2014: im0.png im1.png [disp0GT.pfm] [mask0nocc.png: 255 non-occluded] calib.txt
//   v2:   imL.png imR.png groundtruth.png info.txt (scale, ndisp) [nonocc.png]
//   2005/2006: view1.png view5.png disp1.png (disparity = value / 3)
//   2001: im2.ppm im6.ppm disp2.pgm (disparity = value / 8)
//   2003: im2.png im6.png disp2.png (disparity = value / 4)
// Throws Error naming the folder when no layout matches or a file is unreadable.
MiddleburyScene ReadMiddleburyScene(const std::string& folder);

}  // namespace rangebayes
