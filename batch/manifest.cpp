#include "batch/manifest.h"

#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/error.h"

namespace rangebayes {
namespace fs = std::filesystem;

std::vector<std::string> SplitCommandLine(const std::string& line) {
  std::vector<std::string> words;
  std::string word;
  bool in_word = false;
  size_t i = 0;
  while (i < line.size()) {
    const char c = line[i];
    if (c == ' ' || c == '\t' || c == '\r' || c == '\n') {
      if (in_word) words.push_back(word);
      word.clear();
      in_word = false;
      ++i;
    } else if (c == '#' && !in_word) {
      break;
    } else if (c == '\'') {
      const size_t end = line.find('\'', i + 1);
      RB_CHECK(end != std::string::npos, "unterminated ' quote");
      word += line.substr(i + 1, end - i - 1);
      in_word = true;
      i = end + 1;
    } else if (c == '"') {
      in_word = true;
      ++i;
      bool closed = false;
      while (i < line.size()) {
        if (line[i] == '"') {
          closed = true;
          ++i;
          break;
        }
        if (line[i] == '\\' && i + 1 < line.size() && (line[i + 1] == '"' || line[i + 1] == '\\')) ++i;
        word += line[i++];
      }
      RB_CHECK(closed, "unterminated \" quote");
    } else if (c == '\\') {
      RB_CHECK(i + 1 < line.size(), "backslash at the end of the line");
      word += line[i + 1];
      in_word = true;
      i += 2;
    } else {
      word += c;
      in_word = true;
      ++i;
    }
  }
  if (in_word) words.push_back(word);
  return words;
}

std::vector<ManifestTask> ParseManifest(const std::string& text, const std::string& source) {
  std::vector<ManifestTask> tasks;
  std::istringstream in(text);
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    std::vector<std::string> words;
    try {
      words = SplitCommandLine(line);
    } catch (const Error& e) {
      RB_FAIL(source, ":", line_number, ": ", e.what());
    }
    if (words.empty()) continue;
    RB_CHECK(!words[0].empty(), source, ":", line_number, ": a task starts with a subcommand, not an empty word");
    RB_CHECK(words[0][0] != '-', source, ":", line_number,
             ": a task starts with a subcommand (smooth, replay, decimate, ...), not the option '", words[0], "'");
    RB_CHECK(words[0] != "rangebayes", source, ":", line_number,
             ": leave out the binary's name; a task line starts with the subcommand");
    RB_CHECK(words[0] != "batch", source, ":", line_number, ": a task cannot be a batch command");
    const size_t first = line.find_first_not_of(" \t");
    const size_t last = line.find_last_not_of(" \t\r\n");
    tasks.push_back({static_cast<int>(tasks.size()), line_number, line.substr(first, last - first + 1), words});
  }
  RB_CHECK(!tasks.empty(), source, ": the manifest has no tasks (one rangebayes subcommand line per task)");
  return tasks;
}

std::vector<ManifestTask> ReadManifest(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  RB_CHECK(in.good(), path, ": cannot read the manifest");
  std::ostringstream text;
  text << in.rdbuf();
  return ParseManifest(text.str(), path);
}

std::vector<std::string> ResolveTaskArguments(const std::vector<std::string>& arguments,
                                              const std::string& manifest_dir) {
  RB_CHECK(fs::path(manifest_dir).is_absolute(), "manifest folder must be absolute: ", manifest_dir);
  auto resolve = [&](const std::string& word) -> std::string {
    if (word.empty() || word[0] == '-' || fs::path(word).is_absolute()) return word;
    const fs::path candidate = fs::path(manifest_dir) / word;
    std::error_code ec;
    if (fs::exists(candidate, ec)) return candidate.lexically_normal().string();
    return word;
  };
  std::vector<std::string> resolved;
  resolved.reserve(arguments.size());
  for (size_t i = 0; i < arguments.size(); ++i) {
    const std::string& word = arguments[i];
    if (i == 0) {
      resolved.push_back(word);  // the subcommand
    } else if (word.rfind("--", 0) == 0 && word.find('=') != std::string::npos) {
      const size_t eq = word.find('=');
      resolved.push_back(word.substr(0, eq + 1) + resolve(word.substr(eq + 1)));
    } else {
      resolved.push_back(resolve(word));
    }
  }
  return resolved;
}

std::string QuoteForShell(const std::vector<std::string>& words) {
  std::string out;
  for (const std::string& word : words) {
    if (!out.empty()) out += ' ';
    const bool plain = !word.empty() && word.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ"
                                                               "0123456789_-+=/.,:@%") == std::string::npos;
    if (plain) {
      out += word;
      continue;
    }
    out += '\'';
    for (const char c : word) {
      if (c == '\'') {
        out += "'\\''";
      } else {
        out += c;
      }
    }
    out += '\'';
  }
  return out;
}

}  // namespace rangebayes
