// Checks of paths before they are opened or written, so that a missing file, a folder, a device and a folder
// that cannot be written each get their own line, and so that a long computation does not end in an output that
// cannot be written.
#pragma once

#include <string>

namespace rangebayes {

// Throws Error unless `path` names a regular file (or a link to one): "PATH: WHAT not found" when nothing is
// there, "PATH: is a directory" for a folder, "PATH: not a regular file" for a device, socket or pipe.
void CheckFileToRead(const std::string& path, const std::string& what);

// Throws Error unless a file can be created at `path` or the file there replaced: its folder exists and can be
// written, and `path` is not a folder. Commands call it before their work, not after.
void CheckFileToWrite(const std::string& path);

// Creates the folder `path` and its parents when missing. Throws Error "PATH: cannot create folder (why)" when
// that fails, or when `path` exists and is not a folder.
void CreateFolder(const std::string& path);

}  // namespace rangebayes
