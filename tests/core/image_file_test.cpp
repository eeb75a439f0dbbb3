// Image files checked before a decoder sees them: whole files pass, files cut short are named.
#include "core/image_file.h"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "core/error.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

std::vector<unsigned char> Bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string Write(const std::string& name, const std::vector<unsigned char>& bytes) {
  const std::string path = TempPath(name);
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  return path;
}

// The bundled OpenCV sample (JPEG) and Middlebury image (PNG), whole and cut at three places.
TEST(ImageFile, WholeFilesPassAndFilesCutShortAreNamed) {
  for (const std::string path :
       {"tests/data/calibration/opencv_stereo/left01.jpg", "tests/data/stereo/tsukuba/imL.png"}) {
    SCOPED_TRACE(path);
    const std::vector<unsigned char> whole = Bytes(path);
    ASSERT_GT(whole.size(), 1000u);
    EXPECT_EQ(ImageFileProblem(whole), "");
    EXPECT_NO_THROW(CheckImageFile(path, "image"));
    const bool png = path.ends_with(".png");
    for (const double share : {0.1, 0.5, 0.99}) {
      std::vector<unsigned char> cut(whole.begin(), whole.begin() + static_cast<std::ptrdiff_t>(share * whole.size()));
      EXPECT_EQ(ImageFileProblem(cut), png ? "PNG data is cut short: no IEND chunk"
                                           : "JPEG data is cut short: no end-of-image marker after its last scan")
          << share;
      // A camera's buffer: the frame cut, the rest of the buffer zeros.
      cut.resize(whole.size(), 0);
      EXPECT_NE(ImageFileProblem(cut), "") << share;
    }
    // Bytes some tools append after the end are let be.
    std::vector<unsigned char> padded = whole;
    padded.insert(padded.end(), 64, 0);
    EXPECT_EQ(ImageFileProblem(padded), "");
    const std::string cut_path =
        Write(png ? "cut.png" : "cut.jpg", std::vector<unsigned char>(whole.begin(), whole.begin() + 600));
    try {
      CheckImageFile(cut_path, "image");
      ADD_FAILURE() << "no error";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(cut_path + ": " + (png ? "PNG" : "JPEG") + " data is cut short"),
                std::string::npos)
          << e.what();
    }
  }
}

TEST(ImageFile, OtherFormatsAreLeftToTheDecoderAndBadHeadersAreNamed) {
  const std::vector<unsigned char> pgm = {'P', '5', '\n', '1', ' ', '1', '\n', '2', '5', '5', '\n', 7};
  EXPECT_EQ(ImageFileProblem(pgm), "");
  EXPECT_EQ(ImageFileProblem({}), "");
  EXPECT_EQ(JpegProblem(pgm), "not a JPEG image");
  EXPECT_EQ(PngProblem(pgm), "not a PNG image");
  const std::vector<unsigned char> jpeg_without_scan = {0xff, 0xd8, 0xff, 0xe0, 0x00, 0x02, 0xff, 0xd9};
  EXPECT_EQ(ImageFileProblem(jpeg_without_scan), "JPEG data is cut short: no start-of-scan marker");
  // A PNG header that declares 2^20 x 2^20 pixels in 40 bytes: refused before a decoder allocates for it.
  std::vector<unsigned char> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 0, 0, 0, 13, 'I', 'H', 'D',
                                    'R',  0,   16,  0,   0,    0,    16,   0,    0, 8, 0, 0,  0,   0};
  png.resize(40, 0);
  EXPECT_NE(ImageFileProblem(png).find("PNG declares 1048576x1048576 pixels, more than its 40 bytes can hold"),
            std::string::npos)
      << ImageFileProblem(png);
}

}  // namespace
}  // namespace rangebayes
