#include "capture/v4l2_camera.h"

#include <fcntl.h>
#include <linux/videodev2.h>
#include <sys/mman.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "core/error.h"
#include "core/image_file.h"

namespace rangebayes {

std::uint32_t FourccGrey() { return V4L2_PIX_FMT_GREY; }
std::uint32_t FourccYuyv() { return V4L2_PIX_FMT_YUYV; }
std::uint32_t FourccMjpeg() { return V4L2_PIX_FMT_MJPEG; }

std::string FourccName(std::uint32_t fourcc) {
  std::string s(4, ' ');
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((fourcc >> (8 * i)) & 0xff);
    s[static_cast<size_t>(i)] = (c >= 32 && c < 127) ? c : '?';
  }
  return s;
}

std::string V4l2Format::Describe() const {
  char rate[32] = "rate unknown";
  if (fps > 0) std::snprintf(rate, sizeof(rate), "%.2f fps", fps);
  return StrCat(FourccName(fourcc), " ", width, "x", height, " ", rate, exact ? "" : " (closest offered)",
                card.empty() ? "" : ", " + card);
}

void V4l2CameraOptions::Check() const {
  RB_CHECK(width >= 1 && height >= 1, "camera size must be positive, got ", width, "x", height);
  RB_CHECK(fps > 0 && fps <= 1000, "camera frame rate must be in (0, 1000] fps, got ", fps);
  RB_CHECK(buffers >= 2 && buffers <= 32, "camera buffers must be 2..32, got ", buffers);
}

void V4l2Camera::Fail(const std::string& what, int error) const {
  if (error == ENODEV || error == ENXIO) {
    RB_FAIL(path_, ": device disappeared (unplugged?) during ", what, " (", std::strerror(error), ")");
  }
  RB_FAIL(path_, ": ", what, " failed (", std::strerror(error), ")");
}

V4l2Camera::V4l2Camera(std::shared_ptr<V4l2SysCalls> sys, const std::string& path, const V4l2CameraOptions& options)
    : sys_(std::move(sys)), path_(path), options_(options) {
  options_.Check();
  if (options_.formats.empty()) options_.formats = {FourccGrey(), FourccYuyv(), FourccMjpeg()};
  fd_ = sys_->Open(path_, O_RDWR | O_NONBLOCK);
  if (fd_ < 0) {
    const int e = errno;
    RB_CHECK(e != ENOENT, path_, ": no such device");
    RB_CHECK(e != ENOTTY && e != EINVAL, path_, ": not a video capture device (", std::strerror(e), ")");
    Fail("open", e);
  }
  try {
    Negotiate();
  } catch (...) {
    sys_->Close(fd_);
    fd_ = -1;
    throw;
  }
}

V4l2Camera::~V4l2Camera() {
  try {
    Stop();
  } catch (...) {
    // A vanished device cannot be stopped; its buffers are released below anyway.
  }
  Unmap();
  if (fd_ >= 0) sys_->Close(fd_);
}

void V4l2Camera::Negotiate() {
  v4l2_capability cap{};
  if (XIoctl(*sys_, fd_, VIDIOC_QUERYCAP, &cap) < 0) Fail("VIDIOC_QUERYCAP (is it a V4L2 device?)", errno);
  const std::uint32_t caps = (cap.capabilities & V4L2_CAP_DEVICE_CAPS) ? cap.device_caps : cap.capabilities;
  RB_CHECK(caps & V4L2_CAP_VIDEO_CAPTURE, path_, ": not a video capture device");
  RB_CHECK(caps & V4L2_CAP_STREAMING, path_, ": does not support streaming i/o");
  format_.card = reinterpret_cast<const char*>(cap.card);

  std::vector<std::uint32_t> offered;
  for (std::uint32_t i = 0;; ++i) {
    v4l2_fmtdesc desc{};
    desc.index = i;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (XIoctl(*sys_, fd_, VIDIOC_ENUM_FMT, &desc) < 0) break;
    offered.push_back(desc.pixelformat);
  }
  std::uint32_t chosen = 0;
  for (const std::uint32_t want : options_.formats) {
    for (const std::uint32_t have : offered) {
      if (want == have && chosen == 0) chosen = want;
    }
  }
  if (chosen == 0) {
    std::string list;
    for (const std::uint32_t have : offered) list += (list.empty() ? "" : ", ") + FourccName(have);
    RB_FAIL(path_, ": offers none of GREY, YUYV, MJPEG (offers: ", list.empty() ? "nothing" : list, ")");
  }

  // Closest discrete size by area difference; stepwise/continuous sizes take the request as it is.
  int width = options_.width, height = options_.height;
  long best = -1;
  for (std::uint32_t i = 0;; ++i) {
    v4l2_frmsizeenum size{};
    size.index = i;
    size.pixel_format = chosen;
    if (XIoctl(*sys_, fd_, VIDIOC_ENUM_FRAMESIZES, &size) < 0) break;
    if (size.type != V4L2_FRMSIZE_TYPE_DISCRETE) break;
    const long d = std::labs(static_cast<long>(size.discrete.width) - options_.width) +
                   std::labs(static_cast<long>(size.discrete.height) - options_.height);
    if (best < 0 || d < best) {
      best = d;
      width = static_cast<int>(size.discrete.width);
      height = static_cast<int>(size.discrete.height);
    }
  }

  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.width = static_cast<std::uint32_t>(width);
  fmt.fmt.pix.height = static_cast<std::uint32_t>(height);
  fmt.fmt.pix.pixelformat = chosen;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  if (XIoctl(*sys_, fd_, VIDIOC_S_FMT, &fmt) < 0) Fail("VIDIOC_S_FMT", errno);
  format_.fourcc = fmt.fmt.pix.pixelformat;
  format_.width = static_cast<int>(fmt.fmt.pix.width);
  format_.height = static_cast<int>(fmt.fmt.pix.height);
  bytes_per_line_ = fmt.fmt.pix.bytesperline;
  RB_CHECK(format_.fourcc == FourccGrey() || format_.fourcc == FourccYuyv() || format_.fourcc == FourccMjpeg(), path_,
           ": driver switched to format ", FourccName(format_.fourcc), ", which we cannot decode");
  RB_CHECK(format_.width > 0 && format_.height > 0, path_, ": driver reported an empty image size");

  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  parm.parm.capture.timeperframe.numerator = 1000;
  parm.parm.capture.timeperframe.denominator = static_cast<std::uint32_t>(std::lround(options_.fps * 1000.0));
  if (XIoctl(*sys_, fd_, VIDIOC_S_PARM, &parm) == 0 && parm.parm.capture.timeperframe.numerator > 0) {
    format_.fps = static_cast<double>(parm.parm.capture.timeperframe.denominator) /
                  parm.parm.capture.timeperframe.numerator;
  }
  format_.exact = format_.width == options_.width && format_.height == options_.height &&
                  (format_.fps == 0.0 || std::fabs(format_.fps - options_.fps) < 0.01 * options_.fps);
}

void V4l2Camera::MapBuffers() {
  v4l2_requestbuffers req{};
  req.count = static_cast<std::uint32_t>(options_.buffers);
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (XIoctl(*sys_, fd_, VIDIOC_REQBUFS, &req) < 0) Fail("VIDIOC_REQBUFS (mmap streaming)", errno);
  RB_CHECK(req.count >= 2, path_, ": driver gave only ", req.count, " buffer(s)");
  buffers_.resize(req.count);
  for (std::uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = i;
    if (XIoctl(*sys_, fd_, VIDIOC_QUERYBUF, &buf) < 0) Fail("VIDIOC_QUERYBUF", errno);
    void* start = sys_->Mmap(nullptr, buf.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_, buf.m.offset);
    if (start == MAP_FAILED) Fail("mmap", errno);
    buffers_[i] = {start, buf.length};
  }
}

void V4l2Camera::Unmap() {
  for (Buffer& b : buffers_) {
    if (b.start != nullptr) sys_->Munmap(b.start, b.length);
  }
  buffers_.clear();
}

void V4l2Camera::Start() {
  if (streaming_) return;
  if (buffers_.empty()) MapBuffers();
  for (std::uint32_t i = 0; i < buffers_.size(); ++i) {
    v4l2_buffer buf{};
    buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    buf.memory = V4L2_MEMORY_MMAP;
    buf.index = i;
    if (XIoctl(*sys_, fd_, VIDIOC_QBUF, &buf) < 0) Fail("VIDIOC_QBUF", errno);
  }
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (XIoctl(*sys_, fd_, VIDIOC_STREAMON, &type) < 0) Fail("VIDIOC_STREAMON", errno);
  streaming_ = true;
}

void V4l2Camera::Stop() {
  if (!streaming_) return;
  streaming_ = false;
  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (XIoctl(*sys_, fd_, VIDIOC_STREAMOFF, &type) < 0) Fail("VIDIOC_STREAMOFF", errno);
}

std::optional<TimedImage> V4l2Camera::Dequeue() {
  RB_CHECK(streaming_, path_, ": Dequeue before Start");
  v4l2_buffer buf{};
  buf.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  buf.memory = V4L2_MEMORY_MMAP;
  if (XIoctl(*sys_, fd_, VIDIOC_DQBUF, &buf) < 0) {
    if (errno == EAGAIN) return std::nullopt;
    Fail("VIDIOC_DQBUF", errno);
  }
  RB_CHECK(buf.index < buffers_.size(), path_, ": driver returned buffer ", buf.index, " of ", buffers_.size());
  const auto* data = static_cast<const std::uint8_t*>(buffers_[buf.index].start);
  const size_t used = std::min<size_t>(buf.bytesused, buffers_[buf.index].length);
  TimedImage out;
  out.timestamp_ns = static_cast<std::int64_t>(buf.timestamp.tv_sec) * 1'000'000'000LL +
                     static_cast<std::int64_t>(buf.timestamp.tv_usec) * 1000LL;
  out.sequence = buf.sequence;
  gaps_.Add(out.sequence);
  const int w = format_.width, h = format_.height;
  const int colour_code = options_.colour ? cv::COLOR_YUV2BGR_YUYV : cv::COLOR_YUV2GRAY_YUYV;
  try {
    if (format_.fourcc == FourccGrey()) {
      const size_t stride = bytes_per_line_ >= static_cast<std::uint32_t>(w) ? bytes_per_line_ : static_cast<size_t>(w);
      if (used >= stride * static_cast<size_t>(h)) {
        cv::Mat grey(h, w, CV_8UC1, const_cast<std::uint8_t*>(data), stride);
        out.image = options_.colour ? cv::Mat() : grey.clone();
        if (options_.colour) cv::cvtColor(grey, out.image, cv::COLOR_GRAY2BGR);
      }
    } else if (format_.fourcc == FourccYuyv()) {
      const size_t stride = bytes_per_line_ >= static_cast<std::uint32_t>(2 * w) ? bytes_per_line_ : 2 * static_cast<size_t>(w);
      if (used >= stride * static_cast<size_t>(h)) {
        const cv::Mat yuyv(h, w, CV_8UC2, const_cast<std::uint8_t*>(data), stride);
        cv::cvtColor(yuyv, out.image, colour_code);
      }
    } else {
      const cv::Mat encoded(1, static_cast<int>(used), CV_8UC1, const_cast<std::uint8_t*>(data));
      // A frame cut short (lost USB packets) decodes with its missing part grey: not delivered.
      if (JpegProblem({data, used}).empty()) {
        out.image = cv::imdecode(encoded, options_.colour ? cv::IMREAD_COLOR : cv::IMREAD_GRAYSCALE);
      }
      if (!out.image.empty() && (out.image.cols != w || out.image.rows != h)) out.image.release();
    }
  } catch (const cv::Exception&) {
    out.image.release();
  }
  // Give the buffer back before anything else can fail, so the ring never runs dry.
  if (XIoctl(*sys_, fd_, VIDIOC_QBUF, &buf) < 0) Fail("VIDIOC_QBUF", errno);
  if (out.image.empty()) {
    ++decode_errors_;
    return std::nullopt;
  }
  return out;
}

}  // namespace rangebayes
