#include "pipeline/png.h"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string_view>
#include <vector>

#include "core/error.h"
#include "core/files.h"

namespace rangebayes {

void WritePng(const RgbImage& image, const std::string& path) {
  RB_CHECK(image.width > 0 && image.height > 0, path, ": refusing to write an empty image");
  const cv::Mat rgb(image.height, image.width, CV_8UC3, const_cast<std::uint8_t*>(image.rgb.data()));
  cv::Mat bgr;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  // Encoded as PNG whatever the name's extension (imwrite chose the encoder by it, so `--png pic` failed after all
  // the work), and written whole or not at all.
  std::vector<std::uint8_t> bytes;
  bool ok = false;
  try {
    ok = cv::imencode(".png", bgr, bytes);
  } catch (const cv::Exception& e) {
    RB_FAIL(path, ": cannot encode PNG (", e.err, ")");
  }
  RB_CHECK(ok, path, ": cannot encode PNG");
  WriteFileAtomically(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace rangebayes
