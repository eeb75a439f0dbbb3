// PFM reading and writing: round trip, Middlebury's bottom-to-top rows and byte order, bad files.
#include "stereo/pfm.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>

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
