// Pairing of two independent image streams (left and right camera) by nearest timestamp.
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <opencv2/core.hpp>
#include <utility>

#include "capture/stereo_frame.h"

namespace rangebayes {

// One image from one camera. timestamp_ns: driver capture time (monotonic clock); sequence: driver frame
// counter (−1: unknown).
struct TimedImage {
  cv::Mat image;
  std::int64_t timestamp_ns = 0;
  std::int64_t sequence = -1;
};

struct FramePairerOptions {
  std::int64_t tolerance_ns = 10'000'000;  // > 0: largest |t_left − t_right| of a pair (default 10 ms)
  int max_pending = 8;                     // ≥ 1: images kept per side while waiting for a partner
  void Check() const;
};

// Images must arrive per side in increasing timestamp order. An image is paired with the image of the
// other side nearest in time when that is within the tolerance; an image that can no longer be paired
// (the other side has moved past it) is discarded and counted.
class FramePairer {
 public:
  explicit FramePairer(const FramePairerOptions& options = {});
  void AddLeft(TimedImage image);
  void AddRight(TimedImage image);
  // The next pair, or empty when none is ready yet.
  std::optional<std::pair<TimedImage, TimedImage>> Pop();

  std::int64_t unpaired_left() const { return unpaired_left_; }
  std::int64_t unpaired_right() const { return unpaired_right_; }

 private:
  void Trim(std::deque<TimedImage>* queue, std::int64_t* counter);
  FramePairerOptions options_;
  std::deque<TimedImage> left_, right_;
  std::int64_t unpaired_left_ = 0;
  std::int64_t unpaired_right_ = 0;
};

// The stereo frame of a pair that FramePairer::Pop returned, numbered `index` (the images are moved out).
StereoFrame StereoFrameOf(std::pair<TimedImage, TimedImage>&& pair, std::int64_t index);

// Counts frames lost by a driver from its sequence numbers.
class SequenceGapCounter {
 public:
  // Returns the frames missing before this one (0 for the first or when sequences are unknown).
  std::int64_t Add(std::int64_t sequence) {
    std::int64_t gap = 0;
    if (sequence >= 0 && last_ >= 0 && sequence > last_ + 1) gap = sequence - last_ - 1;
    if (sequence >= 0) last_ = sequence;
    dropped_ += gap;
    return gap;
  }
  std::int64_t dropped() const { return dropped_; }

 private:
  std::int64_t last_ = -1;
  std::int64_t dropped_ = 0;
};

}  // namespace rangebayes
