#include "core/files.h"

#include <unistd.h>

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

}  // namespace rangebayes
