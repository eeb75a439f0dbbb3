// Ctrl-C (SIGINT) and SIGTERM as a stop request that long-running loops poll, so that they finish their
// outputs (a recording's index, the pipeline's sinks) instead of dying half-way.
#pragma once

#include <atomic>

namespace rangebayes {

// Installs handlers for SIGINT and SIGTERM that set the stop flag. A second SIGINT restores the default
// action, so a third Ctrl-C kills a program that does not stop. No SA_RESTART: a blocking poll() wakes up.
void InstallStopSignalHandlers();

// The flag the handlers set; loops read it (and tests may set it).
std::atomic<bool>& StopFlag();
inline bool StopRequested() { return StopFlag().load(std::memory_order_relaxed); }

}  // namespace rangebayes
