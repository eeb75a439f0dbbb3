#include "capture/frame_pairing.h"

#include <cstdlib>

#include "core/error.h"

namespace rangebayes {

void FramePairerOptions::Check() const {
  RB_CHECK(tolerance_ns > 0, "pairing tolerance must be > 0 ns, got ", tolerance_ns);
  RB_CHECK(max_pending >= 1, "max_pending must be >= 1, got ", max_pending);
}

FramePairer::FramePairer(const FramePairerOptions& options) : options_(options) { options_.Check(); }

void FramePairer::Trim(std::deque<TimedImage>* queue, std::int64_t* counter) {
  while (static_cast<int>(queue->size()) > options_.max_pending) {
    queue->pop_front();
    ++*counter;
  }
}

void FramePairer::AddLeft(TimedImage image) {
  left_.push_back(std::move(image));
  Trim(&left_, &unpaired_left_);
}

void FramePairer::AddRight(TimedImage image) {
  right_.push_back(std::move(image));
  Trim(&right_, &unpaired_right_);
}

std::optional<std::pair<TimedImage, TimedImage>> FramePairer::Pop() {
  const std::int64_t tol = options_.tolerance_ns;
  while (!left_.empty() && !right_.empty()) {
    const std::int64_t tl = left_.front().timestamp_ns;
    const std::int64_t tr = right_.front().timestamp_ns;
    if (std::llabs(tl - tr) <= tol) {
      // The next image on the earlier side may be nearer still to the other front: then this one is a stray.
      if (tl <= tr && left_.size() > 1 && std::llabs(left_[1].timestamp_ns - tr) < std::llabs(tl - tr)) {
        left_.pop_front();
        ++unpaired_left_;
        continue;
      }
      if (tr < tl && right_.size() > 1 && std::llabs(right_[1].timestamp_ns - tl) < std::llabs(tl - tr)) {
        right_.pop_front();
        ++unpaired_right_;
        continue;
      }
      std::pair<TimedImage, TimedImage> pair(std::move(left_.front()), std::move(right_.front()));
      left_.pop_front();
      right_.pop_front();
      return pair;
    }
    // The older image is too old for the other side's oldest, and later ones are later still.
    if (tl < tr) {
      left_.pop_front();
      ++unpaired_left_;
    } else {
      right_.pop_front();
      ++unpaired_right_;
    }
  }
  return std::nullopt;
}

StereoFrame StereoFrameOf(std::pair<TimedImage, TimedImage>&& pair, std::int64_t index) {
  StereoFrame f;
  f.left = std::move(pair.first.image);
  f.right = std::move(pair.second.image);
  f.timestamp_left_ns = pair.first.timestamp_ns;
  f.timestamp_right_ns = pair.second.timestamp_ns;
  f.sequence_left = pair.first.sequence;
  f.sequence_right = pair.second.sequence;
  f.index = index;
  return f;
}

}  // namespace rangebayes
