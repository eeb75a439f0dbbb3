// JSON text of values that carry strings from files, paths and error messages.
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace rangebayes {

// j.dump(indent), except that bytes which are not UTF-8 (a Linux file name may hold any byte but '/' and NUL)
// become U+FFFD instead of throwing json::type_error. For text that is shown or reported, not for a value that
// is read back as a path. Header-only: its users link nlohmann_json themselves.
inline std::string JsonText(const nlohmann::json& j, int indent = -1) {
  return j.dump(indent, ' ', /*ensure_ascii=*/false, nlohmann::json::error_handler_t::replace);
}

}  // namespace rangebayes
