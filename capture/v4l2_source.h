// Stereo from V4L2 cameras: two devices paired by nearest timestamp, or one device that delivers both
// views side by side in one image (left half: left camera).
#pragma once

#include <memory>
#include <string>

#include "capture/frame_pairing.h"
#include "capture/frame_source.h"
#include "capture/v4l2_camera.h"

namespace rangebayes {

struct V4l2StereoOptions {
  std::string left_device = "/dev/video0";
  std::string right_device = "/dev/video2";  // ignored when side_by_side
  bool side_by_side = false;                 // one device (left_device), image split in two halves
  V4l2CameraOptions camera;                  // for side_by_side, the size of the whole (double-width) image
  FramePairerOptions pairing;
  int timeout_ms = 2000;                     // 1–60000: Next() returns kTimeout after this long without a pair
  void Check() const;
};

class V4l2StereoSource : public FrameSource {
 public:
  // Opens and negotiates the device(s) and starts streaming. Throws Error naming the device on failure.
  V4l2StereoSource(std::shared_ptr<V4l2SysCalls> sys, const V4l2StereoOptions& options);

  // Polls both devices until a pair is complete or the timeout passes; a device that disappears throws
  // Error (ENODEV named). Frames are numbered from 0 in delivery order; timestamps are the drivers'.
  FrameResult Next() override;
  std::string Describe() const override;
  FrameSourceStats stats() const override;
  RecordingMeta Meta() const override;

  const V4l2Format& left_format() const { return left_->format(); }
  const V4l2Format* right_format() const { return right_ ? &right_->format() : nullptr; }

 private:
  std::shared_ptr<V4l2SysCalls> sys_;
  V4l2StereoOptions options_;
  std::unique_ptr<V4l2Camera> left_;
  std::unique_ptr<V4l2Camera> right_;
  FramePairer pairer_;
  FrameSourceStats stats_;
  std::int64_t next_index_ = 0;
};

}  // namespace rangebayes
