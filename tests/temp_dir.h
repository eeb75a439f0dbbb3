// Temporary files and folders for tests, each named after its use and the test process, so that two suites run at
// once (of two build trees) never share one.
#pragma once

#include <unistd.h>

#include <filesystem>
#include <string>
#include <system_error>

namespace rangebayes {

// A path under the system temp dir for `name`, unique to this process: /tmp/rb_<pid>_<name> (the name stays whole at
// the end, its extension last, for readers and messages that go by it); nothing is created.
inline std::string TempPath(const std::string& name) {
  return (std::filesystem::temp_directory_path() / ("rb_" + std::to_string(::getpid()) + "_" + name)).string();
}

// The empty folder TempPath(name), made afresh; it stays after the test, for a look at what a command wrote.
inline std::string FreshTempDir(const std::string& name) {
  const std::string path = TempPath(name);
  std::filesystem::remove_all(path);
  std::filesystem::create_directories(path);
  return path;
}

// The empty folder TempPath(name), removed with its contents on destruction.
class TempDir {
 public:
  explicit TempDir(const std::string& name) : path_(FreshTempDir(name)) {}
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return path_; }

 private:
  std::string path_;
};

}  // namespace rangebayes
