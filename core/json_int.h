// Integers read from JSON (commands of the console, batch records) without the silent wrap of json::get<int>().
#pragma once

#include <cstdint>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>

namespace rangebayes {

// A JSON integer that fits an int; nullopt otherwise: a fraction, a string, or a value that json::get<int>() would
// wrap without a word (4294967298 read as 2). Header-only: its users link nlohmann_json themselves.
inline std::optional<int> JsonInt(const nlohmann::json& v) {
  if (!v.is_number_integer()) return std::nullopt;
  if (v.is_number_unsigned()) {
    const auto u = v.get<std::uint64_t>();
    if (u > static_cast<std::uint64_t>(std::numeric_limits<int>::max())) return std::nullopt;
    return static_cast<int>(u);
  }
  const auto i = v.get<std::int64_t>();
  if (i < std::numeric_limits<int>::min() || i > std::numeric_limits<int>::max()) return std::nullopt;
  return static_cast<int>(i);
}

}  // namespace rangebayes
