#include "calibration/opencv_yaml.h"

#include <cctype>
#include <fstream>
#include <sstream>

#include "core/error.h"

namespace rangebayes {
namespace {

bool IsKeyStart(char c) { return std::isalpha(static_cast<unsigned char>(c)) != 0 || c == '_'; }
bool IsKeyChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_'; }

// Consumes the part of a line inside a flow sequence (after its '['), updating `depth`; false on a character
// that a sequence of numbers and quoted strings cannot hold.
bool ScanFlow(const std::string& text, size_t from, int* depth) {
  for (size_t i = from; i < text.size(); ++i) {
    const char c = text[i];
    if (c == '"' || c == '\'') {
      const size_t end = text.find(c, i + 1);
      if (end == std::string::npos) return false;  // OpenCV writes a string on one line
      i = end;
    } else if (c == '[') {
      ++*depth;
    } else if (c == ']') {
      if (--*depth < 0) return false;
    } else if (c == '#' && *depth == 0) {
      return true;  // a comment after the sequence
    } else if (!(std::isalnum(static_cast<unsigned char>(c)) || c == ' ' || c == ',' || c == '.' || c == '-' ||
                 c == '+')) {
      return false;
    }
  }
  return true;
}

// The rest of `line` from `from` is one quoted string, or a number or word (letters, digits, . - + _ and spaces).
bool ScalarValue(const std::string& line, size_t from) {
  if (from == std::string::npos || from >= line.size()) return false;
  const char c = line[from];
  if (c == '"' || c == '\'') {
    const size_t end = line.find(c, from + 1);
    return end != std::string::npos && line.find_first_not_of(' ', end + 1) == std::string::npos;
  }
  for (size_t k = from; k < line.size(); ++k) {
    const char v = line[k];
    if (!(std::isalnum(static_cast<unsigned char>(v)) || v == '.' || v == '-' || v == '+' || v == '_' || v == ' ')) {
      return false;
    }
  }
  return true;
}

}  // namespace

void CheckOpenCvYamlSubset(const std::string& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  RB_CHECK(in.good(), path, ": cannot read");
  std::string line;
  int number = 0;
  int depth = 0;                // open '[' of a flow sequence that continues on the next line
  bool sequence_open = false;   // the last key had no value: '- item' lines may follow
  size_t item_indent = std::string::npos;
  auto refuse = [&](const char* why) {
    RB_FAIL(path, ": line ", number, ": not an OpenCV YAML ", what, " (", why, ")");
  };
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.find('\t') != std::string::npos) refuse("a tab");
    if (number == 1) {
      if (line != "%YAML:1.0" && line != "%YAML 1.0") refuse("the first line must be %YAML:1.0");
      continue;
    }
    if (number == 2) {
      if (line.find_first_not_of(' ', 3) != std::string::npos || line.compare(0, 3, "---") != 0) {
        refuse("the second line must be ---");
      }
      continue;
    }
    if (depth > 0) {
      if (!ScanFlow(line, 0, &depth)) refuse("not a sequence of numbers and quoted strings");
      continue;
    }
    const size_t indent = line.find_first_not_of(' ');
    if (indent == std::string::npos || line[indent] == '#') continue;  // blank, or a comment
    if (line[indent] == '-') {
      // An item of a block sequence under the 'key:' before it (how OpenCV writes a list of strings).
      if (!sequence_open || indent == 0 || (item_indent != std::string::npos && indent != item_indent) ||
          line.compare(indent, 2, "- ") != 0) {
        refuse("a '- item' that is not in a list under 'key:'");
      }
      item_indent = indent;
      if (!ScalarValue(line, line.find_first_not_of(' ', indent + 1))) refuse("an item that is not a value");
      continue;
    }
    sequence_open = false;
    item_indent = std::string::npos;
    size_t i = indent;
    if (!IsKeyStart(line[i])) refuse("expected 'key: value'");
    while (i < line.size() && IsKeyChar(line[i])) ++i;
    if (i == line.size() || line[i] != ':' || (i + 1 < line.size() && line[i + 1] != ' ')) {
      refuse("expected 'key: value'");
    }
    const size_t value = line.find_first_not_of(' ', i + 1);
    if (value == std::string::npos || line[value] == '#') {
      sequence_open = true;  // a list or a map may follow, indented
      continue;
    }
    if (line[value] == '[') {
      depth = 1;
      if (!ScanFlow(line, value + 1, &depth)) refuse("not a sequence of numbers and quoted strings");
    } else if (line.compare(value, std::string::npos, "!!opencv-matrix") == 0) {
      // the matrix's rows, cols, dt and data follow, indented
    } else if (!ScalarValue(line, value)) {
      refuse("a value that is not a number, a word or a quoted string");
    }
  }
  if (number < 2) refuse("the file must start with %YAML:1.0 and ---");
  if (depth != 0) refuse("an unclosed [");
}

}  // namespace rangebayes
