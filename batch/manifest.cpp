#include "batch/manifest.h"

#include <algorithm>
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
  // A file saved by an editor that marks UTF-8 (Windows) starts with a byte order mark, which is no part of a word.
  const std::string bom = "\xEF\xBB\xBF";
  std::istringstream in(text.rfind(bom, 0) == 0 ? text.substr(bom.size()) : text);
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

std::vector<size_t> OutputWordIndices(const std::vector<std::string>& arguments, const SubcommandSyntaxes& syntaxes) {
  std::vector<size_t> outputs;
  if (arguments.empty()) return outputs;
  size_t first = 1;
  const SubcommandSyntax* syntax = nullptr;
  if (arguments.size() > 1) {
    const auto nested = syntaxes.find(arguments[0] + " " + arguments[1]);
    if (nested != syntaxes.end()) {
      syntax = &nested->second;
      first = 2;
    }
  }
  if (syntax == nullptr) {
    const auto it = syntaxes.find(arguments[0]);
    if (it != syntaxes.end()) syntax = &it->second;
  }
  static const SubcommandSyntax kFallback{{"--out", "-o"}, {"--out", "-o"}, {}};
  if (syntax == nullptr) syntax = &kFallback;
  auto listed = [](const std::vector<std::string>& names, const std::string& name) {
    return std::find(names.begin(), names.end(), name) != names.end();
  };
  std::vector<size_t> positional;
  bool output_option = false;
  bool only_positional = false;
  for (size_t i = first; i < arguments.size(); ++i) {
    const std::string& word = arguments[i];
    if (only_positional || word.empty() || word[0] != '-' || word == "-") {
      positional.push_back(i);
    } else if (word == "--") {
      only_positional = true;
    } else if (word.rfind("--", 0) == 0 && word.find('=') != std::string::npos) {
      if (listed(syntax->output_options, word.substr(0, word.find('=')))) {
        outputs.push_back(i);
        output_option = true;
      }
    } else if (listed(syntax->value_options, word) || listed(syntax->output_options, word)) {
      if (i + 1 < arguments.size()) {
        ++i;
        if (listed(syntax->output_options, word)) {
          outputs.push_back(i);
          output_option = true;
        }
      }
    } else if (word.size() > 2 && word[1] != '-' && listed(syntax->output_options, word.substr(0, 2))) {
      outputs.push_back(i);  // -oVALUE
      output_option = true;
    }
  }
  size_t next = 0;
  for (const SubcommandSyntax::Positional& p : syntax->positionals) {
    const size_t count = p.words < 0 ? positional.size() - next : std::min<size_t>(p.words, positional.size() - next);
    if (p.output) {
      for (size_t k = 0; k < count; ++k) outputs.push_back(positional[next + k]);
    } else if (p.last_is_output && !output_option && count > 0) {
      outputs.push_back(positional[next + count - 1]);
    }
    next += count;
  }
  std::sort(outputs.begin(), outputs.end());
  return outputs;
}

namespace {

// The path in an output word: the word, or VALUE of --option=VALUE, or VALUE of -oVALUE.
std::string OutputPath(const std::string& word) {
  if (word.rfind("--", 0) == 0 && word.find('=') != std::string::npos) return word.substr(word.find('=') + 1);
  if (word.size() > 2 && word[0] == '-' && word[1] != '-') return word.substr(2);
  return word;
}

}  // namespace

void CheckTaskOutputs(const ManifestTask& task, const SubcommandSyntaxes& syntaxes, const std::string& source) {
  for (const size_t i : OutputWordIndices(task.arguments, syntaxes)) {
    const std::string path = OutputPath(task.arguments[i]);
    RB_CHECK(!fs::path(path).is_absolute(), source, ":", task.line_number, ": the output '", path,
             "' is an absolute path; a task's outputs are relative paths inside its own folder DIR/tasks/", task.index,
             "/, which keeps tasks from overwriting each other's results");
    int depth = 0;
    for (const fs::path& part : fs::path(path).lexically_normal()) {
      if (part == "..")
        --depth;
      else if (!part.empty() && part != ".")
        ++depth;
      RB_CHECK(depth >= 0, source, ":", task.line_number, ": the output '", path,
               "' leaves the task's folder DIR/tasks/", task.index, "/ through '..'; name it inside that folder");
    }
  }
}

std::vector<std::string> ResolveTaskArguments(const std::vector<std::string>& arguments,
                                              const std::string& manifest_dir, const SubcommandSyntaxes& syntaxes) {
  RB_CHECK(fs::path(manifest_dir).is_absolute(), "manifest folder must be absolute: ", manifest_dir);
  auto resolve = [&](const std::string& word) -> std::string {
    if (word.empty() || word[0] == '-' || fs::path(word).is_absolute()) return word;
    const fs::path candidate = fs::path(manifest_dir) / word;
    std::error_code ec;
    if (fs::exists(candidate, ec)) return candidate.lexically_normal().string();
    return word;
  };
  const std::vector<size_t> outputs = OutputWordIndices(arguments, syntaxes);
  std::vector<std::string> resolved;
  resolved.reserve(arguments.size());
  for (size_t i = 0; i < arguments.size(); ++i) {
    const std::string& word = arguments[i];
    if (i == 0 || std::binary_search(outputs.begin(), outputs.end(), i)) {
      resolved.push_back(word);  // the subcommand, or an output: never a path beside the manifest
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
