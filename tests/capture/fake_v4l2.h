// A scripted V4L2 device behind the system-call seam: formats, sizes and rates it offers, and a script of
// what each dequeue returns (a frame, nothing yet, an unplug), so negotiation and streaming run without
// cameras or kernel modules.
#pragma once

#include <linux/videodev2.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstring>
#include <deque>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "capture/v4l2_syscalls.h"

namespace rangebayes {

struct FakeEvent {
  // kCorrupt: a buffer too short for the format (MJPEG: 100 bytes that are no JPEG); kTruncated (MJPEG): the first
  // half of the frame's JPEG, the rest of the buffer zeros, as a camera that lost USB packets delivers it.
  enum Kind { kFrame, kStall, kUnplug, kCorrupt, kTruncated } kind = kFrame;
  std::int64_t timestamp_ns = 0;
  std::uint32_t sequence = 0;
  std::uint8_t value = 0;  // kFrame: pixel value (the frame fills with value + x % 7)
};

struct FakeDeviceSpec {
  std::vector<std::uint32_t> formats = {V4L2_PIX_FMT_YUYV};
  std::vector<std::pair<int, int>> sizes = {{640, 480}, {320, 240}};
  double fps = 30.0;                 // what S_PARM answers
  bool capture_capable = true;
  std::deque<FakeEvent> script;      // consumed by DQBUF (kStall: poll says nothing is ready)
};

class FakeV4l2 : public V4l2SysCalls {
 public:
  std::map<std::string, FakeDeviceSpec> devices;
  int open_count = 0, close_count = 0, mapped_now = 0;

  int Open(const std::string& path, int) override {
    auto it = devices.find(path);
    if (it == devices.end()) {
      errno = ENOENT;
      return -1;
    }
    const int fd = next_fd_++;
    state_[fd].path = path;
    ++open_count;
    return fd;
  }
  int Close(int fd) override {
    state_.erase(fd);
    ++close_count;
    return 0;
  }
  void* Mmap(void*, size_t length, int, int, int fd, std::int64_t offset) override {
    State& s = state_.at(fd);
    auto& b = s.buffers.at(static_cast<size_t>(offset / kBufferSize));
    ++mapped_now;
    return length <= b.size() ? b.data() : MAP_FAILED;
  }
  int Munmap(void*, size_t) override {
    --mapped_now;
    return 0;
  }
  int Poll(struct pollfd* fds, nfds_t count, int) override {
    int ready = 0;
    for (nfds_t i = 0; i < count; ++i) {
      fds[i].revents = 0;
      if (fds[i].fd < 0) continue;
      FakeDeviceSpec& d = Spec(fds[i].fd);
      if (!d.script.empty() && d.script.front().kind == FakeEvent::kUnplug) {
        fds[i].revents = POLLERR;
        ++ready;
      } else if (!d.script.empty() && d.script.front().kind != FakeEvent::kStall) {
        fds[i].revents = POLLIN;
        ++ready;
      }
    }
    // A stall (or an empty script) times out at once: the test does not wait for real time.
    if (ready == 0) {
      for (nfds_t i = 0; i < count; ++i) {
        if (fds[i].fd < 0) continue;
        FakeDeviceSpec& d = Spec(fds[i].fd);
        if (!d.script.empty() && d.script.front().kind == FakeEvent::kStall) d.script.pop_front();
      }
    }
    return ready;
  }

  int Ioctl(int fd, unsigned long request, void* arg) override {
    State& s = state_.at(fd);
    FakeDeviceSpec& d = devices.at(s.path);
    switch (request) {
      case VIDIOC_QUERYCAP: {
        auto* cap = static_cast<v4l2_capability*>(arg);
        std::memset(cap, 0, sizeof(*cap));
        std::snprintf(reinterpret_cast<char*>(cap->card), sizeof(cap->card), "Fake camera %s", s.path.c_str());
        std::snprintf(reinterpret_cast<char*>(cap->driver), sizeof(cap->driver), "fake");
        cap->capabilities = V4L2_CAP_STREAMING | (d.capture_capable ? V4L2_CAP_VIDEO_CAPTURE : 0);
        return 0;
      }
      case VIDIOC_ENUM_FMT: {
        auto* desc = static_cast<v4l2_fmtdesc*>(arg);
        if (desc->index >= d.formats.size()) return Error(EINVAL);
        desc->pixelformat = d.formats[desc->index];
        return 0;
      }
      case VIDIOC_ENUM_FRAMESIZES: {
        auto* size = static_cast<v4l2_frmsizeenum*>(arg);
        if (size->index >= d.sizes.size()) return Error(EINVAL);
        size->type = V4L2_FRMSIZE_TYPE_DISCRETE;
        size->discrete.width = static_cast<std::uint32_t>(d.sizes[size->index].first);
        size->discrete.height = static_cast<std::uint32_t>(d.sizes[size->index].second);
        return 0;
      }
      case VIDIOC_S_FMT: {
        auto* fmt = static_cast<v4l2_format*>(arg);
        s.fourcc = fmt->fmt.pix.pixelformat;
        s.width = static_cast<int>(fmt->fmt.pix.width);
        s.height = static_cast<int>(fmt->fmt.pix.height);
        fmt->fmt.pix.bytesperline = static_cast<std::uint32_t>(s.fourcc == V4L2_PIX_FMT_YUYV ? 2 * s.width : s.width);
        return 0;
      }
      case VIDIOC_S_PARM: {
        auto* parm = static_cast<v4l2_streamparm*>(arg);
        parm->parm.capture.timeperframe.numerator = 1000;
        parm->parm.capture.timeperframe.denominator = static_cast<std::uint32_t>(d.fps * 1000);
        return 0;
      }
      case VIDIOC_REQBUFS: {
        auto* req = static_cast<v4l2_requestbuffers*>(arg);
        s.buffers.assign(req->count, std::vector<std::uint8_t>(kBufferSize));
        return 0;
      }
      case VIDIOC_QUERYBUF: {
        auto* buf = static_cast<v4l2_buffer*>(arg);
        buf->length = kBufferSize;
        buf->m.offset = buf->index * kBufferSize;
        return 0;
      }
      case VIDIOC_QBUF:
        ++s.queued;
        return 0;
      case VIDIOC_STREAMON:
        s.streaming = true;
        return 0;
      case VIDIOC_STREAMOFF:
        s.streaming = false;
        return 0;
      case VIDIOC_DQBUF: {
        if (!s.streaming) return Error(EINVAL);
        if (d.script.empty() || d.script.front().kind == FakeEvent::kStall) return Error(EAGAIN);
        const FakeEvent e = d.script.front();
        d.script.pop_front();
        if (e.kind == FakeEvent::kUnplug) {
          d.script.push_front(e);  // stays gone
          return Error(ENODEV);
        }
        auto* buf = static_cast<v4l2_buffer*>(arg);
        buf->index = static_cast<std::uint32_t>(s.next_buffer++ % s.buffers.size());
        buf->sequence = e.sequence;
        buf->timestamp.tv_sec = e.timestamp_ns / 1'000'000'000LL;
        buf->timestamp.tv_usec = (e.timestamp_ns % 1'000'000'000LL) / 1000;
        buf->bytesused = Fill(s, e, s.buffers[buf->index]);
        --s.queued;
        return 0;
      }
      default:
        return Error(ENOTTY);
    }
  }

  // The grey image a kFrame event decodes to.
  static cv::Mat Expected(int width, int height, std::uint8_t value) {
    cv::Mat m(height, width, CV_8UC1);
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) m.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>(value + x % 7);
    }
    return m;
  }

  int streaming_devices() const {
    int n = 0;
    for (const auto& [fd, s] : state_) n += s.streaming ? 1 : 0;
    return n;
  }

 private:
  static constexpr std::uint32_t kBufferSize = 640 * 480 * 2;
  struct State {
    std::string path;
    std::uint32_t fourcc = 0;
    int width = 0, height = 0;
    std::vector<std::vector<std::uint8_t>> buffers;
    int queued = 0;
    std::uint32_t next_buffer = 0;
    bool streaming = false;
  };

  static int Error(int e) {
    errno = e;
    return -1;
  }
  FakeDeviceSpec& Spec(int fd) { return devices.at(state_.at(fd).path); }

  static std::uint32_t Fill(const State& s, const FakeEvent& e, std::vector<std::uint8_t>& out) {
    const cv::Mat grey = Expected(s.width, s.height, e.value);
    if (e.kind == FakeEvent::kCorrupt && s.fourcc == V4L2_PIX_FMT_MJPEG) {
      std::memset(out.data(), 0x5a, 100);
      return 100;
    }
    if (s.fourcc == V4L2_PIX_FMT_GREY) {
      std::memcpy(out.data(), grey.data, grey.total());
      return static_cast<std::uint32_t>(grey.total());
    }
    if (s.fourcc == V4L2_PIX_FMT_YUYV) {
      for (size_t i = 0; i < grey.total(); ++i) {
        out[2 * i] = grey.data[i];
        out[2 * i + 1] = 128;
      }
      return e.kind == FakeEvent::kCorrupt ? 10 : static_cast<std::uint32_t>(2 * grey.total());
    }
    std::vector<std::uint8_t> jpeg;
    cv::imencode(".jpg", grey, jpeg, {cv::IMWRITE_JPEG_QUALITY, 100});
    std::memcpy(out.data(), jpeg.data(), jpeg.size());
    if (e.kind == FakeEvent::kTruncated) std::memset(out.data() + jpeg.size() / 2, 0, jpeg.size() - jpeg.size() / 2);
    return static_cast<std::uint32_t>(jpeg.size());
  }

  int next_fd_ = 100;
  std::map<int, State> state_;
};

}  // namespace rangebayes
