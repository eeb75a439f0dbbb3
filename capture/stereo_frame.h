// One stereo pair as it leaves a camera or a recording.
#pragma once

#include <cstdint>
#include <opencv2/core.hpp>

namespace rangebayes {

// left/right: unrectified images, 8-bit or 16-bit, 1 channel (grey) or 3 channels (BGR, OpenCV order), both
// the same size. A frame handed to another stage is never written again (clone before modifying).
struct StereoFrame {
  cv::Mat left;
  cv::Mat right;
  std::int64_t timestamp_left_ns = 0;   // capture time of each image (device clock, or recording time)
  std::int64_t timestamp_right_ns = 0;
  std::int64_t sequence_left = -1;      // driver sequence numbers; -1 when the source has none
  std::int64_t sequence_right = -1;
  int pattern_id = -1;                  // projected light pattern shown during capture; -1: none / unknown
  std::int64_t index = 0;               // frame index within the session or recording, from 0

  bool empty() const { return left.empty() || right.empty(); }
  // The later of the two timestamps, which is when the pair was complete.
  std::int64_t timestamp_ns() const {
    return timestamp_left_ns > timestamp_right_ns ? timestamp_left_ns : timestamp_right_ns;
  }
};

}  // namespace rangebayes
