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

// A float's bits as a value a PFM would hold: 0 for zero, NaN and inf (they say nothing about the byte order),
// 1 for a magnitude within 1e±20, -1 beyond (denormals included): what the bytes of a float read in the wrong
// order mostly give.
int Plausible(std::uint32_t bits) {
  const std::uint32_t exponent = (bits >> 23) & 0xffu;
  if (exponent == 0xffu || (bits & 0x7fffffffu) == 0) return 0;
  return exponent >= 127 - 66 && exponent <= 127 + 66 ? 1 : -1;
}

// Throws when the data is implausible in the declared byte order and plausible in the other: a header whose
// scale has the wrong sign (Middlebury's files are little-endian with scale -1).
void CheckByteOrder(const std::vector<std::uint32_t>& data, bool swapped, bool little, const std::string& path) {
  int64_t bad[2] = {0, 0}, told[2] = {0, 0};  // [0]: as declared, [1]: the other order
  for (const std::uint32_t raw : data) {
    const std::uint32_t other = __builtin_bswap32(raw);
    const std::uint32_t as_declared = swapped ? other : raw, as_other = swapped ? raw : other;
    for (int k = 0; k < 2; ++k) {
      const int p = Plausible(k == 0 ? as_declared : as_other);
      told[k] += p != 0 ? 1 : 0;
      bad[k] += p < 0 ? 1 : 0;
    }
  }
  RB_CHECK(!(told[0] > 0 && bad[0] * 4 > told[0] && told[1] >= 16 && bad[1] * 100 < told[1]), path, ": ", bad[0],
           " of ", told[0], " values read ", little ? "little" : "big",
           "-endian, as the scale's sign declares, are "
           "beyond 1e±20, and ",
           bad[1], " read ", little ? "big" : "little",
           "-endian: the header's scale probably "
           "has the wrong sign (negative means little-endian)");
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
  std::vector<std::uint32_t> data(row_floats * height);
  in.read(reinterpret_cast<char*>(data.data()), static_cast<std::streamsize>(need));
  RB_CHECK(in.good(), path, ": PFM data is truncated");
  const bool swap = little != (std::endian::native == std::endian::little);
  CheckByteOrder(data, swap, little, path);
  for (int r = 0; r < height; ++r) {
    std::uint32_t* row = data.data() + static_cast<size_t>(r) * row_floats;
    if (swap) {
      for (size_t i = 0; i < row_floats; ++i) row[i] = __builtin_bswap32(row[i]);
    }
    std::memcpy(image.ptr<float>(height - 1 - r), row, row_floats * 4);
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
