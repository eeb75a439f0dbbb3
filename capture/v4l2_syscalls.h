// The system-call seam of the V4L2 code: every open/ioctl/mmap/munmap/poll/close goes through this
// interface, so that tests can script a fake device (negotiation, streaming, timeouts, a device that is
// unplugged mid-stream, one that stalls) on machines without cameras or video kernel modules.
#pragma once

#include <poll.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>

namespace rangebayes {

// Same contracts as the POSIX / libv4l2 calls: −1 (MAP_FAILED for Mmap) and errno on failure.
class V4l2SysCalls {
 public:
  virtual ~V4l2SysCalls() = default;
  virtual int Open(const std::string& path, int flags) = 0;
  virtual int Close(int fd) = 0;
  virtual int Ioctl(int fd, unsigned long request, void* arg) = 0;
  virtual void* Mmap(void* address, size_t length, int protection, int flags, int fd, std::int64_t offset) = 0;
  virtual int Munmap(void* address, size_t length) = 0;
  virtual int Poll(struct pollfd* fds, nfds_t count, int timeout_ms) = 0;
};

// The real calls through libv4l2 (v4l2_open, v4l2_ioctl, v4l2_mmap, ...), which also convert exotic
// camera formats; poll is the system's.
std::shared_ptr<V4l2SysCalls> RealV4l2SysCalls();

// ioctl with the EINTR retry every V4L2 program needs.
int XIoctl(V4l2SysCalls& sys, int fd, unsigned long request, void* arg);

}  // namespace rangebayes
