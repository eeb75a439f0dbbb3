// libFuzzer entry for recordings: the input is frames.csv, meta.yaml, the left and the right image of
// frame 0 (left/000000.png, right/000000.png), separated by "\n--8<--\n" lines. The recording is opened and
// its first frames loaded; any input must open or throw rangebayes::Error, and a loaded frame must be a
// consistent 8- or 16-bit pair.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <opencv2/imgcodecs.hpp>
#include <string_view>

#include "capture/recording.h"
#include "core/error.h"
#include "fuzz/fuzz_util.h"

// OpenCV registers its image decoders (GDAL's among them) on the first decode, which takes seconds: done
// here once so that it does not count against the first input's time limit.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  static const unsigned char kPng[] = {
      0x89, 'P',  'N',  'G',  '\r', '\n', 0x1a, '\n', 0,    0,    0,    13,  'I',  'H',  'D',  'R',  0,
      0,    0,    1,    0,    0,    0,    1,    8,    0,    0,    0,    0,   0x3a, 0x7e, 0x9b, 0x55, 0,
      0,    0,    10,   'I',  'D',  'A',  'T',  0x78, 0x9c, 0x63, 0x60, 0,   0,    0,    2,    0,    1,
      0x48, 0xaf, 0xa4, 0x71, 0,    0,    0,    0,    'I',  'E',  'N',  'D', 0xae, 0x42, 0x60, 0x82};
  cv::imdecode(cv::Mat(1, sizeof(kPng), CV_8U, const_cast<unsigned char*>(kPng)), cv::IMREAD_UNCHANGED);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rangebayes;
  const auto parts = fuzz::SplitParts(std::string_view(reinterpret_cast<const char*>(data), size), 4);
  fuzz::ClearScratch();
  const std::string folder = fuzz::ScratchDir() + "/rec";
  fuzz::WriteScratch("rec/frames.csv", parts[0]);
  fuzz::WriteScratch("rec/meta.yaml", parts[1]);
  if (!parts[2].empty()) fuzz::WriteScratch("rec/left/000000.png", parts[2]);
  if (!parts[3].empty()) fuzz::WriteScratch("rec/right/000000.png", parts[3]);
  Recording recording;
  RecordingReadSummary summary;
  try {
    recording = OpenRecording(folder, &summary);
  } catch (const Error&) {
    return 0;
  }
  fuzz::Require(recording.files_present.size() == recording.frames.size(), "files_present per frame");
  for (int i = 0; i < std::min(recording.num_frames(), 3); ++i) {
    try {
      const StereoFrame frame = LoadRecordingFrame(recording, i);
      fuzz::Require(
          !frame.left.empty() && frame.left.size() == frame.right.size() && frame.left.type() == frame.right.type(),
          "a loaded frame is a consistent pair");
      fuzz::Require(frame.left.depth() == CV_8U || frame.left.depth() == CV_16U, "8- or 16-bit frame");
    } catch (const Error&) {
    }
  }
  return 0;
}
