// A batch manifest: one `rangebayes` subcommand line per task, and the rule that resolves its paths.
#pragma once

#include <string>
#include <vector>

namespace rangebayes {

// One task of a manifest. `index` counts tasks from 0 in file order (blank and comment lines do not count).
struct ManifestTask {
  int index = 0;
  int line_number = 0;              // 1-based line in the manifest file
  std::string line;                 // the line as written, without surrounding whitespace
  std::vector<std::string> arguments;  // the line split into words (arguments[0] is the subcommand)
};

// Splits one line into words like a POSIX shell without expansions: whitespace separates words; '...'
// keeps everything literally; "..." keeps everything but \" and \\ ; a backslash outside quotes escapes the
// next character; a word starting with # (outside quotes) begins a comment. Throws rangebayes::Error on an
// unterminated quote or a trailing backslash.
std::vector<std::string> SplitCommandLine(const std::string& line);

// Parses a manifest's text: blank lines and lines whose first word starts with # are skipped. `source`
// names the file in error messages ("tasks.txt:7: unterminated quote"). Throws on a bad line, on a line whose
// first word is an option or `batch` (a task must be a subcommand other than batch), and on no tasks.
std::vector<ManifestTask> ParseManifest(const std::string& text, const std::string& source);

// Reads and parses a manifest file; throws naming the file when it cannot be read.
std::vector<ManifestTask> ReadManifest(const std::string& path);

// The path rule of a task (README, "Batch processing"): the command runs with the task's own output folder
// as its working folder, so a relative path names an output there; a word (or the VALUE of --option=VALUE)
// that is a relative path naming an existing file or folder relative to `manifest_dir` is an input and is
// replaced by that absolute path. Absolute paths, options and words naming nothing beside the manifest are
// unchanged. `manifest_dir` must be absolute.
std::vector<std::string> ResolveTaskArguments(const std::vector<std::string>& arguments,
                                              const std::string& manifest_dir);

// Quotes words for display and for a shell: a word with no special characters is kept, others are put in
// single quotes.
std::string QuoteForShell(const std::vector<std::string>& words);

}  // namespace rangebayes
