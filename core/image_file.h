// Checks of an image file's bytes before a decoder sees them. A decoder prints its own messages to stderr
// ("libpng error: Read Error"), and libjpeg returns a JPEG that was cut short as a whole image, the missing part
// grey, with only a warning: a frame written half-way would be measured as a scene.
#pragma once

#include <span>
#include <string>

namespace rangebayes {

// PNG: the signature, an IHDR header with a valid size, bit depth and colour type, no more pixels than its bytes
// can hold (deflate compresses at most 1032:1, so nothing is allocated for a hostile header), and the IEND chunk
// at the end. Empty when nothing is wrong, else why ("not a PNG image", "PNG data is cut short: no IEND chunk").
std::string PngProblem(std::span<const unsigned char> bytes);

// JPEG: the start-of-image marker, and an end-of-image marker after the last start-of-scan marker (inside the
// entropy-coded data 0xFF is always followed by 0x00 or a restart marker, so neither marker can appear there).
std::string JpegProblem(std::span<const unsigned char> bytes);

// By the file's signature: PNG and JPEG as above; other formats are left to the decoder (empty).
std::string ImageFileProblem(std::span<const unsigned char> bytes);

// CheckFileToRead(path, what) (core/files.h), then the file's bytes through ImageFileProblem: throws Error
// "PATH: PROBLEM".
void CheckImageFile(const std::string& path, const std::string& what);

}  // namespace rangebayes
