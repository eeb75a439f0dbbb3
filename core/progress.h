// The callback through which long-running library code reports progress (library code never prints).
#pragma once

#include <functional>
#include <string_view>

namespace rangebayes {

// fraction in [0, 1]; stage names what is being done ("smoothing", "frame 12"). May be empty.
using ProgressCallback = std::function<void(double fraction, std::string_view stage)>;

}  // namespace rangebayes
