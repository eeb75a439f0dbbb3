// The main() of a benchmark program: runs it, and turns an exception into one error line on stderr
// ("NAME: error: what") and exit status 1, as the rangebayes CLI does.
//
//   int main(int argc, char** argv) { return rangebayes::bench::Main("bench_fuse", RunBench, argc, argv); }
#pragma once

#include <cstdio>
#include <exception>

namespace rangebayes::bench {

inline int Main(const char* name, int (*run)(int argc, char** argv), int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: error: %s\n", name, e.what());
    return 1;
  }
}

}  // namespace rangebayes::bench
