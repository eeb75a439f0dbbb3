#include "capture/v4l2_source.h"

#include <cerrno>
#include <chrono>
#include <cstring>

#include "core/error.h"

namespace rangebayes {

void V4l2StereoOptions::Check() const {
  camera.Check();
  pairing.Check();
  RB_CHECK(timeout_ms >= 1 && timeout_ms <= 60000, "camera timeout must be 1..60000 ms, got ", timeout_ms);
  RB_CHECK(!left_device.empty(), "no left device given");
  RB_CHECK(side_by_side || !right_device.empty(), "no right device given");
  RB_CHECK(side_by_side || left_device != right_device, "left and right are the same device ", left_device,
           " (use side-by-side mode for a single stereo device)");
}

V4l2StereoSource::V4l2StereoSource(std::shared_ptr<V4l2SysCalls> sys, const V4l2StereoOptions& options)
    : sys_(std::move(sys)), options_(options), pairer_(options.pairing) {
  options_.Check();
  left_ = std::make_unique<V4l2Camera>(sys_, options_.left_device, options_.camera);
  if (options_.side_by_side) {
    RB_CHECK(left_->format().width % 2 == 0, options_.left_device, ": side-by-side image width ",
             left_->format().width, " is odd");
  } else {
    right_ = std::make_unique<V4l2Camera>(sys_, options_.right_device, options_.camera);
    RB_CHECK(left_->format().width == right_->format().width && left_->format().height == right_->format().height,
             "left camera gives ", left_->format().Describe(), " but right camera gives ", right_->format().Describe());
  }
  left_->Start();
  if (right_) right_->Start();
}

std::string V4l2StereoSource::Describe() const {
  if (options_.side_by_side) return StrCat("V4L2 side-by-side ", options_.left_device, " [", left_->format().Describe(), "]");
  return StrCat("V4L2 ", options_.left_device, " [", left_->format().Describe(), "] + ", options_.right_device, " [",
                right_->format().Describe(), "]");
}

RecordingMeta V4l2StereoSource::Meta() const {
  RecordingMeta meta;
  meta["source"] = Describe();
  meta["left_device"] = options_.left_device;
  meta["left_format"] = left_->format().Describe();
  if (right_) {
    meta["right_device"] = options_.right_device;
    meta["right_format"] = right_->format().Describe();
  } else {
    meta["layout"] = "side by side in one image, split at half width";
  }
  meta["pairing_tolerance_ns"] = std::to_string(options_.pairing.tolerance_ns);
  return meta;
}

FrameSourceStats V4l2StereoSource::stats() const {
  FrameSourceStats s = stats_;
  s.dropped_left = left_->dropped();
  s.dropped_right = right_ ? right_->dropped() : left_->dropped();
  s.unpaired_left = pairer_.unpaired_left();
  s.unpaired_right = pairer_.unpaired_right();
  s.frames_skipped = left_->decode_errors() + (right_ ? right_->decode_errors() : 0);
  return s;
}

FrameResult V4l2StereoSource::Next() {
  using Clock = std::chrono::steady_clock;
  const auto deadline = Clock::now() + std::chrono::milliseconds(options_.timeout_ms);
  FrameResult result;
  while (true) {
    if (auto pair = pairer_.Pop()) {
      result.frame = StereoFrameOf(std::move(*pair), next_index_++);
      result.status = FrameStatus::kFrame;
      ++stats_.frames_delivered;
      return result;
    }
    const auto left_ms = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left_ms <= 0) break;
    pollfd fds[2] = {{left_->fd(), POLLIN, 0}, {right_ ? right_->fd() : -1, POLLIN, 0}};
    const nfds_t count = right_ ? 2 : 1;
    const int ready = sys_->Poll(fds, count, static_cast<int>(left_ms));
    if (ready < 0) {
      // Ctrl-C interrupts poll: report a timeout so that the caller looks at its stop flag.
      if (errno == EINTR) break;
      RB_FAIL("poll on ", options_.left_device, right_ ? " and " + options_.right_device : "", " failed (",
              std::strerror(errno), ")");
    }
    if (ready == 0) break;
    for (nfds_t i = 0; i < count; ++i) {
      V4l2Camera& cam = i == 0 ? *left_ : *right_;
      if (fds[i].revents & (POLLERR | POLLHUP | POLLNVAL)) {
        // Drivers signal an unplugged device with POLLERR; DQBUF then says ENODEV, which Dequeue reports.
        cam.Dequeue();
        RB_FAIL(cam.path(), ": device error while streaming (unplugged?)");
      }
      if (!(fds[i].revents & POLLIN)) continue;
      std::optional<TimedImage> image = cam.Dequeue();
      if (!image) continue;
      if (options_.side_by_side) {
        const int half = image->image.cols / 2;
        TimedImage l = *image, r = *image;
        l.image = image->image.colRange(0, half).clone();
        r.image = image->image.colRange(half, 2 * half).clone();
        pairer_.AddLeft(std::move(l));
        pairer_.AddRight(std::move(r));
      } else if (i == 0) {
        pairer_.AddLeft(std::move(*image));
      } else {
        pairer_.AddRight(std::move(*image));
      }
    }
  }
  result.status = FrameStatus::kTimeout;
  result.reason = StrCat("no stereo pair within ", options_.timeout_ms, " ms");
  ++stats_.timeouts;
  return result;
}

}  // namespace rangebayes
