// Writing pictures for people to look at (PNG), from our plain RgbImage.
#pragma once

#include <string>

#include "core/image.h"

namespace rangebayes {

// PNG whatever the path's extension; a failure leaves no partial file (WriteFileAtomically). Throws Error naming
// the path when the file cannot be written.
void WritePng(const RgbImage& image, const std::string& path);

}  // namespace rangebayes
