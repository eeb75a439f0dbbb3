// Portable float map (PFM) images: the format of Middlebury's ground-truth disparities and of our own
// float outputs (disparity.pfm, depth.pfm, sigma PFMs).
#pragma once

#include <opencv2/core.hpp>
#include <string>

namespace rangebayes {

// Reads a PFM file ("Pf" one channel, "PF" three channels). Rows are stored bottom to top in the file and
// come back top to bottom; the sign of the scale gives the byte order (negative: little endian). Values are
// returned as stored (Middlebury uses inf for "unknown"). Returns CV_32F or CV_32FC3. Throws Error naming the
// file on a missing file, a malformed header, a file shorter than width·height·channels·4 bytes, or data that
// reads as implausible values (over a quarter beyond 1e±20) in the declared byte order and as plausible ones
// (under 1%) in the other: a scale of the wrong sign.
cv::Mat ReadPfm(const std::string& path);

// Writes a CV_32F (or CV_32FC3) image as little-endian PFM, rows bottom to top. NaN and inf are written as
// they are. Throws Error naming the file when it cannot be written or the type is not float.
void WritePfm(const cv::Mat& image, const std::string& path);

}  // namespace rangebayes
