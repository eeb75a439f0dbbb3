// The one project exception and the one check macro.
#pragma once

#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace rangebayes {

// Thrown on bad input or a broken precondition. what() is one line meant for a user (it names the file,
// frame or field); where() is the source location that raised it, for developers.
class Error : public std::runtime_error {
 public:
  Error(const std::string& message, std::string where)
      : std::runtime_error(message), where_(std::move(where)) {}
  explicit Error(const std::string& message) : std::runtime_error(message) {}
  const std::string& where() const { return where_; }

 private:
  std::string where_;
};

namespace internal {
template <typename... Args>
std::string StrCat(const Args&... args) {
  std::ostringstream out;
  (out << ... << args);
  return out.str();
}
[[noreturn]] void ThrowError(const char* file, int line, const std::string& message);
}  // namespace internal

// Concatenates any streamable values into a string.
template <typename... Args>
std::string StrCat(const Args&... args) {
  return internal::StrCat(args...);
}

}  // namespace rangebayes

// RB_CHECK(condition, message parts...): throws rangebayes::Error with the parts streamed together when the
// condition is false. RB_FAIL(parts...) throws unconditionally.
#define RB_CHECK(condition, ...)                                                                   \
  do {                                                                                             \
    if (!(condition)) {                                                                            \
      ::rangebayes::internal::ThrowError(__FILE__, __LINE__, ::rangebayes::StrCat(__VA_ARGS__));   \
    }                                                                                              \
  } while (false)

#define RB_FAIL(...) ::rangebayes::internal::ThrowError(__FILE__, __LINE__, ::rangebayes::StrCat(__VA_ARGS__))
