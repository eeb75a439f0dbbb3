#include "core/files.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include "core/error.h"

namespace rangebayes {
namespace fs = std::filesystem;

void CheckFileToRead(const std::string& path, const std::string& what) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  RB_CHECK(fs::exists(status), path, ": ", what, " not found");
  RB_CHECK(!fs::is_directory(status), path, ": is a directory");
  RB_CHECK(fs::is_regular_file(status), path, ": not a regular file");
}

void CheckFileToWrite(const std::string& path) {
  RB_CHECK(!path.empty(), "an output file name is empty");
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  RB_CHECK(!fs::is_directory(status), path, ": is a directory");
  const fs::path parent = fs::path(path).has_parent_path() ? fs::path(path).parent_path() : fs::path(".");
  const fs::file_status folder = fs::status(parent, ec);
  RB_CHECK(fs::exists(folder), path, ": cannot create: folder ", parent.string(), " does not exist");
  RB_CHECK(fs::is_directory(folder), path, ": cannot create: ", parent.string(), " is not a folder");
  // The writers replace an existing file in place (its own permission counts) or create a new one in the folder.
  const bool writable = fs::exists(status) ? access(path.c_str(), W_OK) == 0 : access(parent.c_str(), W_OK) == 0;
  RB_CHECK(writable, path, ": cannot write: ", std::strerror(errno));
}

void CreateFolder(const std::string& path) {
  std::error_code ec;
  fs::create_directories(path, ec);
  RB_CHECK(!ec, path, ": cannot create folder (", ec.message(), ")");
  RB_CHECK(fs::is_directory(path, ec), path, ": exists and is not a folder");
}

namespace {

// Writes all of `bytes` to `fd`; false with errno set when a write fails.
bool WriteAllBytes(int fd, std::string_view bytes) {
  size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    done += static_cast<size_t>(n);
  }
  return true;
}

}  // namespace

void WriteFileAtomically(const std::string& path, std::string_view bytes, bool sync) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status existing = fs::symlink_status(path, ec);
  if (fs::exists(existing) && !fs::is_regular_file(existing)) {
    const int fd = ::open(path.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC);
    RB_CHECK(fd >= 0, path, ": cannot write: ", std::strerror(errno));
    const bool written = WriteAllBytes(fd, bytes);
    const int error = errno;
    const bool closed = ::close(fd) == 0;
    RB_CHECK(written && closed, path, ": write failed: ", std::strerror(written ? errno : error));
    return;
  }
  static std::atomic<unsigned> serial{0};
  const fs::path target(path);
  const fs::path temporary =
      target.parent_path() / StrCat(".", target.filename().string(), ".tmp-", ::getpid(), "-", serial++);
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  RB_CHECK(fd >= 0, path, ": cannot create: ", std::strerror(errno));
  bool ok = WriteAllBytes(fd, bytes);
  const char* step = "write failed";
  if (ok && sync && ::fsync(fd) != 0) ok = false;
  int error = errno;
  if (::close(fd) != 0 && ok) {
    ok = false;
    error = errno;
  }
  if (ok && ::rename(temporary.c_str(), path.c_str()) != 0) {
    ok = false;
    error = errno;
    step = "cannot replace";
  }
  if (!ok) {
    ::unlink(temporary.c_str());  // nothing half-written is left behind, and the old file stays
    RB_FAIL(path, ": ", step, ": ", std::strerror(error));
  }
}

}  // namespace rangebayes
