#include "calibration/image_read.h"

#include <opencv2/imgcodecs.hpp>

#include "core/error.h"
#include "core/image_file.h"

namespace rangebayes {

cv::Mat ReadImage(const std::string& path, int flags) {
  CheckImageFile(path, "image");
  cv::Mat image;
  try {
    image = cv::imread(path, flags);
  } catch (const cv::Exception& e) {
    RB_FAIL(path, ": unreadable image (", e.err, ")");
  }
  RB_CHECK(!image.empty(), path, ": unreadable image");
  return image;
}

}  // namespace rangebayes
