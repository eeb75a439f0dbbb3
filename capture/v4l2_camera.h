// One V4L2 capture device: format negotiation (GREY, YUYV or MJPEG; the size and rate asked for or the
// closest offered), memory-mapped streaming with a ring of buffers, and decoding to an 8-bit grey image.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "capture/frame_pairing.h"
#include "capture/v4l2_syscalls.h"

namespace rangebayes {

// Pixel formats we decode, as V4L2 fourcc codes.
std::uint32_t FourccGrey();
std::uint32_t FourccYuyv();
std::uint32_t FourccMjpeg();
std::string FourccName(std::uint32_t fourcc);

struct V4l2CameraOptions {
  int width = 640;         // requested size (px); the closest offered size is used
  int height = 480;
  double fps = 30.0;       // > 0: requested frame rate; the driver's nearest is used
  int buffers = 4;         // 2–32: mmap ring size
  bool colour = false;     // false: deliver 8-bit grey (what the matchers use); true: BGR
  // Formats in order of preference; the first the device offers wins. Empty: GREY, YUYV, MJPEG.
  std::vector<std::uint32_t> formats;
  void Check() const;
};

// What was negotiated, with a one-line description for logs and meta.yaml.
struct V4l2Format {
  std::uint32_t fourcc = 0;
  int width = 0;
  int height = 0;
  double fps = 0.0;        // 0 when the driver does not report a rate
  bool exact = false;      // size and rate are what was asked for
  std::string card;        // device name from VIDIOC_QUERYCAP
  std::string Describe() const;
};

// Owns the file descriptor and the mapped buffers. Every call throws Error naming the device on failure;
// a device that vanished (ENODEV, unplugged) says so.
class V4l2Camera {
 public:
  V4l2Camera(std::shared_ptr<V4l2SysCalls> sys, const std::string& path, const V4l2CameraOptions& options = {});
  ~V4l2Camera();
  V4l2Camera(const V4l2Camera&) = delete;
  V4l2Camera& operator=(const V4l2Camera&) = delete;

  void Start();
  void Stop();
  int fd() const { return fd_; }
  const std::string& path() const { return path_; }
  const V4l2Format& format() const { return format_; }

  // Takes one filled buffer if the driver has one (after poll said readable): decoded image, timestamp,
  // sequence. Empty when no buffer was ready (EAGAIN). A buffer that cannot be decoded (corrupt MJPEG)
  // throws nothing: it is counted in decode_errors() and empty is returned.
  std::optional<TimedImage> Dequeue();

  std::int64_t decode_errors() const { return decode_errors_; }
  std::int64_t dropped() const { return gaps_.dropped(); }

 private:
  void Negotiate();
  void MapBuffers();
  void Unmap();
  [[noreturn]] void Fail(const std::string& what, int error) const;

  std::shared_ptr<V4l2SysCalls> sys_;
  std::string path_;
  V4l2CameraOptions options_;
  V4l2Format format_;
  int fd_ = -1;
  std::uint32_t bytes_per_line_ = 0;
  struct Buffer {
    void* start = nullptr;
    size_t length = 0;
  };
  std::vector<Buffer> buffers_;
  bool streaming_ = false;
  std::int64_t decode_errors_ = 0;
  SequenceGapCounter gaps_;
};

}  // namespace rangebayes
