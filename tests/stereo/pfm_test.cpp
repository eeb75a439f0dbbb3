// PFM reading and writing: round trip, Middlebury's bottom-to-top rows and byte order, bad files.
#include "stereo/pfm.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <tuple>
#include <vector>

#include "core/error.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

TEST(Pfm, RoundTripKeepsValuesNaNAndInf) {
  cv::Mat image(3, 5, CV_32F);
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 5; ++x) image.at<float>(y, x) = static_cast<float>(y * 10 + x) + 0.25f;
  image.at<float>(1, 2) = std::numeric_limits<float>::quiet_NaN();
  image.at<float>(2, 4) = std::numeric_limits<float>::infinity();
  const std::string path = TempPath("round_trip.pfm");
  WritePfm(image, path);
  const cv::Mat back = ReadPfm(path);
  ASSERT_EQ(back.size(), image.size());
  ASSERT_EQ(back.type(), CV_32F);
  for (int y = 0; y < 3; ++y) {
    for (int x = 0; x < 5; ++x) {
      const float a = image.at<float>(y, x), b = back.at<float>(y, x);
      if (std::isnan(a)) {
        EXPECT_TRUE(std::isnan(b));
      } else {
        EXPECT_EQ(a, b);
      }
    }
  }
}

// A file written by hand the way Middlebury stores it: "Pf", size, negative scale (little endian), and the
// bottom image row first.
TEST(Pfm, ReadsRowsBottomToTopAndBigEndian) {
  for (const bool big : {false, true}) {
    const std::string path = TempPath(big ? "be.pfm" : "le.pfm");
    {
      std::ofstream out(path, std::ios::binary);
      out << "Pf\n2 2\n" << (big ? "1.0" : "-1.0") << "\n";
      // Stored order: bottom row (3, 4), then top row (1, 2).
      for (float v : {3.0f, 4.0f, 1.0f, 2.0f}) {
        std::uint32_t bits;
        std::memcpy(&bits, &v, 4);
        if (big) bits = __builtin_bswap32(bits);
        out.write(reinterpret_cast<const char*>(&bits), 4);
      }
    }
    const cv::Mat m = ReadPfm(path);
    EXPECT_EQ(m.at<float>(0, 0), 1.0f);
    EXPECT_EQ(m.at<float>(0, 1), 2.0f);
    EXPECT_EQ(m.at<float>(1, 0), 3.0f);
    EXPECT_EQ(m.at<float>(1, 1), 4.0f);
  }
}

// A disparity map written little-endian under a header that says big-endian (scale 1) was read as values up to
// 1e36: refused, naming the likely cause. The same bytes under the right header, and the map written big-endian
// under scale 1, read as written.
TEST(Pfm, DataInTheOtherByteOrderThanDeclaredIsNamed) {
  std::vector<float> values;
  for (int i = 0; i < 64; ++i)
    values.push_back(i % 9 == 0 ? std::numeric_limits<float>::infinity() : 20.0f + 0.37f * i);
  auto write = [&](const std::string& name, const char* scale, bool big_endian_data) {
    const std::string path = TempPath(name);
    std::ofstream out(path, std::ios::binary);
    out << "Pf\n8 8\n" << scale << "\n";
    for (const float v : values) {
      std::uint32_t bits;
      std::memcpy(&bits, &v, 4);
      if (big_endian_data) bits = __builtin_bswap32(bits);
      out.write(reinterpret_cast<const char*>(&bits), 4);
    }
    return path;
  };
  const std::string wrong = write("wrong_sign.pfm", "1.0", false);
  try {
    ReadPfm(wrong);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    const std::string why = e.what();
    EXPECT_NE(why.find("wrong_sign.pfm: "), std::string::npos) << why;
    EXPECT_NE(why.find("read big-endian, as the scale's sign declares, are beyond 1e±20, and 0 read little-endian: "
                       "the header's scale probably has the wrong sign"),
              std::string::npos)
        << why;
  }
  for (const auto& [name, scale, big] : {std::tuple{"le.pfm", "-1.0", false}, std::tuple{"be.pfm", "1.0", true}}) {
    const cv::Mat m = ReadPfm(write(name, scale, big));
    EXPECT_EQ(m.at<float>(7, 1), values[1]) << name;  // stored bottom row first
    EXPECT_TRUE(std::isinf(m.at<float>(7, 0))) << name;
  }
}

TEST(Pfm, BadFilesThrowNamingTheFile) {
  EXPECT_THROW(ReadPfm(TempPath("does_not_exist.pfm")), Error);
  const std::string truncated = TempPath("truncated.pfm");
  {
    std::ofstream out(truncated, std::ios::binary);
    out << "Pf\n4 4\n-1.0\n";
    out.write("abcd", 4);
  }
  try {
    ReadPfm(truncated);
    FAIL() << "truncated PFM was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("truncated.pfm"), std::string::npos) << e.what();
  }
  const std::string not_pfm = TempPath("not.pfm");
  {
    std::ofstream out(not_pfm);
    out << "P5\n1 1\n255\n";
  }
  EXPECT_THROW(ReadPfm(not_pfm), Error);
  EXPECT_THROW(WritePfm(cv::Mat(2, 2, CV_8U, cv::Scalar(0)), TempPath("u8.pfm")), Error);
}

}  // namespace
}  // namespace rangebayes
