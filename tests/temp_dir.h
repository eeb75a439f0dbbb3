// Temporary files and folders for tests, each named after its use and the test process, so that two suites run at
// once (of two build trees) never share one. Every such path is removed when the test process exits (a suite run
// left some 300 of them, 130 MB, in /tmp each time); RB_KEEP_TEST_FILES=1 keeps them for a look at what a command
// wrote.
#pragma once

#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <set>
#include <string>
#include <system_error>

namespace rangebayes {

namespace temp_dir_internal {
// The paths handed out by this process, removed (with their contents) at its normal exit.
class Registry {
 public:
  ~Registry() {
    const char* keep = std::getenv("RB_KEEP_TEST_FILES");
    if (keep != nullptr && std::string(keep) == "1") return;
    std::error_code ec;
    for (const std::string& path : paths_) std::filesystem::remove_all(path, ec);
  }
  void Add(const std::string& path) {
    std::lock_guard<std::mutex> lock(mutex_);
    paths_.insert(path);
  }

 private:
  std::mutex mutex_;
  std::set<std::string> paths_;
};
inline Registry& TheRegistry() {
  static Registry registry;
  return registry;
}
}  // namespace temp_dir_internal

// A path under the system temp dir for `name`, unique to this process: /tmp/rb_<pid>_<name> (the name stays whole at
// the end, its extension last, for readers and messages that go by it); nothing is created. Whatever is made
// there is removed when the process exits.
inline std::string TempPath(const std::string& name) {
  const std::string path =
      (std::filesystem::temp_directory_path() / ("rb_" + std::to_string(::getpid()) + "_" + name)).string();
  temp_dir_internal::TheRegistry().Add(path);
  return path;
}

// Writes `text` to the file TempPath(name) and returns its path; it stays until the process exits (see above).
inline std::string WriteTempFile(const std::string& name, const std::string& text) {
  const std::string path = TempPath(name);
  std::ofstream(path) << text;
  return path;
}

// The empty folder TempPath(name), made afresh; it stays until the process exits (see above).
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
