#include "core/image_file.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <vector>

#include "core/error.h"
#include "core/files.h"

namespace rangebayes {
namespace {

constexpr unsigned char kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};

bool IsPng(std::span<const unsigned char> bytes) {
  return bytes.size() >= 8 && std::memcmp(bytes.data(), kPngSignature, 8) == 0;
}

bool IsJpeg(std::span<const unsigned char> bytes) {
  return bytes.size() >= 3 && bytes[0] == 0xff && bytes[1] == 0xd8 && bytes[2] == 0xff;
}

// The position of the last 0xFF `marker` pair in bytes, or -1.
std::int64_t LastMarker(std::span<const unsigned char> bytes, unsigned char marker) {
  for (std::int64_t i = static_cast<std::int64_t>(bytes.size()) - 2; i >= 0; --i) {
    if (bytes[static_cast<size_t>(i)] == 0xff && bytes[static_cast<size_t>(i) + 1] == marker) return i;
  }
  return -1;
}

}  // namespace

std::string PngProblem(std::span<const unsigned char> bytes) {
  if (bytes.size() < 33 || !IsPng(bytes) || std::memcmp(&bytes[12], "IHDR", 4) != 0) return "not a PNG image";
  auto u32 = [&](size_t at) {
    return (std::uint64_t{bytes[at]} << 24) | (std::uint64_t{bytes[at + 1]} << 16) |
           (std::uint64_t{bytes[at + 2]} << 8) | std::uint64_t{bytes[at + 3]};
  };
  const std::uint64_t width = u32(16), height = u32(20);
  const int bit_depth = bytes[24], color_type = bytes[25];
  const int channels = color_type == 0   ? 1
                       : color_type == 2 ? 3
                       : color_type == 3 ? 1
                       : color_type == 4 ? 2
                       : color_type == 6 ? 4
                                         : 0;
  if (channels == 0 || width == 0 || height == 0 || width > (1u << 20) || height > (1u << 20) ||
      (bit_depth != 1 && bit_depth != 2 && bit_depth != 4 && bit_depth != 8 && bit_depth != 16)) {
    return "PNG header is invalid";
  }
  const std::uint64_t raw = height * (1 + (width * channels * bit_depth + 7) / 8);
  if (raw > 1032 * static_cast<std::uint64_t>(bytes.size()) + 1024) {
    return StrCat("PNG declares ", width, "x", height, " pixels, more than its ", bytes.size(), " bytes can hold");
  }
  // The IEND chunk (length 0, type, CRC) ends the file; a few bytes that some tools append after it are let be.
  const size_t tail = std::min<size_t>(bytes.size() - 33, 1024);
  const auto* end = bytes.data() + bytes.size();
  if (std::search(end - tail, end, "IEND", "IEND" + 4) == end) return "PNG data is cut short: no IEND chunk";
  return {};
}

std::string JpegProblem(std::span<const unsigned char> bytes) {
  if (!IsJpeg(bytes)) return "not a JPEG image";
  const std::int64_t scan = LastMarker(bytes, 0xda), end = LastMarker(bytes, 0xd9);
  if (scan < 0) return "JPEG data is cut short: no start-of-scan marker";
  if (end < scan) return "JPEG data is cut short: no end-of-image marker after its last scan";
  return {};
}

std::string ImageFileProblem(std::span<const unsigned char> bytes) {
  if (IsPng(bytes)) return PngProblem(bytes);
  if (IsJpeg(bytes)) return JpegProblem(bytes);
  return {};
}

void CheckImageFile(const std::string& path, const std::string& what) {
  CheckFileToRead(path, what);
  std::ifstream in(path, std::ios::binary);
  RB_CHECK(in.good(), path, ": cannot open ", what);
  const std::vector<unsigned char> bytes{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  RB_CHECK(!in.bad(), path, ": cannot read ", what);
  const std::string problem = ImageFileProblem(bytes);
  RB_CHECK(problem.empty(), path, ": ", problem);
}

}  // namespace rangebayes
