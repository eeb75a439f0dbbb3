#include "pipeline/png.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"

namespace rangebayes {

void WritePng(const RgbImage& image, const std::string& path) {
  RB_CHECK(image.width > 0 && image.height > 0, path, ": refusing to write an empty image");
  const cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.rgb.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  bool ok = false;
  try {
    ok = cv::imwrite(path, bgr);
  } catch (const cv::Exception& e) {
    RB_FAIL(path, ": cannot write PNG (", e.err, ")");
  }
  RB_CHECK(ok, path, ": cannot write PNG");
}

}  // namespace rangebayes
