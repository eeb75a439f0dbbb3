#include "capture/v4l2_syscalls.h"

#include <fcntl.h>
#include <libv4l2.h>
#include <linux/videodev2.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <cerrno>

namespace rangebayes {
namespace {

class LibV4l2 : public V4l2SysCalls {
 public:
  // libv4l2 prints "libv4l2: error getting capabilities" on a file that is no video device (/dev/null, a
  // regular file): such a file is refused here first (errno from VIDIOC_QUERYCAP, ENOTTY), so that the caller's
  // one error line is the only one.
  int Open(const std::string& path, int flags) override {
    const int fd = ::open(path.c_str(), flags);
    if (fd < 0) return -1;
    v4l2_capability capability{};
    int wrapped = -1;
    if (::ioctl(fd, VIDIOC_QUERYCAP, &capability) == 0) wrapped = v4l2_fd_open(fd, 0);
    if (wrapped < 0) {
      const int error = errno;
      ::close(fd);
      errno = error;
    }
    return wrapped;
  }
  int Close(int fd) override { return v4l2_close(fd); }
  int Ioctl(int fd, unsigned long request, void* arg) override { return v4l2_ioctl(fd, request, arg); }
  void* Mmap(void* address, size_t length, int protection, int flags, int fd, std::int64_t offset) override {
    return v4l2_mmap(address, length, protection, flags, fd, offset);
  }
  int Munmap(void* address, size_t length) override { return v4l2_munmap(address, length); }
  int Poll(struct pollfd* fds, nfds_t count, int timeout_ms) override { return ::poll(fds, count, timeout_ms); }
};

}  // namespace

std::shared_ptr<V4l2SysCalls> RealV4l2SysCalls() { return std::make_shared<LibV4l2>(); }

int XIoctl(V4l2SysCalls& sys, int fd, unsigned long request, void* arg) {
  int r = 0;
  do {
    r = sys.Ioctl(fd, request, arg);
  } while (r == -1 && errno == EINTR);
  return r;
}

}  // namespace rangebayes
