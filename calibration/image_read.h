// Reading an image file, one way for every module that reads images (calibration is the lowest one with OpenCV).
#pragma once

#include <opencv2/core.hpp>
#include <string>

namespace rangebayes {

// Reads an image with cv::imread's `flags` (cv::IMREAD_COLOR, cv::IMREAD_GRAYSCALE, cv::IMREAD_UNCHANGED, ...).
// The file's bytes are checked first (core/image_file.h: a PNG or JPEG cut short is refused, not decoded with its
// missing part grey). Throws Error naming the file when it is missing, not a file, or not a readable image.
cv::Mat ReadImage(const std::string& path, int flags);

}  // namespace rangebayes
