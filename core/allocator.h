// glibc malloc settings for a process that allocates and frees the same large buffers again and again.
#pragma once

namespace rangebayes {

// What ConfigureMallocForRepeatedBuffers did.
enum class MallocConfiguration {
  kApplied,        // blocks up to 32 MiB come from the heap, and up to 256 MiB of free heap stay mapped
  kUserTunables,   // GLIBC_TUNABLES sets glibc.malloc.* already: the user's choice is kept, nothing changed
};

// Every smoothing call, pipeline frame and conversion allocates and frees buffers of the same sizes again. With
// glibc's defaults (mmap threshold 128 KiB adapting upward, trim threshold twice that) freed blocks go back to
// the system and the next call pays its page faults again (measured in docs/journal/python.md, "allocator").
// This raises both thresholds once for the process, unless the environment's GLIBC_TUNABLES already names a
// glibc.malloc tunable. Process-wide: meant for a program's start (the CLI's main, the Python module's import).
MallocConfiguration ConfigureMallocForRepeatedBuffers();

}  // namespace rangebayes
