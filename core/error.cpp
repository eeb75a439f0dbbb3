#include "core/error.h"

namespace rangebayes::internal {

void ThrowError(const char* file, int line, const std::string& message) {
  throw Error(message, StrCat(file, ":", line));
}

}  // namespace rangebayes::internal
