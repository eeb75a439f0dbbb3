// Checks of paths before they are opened or written, so that a missing file, a folder, a device and a folder
// that cannot be written each get their own line, and so that a long computation does not end in an output that
// cannot be written.
#pragma once

#include <string>
#include <string_view>

namespace rangebayes {

// Throws Error unless `path` names a regular file (or a link to one): "PATH: WHAT not found" when nothing is
// there, "PATH: is a directory" for a folder, "PATH: not a regular file" for a device, socket or pipe.
void CheckFileToRead(const std::string& path, const std::string& what);

// Throws Error unless a file can be created at `path` or the file there replaced: its folder exists and can be
// written, and `path` is not a folder. Commands call it before their work, not after.
void CheckFileToWrite(const std::string& path);

// Writes `bytes` to `path` so that a failure (a full disk, a file size limit) leaves no partial file and the old
// one intact: into a temporary file in the same folder, renamed over `path` once complete; with `sync`, fsync'd
// first, so that a crash of the machine cannot leave the name on an empty file. A path that exists as something
// other than a regular file (a device such as /dev/stdout, a pipe, a symbolic link) is written in place. Throws
// Error "PATH: ..." naming what failed.
void WriteFileAtomically(const std::string& path, std::string_view bytes, bool sync = false);

// Creates the folder `path` and its parents when missing. Throws Error "PATH: cannot create folder (why)" when
// that fails, or when `path` exists and is not a folder.
void CreateFolder(const std::string& path);

}  // namespace rangebayes
