// The system-call seam of the recording writer's files: every open/write/fsync/close/rename of a recording
// goes through this interface, so that tests can fail any write as a full disk does (ENOSPC, a short write
// first) without filling one.
#pragma once

#include <sys/types.h>

#include <cstddef>
#include <memory>
#include <string>

namespace rangebayes {

// Same contracts as the POSIX calls: −1 and errno on failure; Write may write less than asked.
class FileSysCalls {
 public:
  virtual ~FileSysCalls() = default;
  virtual int Open(const std::string& path, int flags, mode_t mode) = 0;
  virtual ssize_t Write(int fd, const void* data, size_t size) = 0;
  virtual int Fsync(int fd) = 0;
  virtual int Close(int fd) = 0;
  virtual int Rename(const std::string& from, const std::string& to) = 0;
};

// The system's calls.
std::shared_ptr<FileSysCalls> RealFileSysCalls();

}  // namespace rangebayes
