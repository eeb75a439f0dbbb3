// libFuzzer entry for PFM disparity/depth files (ReadPfm): any input reads or throws rangebayes::Error; an
// image read has the size its header declares, bounded by the file's size. Pixel values are returned as
// stored (NaN and inf are valid PFM content: "no value").
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/error.h"
#include "fuzz/fuzz_util.h"
#include "stereo/pfm.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rangebayes;
  const std::string path = fuzz::WriteScratch("in.pfm", std::string_view(reinterpret_cast<const char*>(data), size));
  cv::Mat image;
  try {
    image = ReadPfm(path);
  } catch (const Error&) {
    return 0;
  }
  fuzz::Require(!image.empty() && (image.type() == CV_32F || image.type() == CV_32FC3), "float image");
  fuzz::Require(image.total() * image.elemSize() <= size, "pixels fit in the file");
  return 0;
}
