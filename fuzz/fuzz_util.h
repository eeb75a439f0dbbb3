// Helpers shared by the libFuzzer targets: a scratch folder per process for the readers that take a path,
// multi-part inputs, and the checks an accepted input must pass. A failed check aborts (a finding).
#pragma once
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

namespace rangebayes::fuzz {

// A folder of this process's own, removed at exit.
inline const std::string& ScratchDir() {
  static const std::string dir = [] {
    std::string pattern = (std::filesystem::temp_directory_path() / "rbfuzz-XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) std::abort();
    static const std::string keep = pattern;
    std::atexit([] {
      std::error_code ec;
      std::filesystem::remove_all(keep, ec);
    });
    return pattern;
  }();
  return dir;
}

// Writes `bytes` to ScratchDir()/name (folders created) and returns the path.
inline std::string WriteScratch(const std::string& name, std::string_view bytes) {
  const std::filesystem::path path = std::filesystem::path(ScratchDir()) / name;
  std::filesystem::create_directories(path.parent_path());
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (!out.good()) std::abort();
  return path.string();
}

// Empties ScratchDir() (between inputs of targets that write several files).
inline void ClearScratch() {
  for (const auto& entry : std::filesystem::directory_iterator(ScratchDir())) {
    std::filesystem::remove_all(entry.path());
  }
}

// Splits an input into at most `parts` pieces at the separator line "\n--8<--\n" (the dictionaries hold it);
// missing pieces are empty.
inline std::vector<std::string_view> SplitParts(std::string_view bytes, size_t parts) {
  static constexpr std::string_view kSeparator = "\n--8<--\n";
  std::vector<std::string_view> out;
  while (out.size() + 1 < parts) {
    const size_t at = bytes.find(kSeparator);
    if (at == std::string_view::npos) break;
    out.push_back(bytes.substr(0, at));
    bytes.remove_prefix(at + kSeparator.size());
  }
  out.push_back(bytes);
  out.resize(parts);
  return out;
}

// A finding: what an accepted input must never contain.
inline void Require(bool ok, const char* what) {
  if (!ok) {
    std::fprintf(stderr, "fuzz check failed: %s\n", what);
    std::abort();
  }
}

template <typename Matrix>
void RequireFinite(const Matrix& m, const char* what) {
  Require(m.allFinite(), what);
}

inline void RequireFinite(double v, const char* what) { Require(std::isfinite(v), what); }

}  // namespace rangebayes::fuzz
