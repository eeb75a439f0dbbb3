#include "core/allocator.h"

#include <malloc.h>

#include <cstdlib>
#include <cstring>

namespace rangebayes {

MallocConfiguration ConfigureMallocForRepeatedBuffers() {
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  if (tunables != nullptr && std::strstr(tunables, "glibc.malloc.") != nullptr) {
    return MallocConfiguration::kUserTunables;
  }
  mallopt(M_MMAP_THRESHOLD, 32 << 20);  // glibc's largest accepted value
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
  return MallocConfiguration::kApplied;
}

}  // namespace rangebayes
