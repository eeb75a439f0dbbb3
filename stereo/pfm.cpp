#include "stereo/pfm.h"

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "core/error.h"

namespace rangebayes {
namespace {

// Reads one whitespace-delimited header token; PFM headers are three text lines but writers differ in the
// whitespace they put between fields.
std::string Token(std::istream& in) {
  std::string token;
  char c = 0;
  while (in.get(c) && std::isspace(static_cast<unsigned char>(c))) {
  }
  if (!in) return token;
  token.push_back(c);
  while (in.get(c) && !std::isspace(static_cast<unsigned char>(c))) token.push_back(c);
  return token;  // the single whitespace after the token has been consumed
}

}  // namespace

cv::Mat ReadPfm(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  RB_CHECK(in.good(), path, ": cannot open PFM file");
  const std::string magic = Token(in);
  RB_CHECK(magic == "Pf" || magic == "PF", path, ": not a PFM file (magic '", magic, "')");
  const int channels = magic == "PF" ? 3 : 1;
  int width = 0, height = 0;
  double scale = 0.0;
  try {
    width = std::stoi(Token(in));
    height = std::stoi(Token(in));
    scale = std::stod(Token(in));
  } catch (const std::exception&) {
    RB_FAIL(path, ": malformed PFM header");
  }
  RB_CHECK(width > 0 && height > 0 && width <= 1 << 16 && height <= 1 << 16, path, ": PFM size ", width, "x",
           height, " is out of range");
  RB_CHECK(scale != 0.0 && std::isfinite(scale), path, ": PFM scale is zero or not finite");
  const bool little = scale < 0.0;
  const size_t row_floats = static_cast<size_t>(width) * channels;
  const std::streampos data_start = in.tellg();
  const auto file_size = std::filesystem::file_size(path);
  const size_t need = row_floats * height * 4;
  RB_CHECK(file_size >= static_cast<uintmax_t>(data_start) + need, path, ": PFM data is truncated (", file_size,
           " bytes, header says ", width, "x", height, "x", channels, ")");
  cv::Mat image(height, width, channels == 3 ? CV_32FC3 : CV_32F);
  std::vector<std::uint32_t> row(row_floats);
  const bool swap = little != (std::endian::native == std::endian::little);
  for (int r = 0; r < height; ++r) {
    in.read(reinterpret_cast<char*>(row.data()), static_cast<std::streamsize>(row_floats * 4));
    RB_CHECK(in.good(), path, ": PFM data is truncated at row ", r);
    if (swap) {
      for (auto& v : row) v = __builtin_bswap32(v);
    }
    float* out = image.ptr<float>(height - 1 - r);
    std::memcpy(out, row.data(), row_floats * 4);
  }
  if (channels == 3) {
    // PFM stores RGB; OpenCV's convention is BGR.
    cv::cvtColor(image, image, cv::COLOR_RGB2BGR);
  }
  return image;
}

void WritePfm(const cv::Mat& image, const std::string& path) {
  RB_CHECK(!image.empty(), path, ": refusing to write an empty PFM");
  RB_CHECK(image.depth() == CV_32F && (image.channels() == 1 || image.channels() == 3), path,
           ": PFM needs a 1- or 3-channel float image");
  cv::Mat data = image;
  if (image.channels() == 3) cv::cvtColor(image, data, cv::COLOR_BGR2RGB);
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  RB_CHECK(out.good(), path, ": cannot open for writing");
  out << (image.channels() == 3 ? "PF" : "Pf") << "\n" << image.cols << " " << image.rows << "\n";
  out << (std::endian::native == std::endian::little ? "-1.0" : "1.0") << "\n";
  const size_t row_bytes = static_cast<size_t>(image.cols) * image.channels() * 4;
  for (int r = image.rows - 1; r >= 0; --r) {
    out.write(reinterpret_cast<const char*>(data.ptr<float>(r)), static_cast<std::streamsize>(row_bytes));
  }
  out.flush();
  RB_CHECK(out.good(), path, ": write failed (disk full?)");
}

}  // namespace rangebayes
