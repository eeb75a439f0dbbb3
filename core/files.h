// Checks of a path before it is opened, so that a missing file, a folder and a device each get their own line.
#pragma once

#include <filesystem>
#include <string>

#include "core/error.h"

namespace rangebayes {

// Throws Error unless `path` names a regular file (or a link to one): "PATH: WHAT not found" when nothing is
// there, "PATH: is a directory" for a folder, "PATH: not a regular file" for a device, socket or pipe.
inline void CheckFileToRead(const std::string& path, const std::string& what) {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(path, ec);
  RB_CHECK(std::filesystem::exists(status), path, ": ", what, " not found");
  RB_CHECK(!std::filesystem::is_directory(status), path, ": is a directory");
  RB_CHECK(std::filesystem::is_regular_file(status), path, ": not a regular file");
}

}  // namespace rangebayes
