// Stereo from two libcamera cameras (Raspberry Pi and other CSI cameras): two streams configured to the
// same size, a request loop per camera, and the same nearest-timestamp pairing as the V4L2 source.
#pragma once

#include <memory>
#include <string>

#include "capture/frame_pairing.h"
#include "capture/frame_source.h"

namespace rangebayes {

struct LibcameraStereoOptions {
  std::string left_camera;    // camera id (see `rangebayes cameras`); empty: the first camera
  std::string right_camera;   // empty: the second camera
  int width = 640;            // requested size (px); the camera's validated size is used and reported
  int height = 480;
  int buffers = 4;            // 2–16 requests in flight per camera
  FramePairerOptions pairing;
  int timeout_ms = 2000;      // 1–60000
  void Check() const;
};

// Throws Error when the camera manager cannot start, fewer than two cameras exist, or a camera cannot be
// configured to a grey-decodable format (R8, YUV420 or NV12: the Y plane is used).
class LibcameraStereoSource : public FrameSource {
 public:
  explicit LibcameraStereoSource(const LibcameraStereoOptions& options);
  ~LibcameraStereoSource() override;

  FrameResult Next() override;
  std::string Describe() const override;
  FrameSourceStats stats() const override;
  RecordingMeta Meta() const override;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace rangebayes
