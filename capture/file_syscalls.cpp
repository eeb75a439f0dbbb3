#include "capture/file_syscalls.h"

#include <fcntl.h>
#include <unistd.h>

#include <cstdio>

namespace rangebayes {
namespace {

class RealFiles final : public FileSysCalls {
 public:
  int Open(const std::string& path, int flags, mode_t mode) override { return ::open(path.c_str(), flags, mode); }
  ssize_t Write(int fd, const void* data, size_t size) override { return ::write(fd, data, size); }
  int Fsync(int fd) override { return ::fsync(fd); }
  int Close(int fd) override { return ::close(fd); }
  int Rename(const std::string& from, const std::string& to) override { return std::rename(from.c_str(), to.c_str()); }
};

}  // namespace

std::shared_ptr<FileSysCalls> RealFileSysCalls() {
  static const std::shared_ptr<FileSysCalls> real = std::make_shared<RealFiles>();
  return real;
}

}  // namespace rangebayes
