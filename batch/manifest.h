// A batch manifest: one `rangebayes` subcommand line per task, and the rule that resolves its paths.
#pragma once

#include <map>
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

// Parses a manifest's text (a leading UTF-8 byte order mark is skipped): blank lines and lines whose first word starts
// with # are skipped. `source` names the file in error messages ("tasks.txt:7: unterminated quote"). Throws on a bad
// line, on a line whose first word is an option or `batch` (a task must be a subcommand other than batch), and on no
// tasks.
std::vector<ManifestTask> ParseManifest(const std::string& text, const std::string& source);

// Reads and parses a manifest file; throws naming the file when it cannot be read.
std::vector<ManifestTask> ReadManifest(const std::string& path);

// How a subcommand's words are read, as far as batch needs: which options take a value (so that positional words
// can be counted) and which words name outputs. apps/cmd_batch.cpp derives it from each subcommand's own parser.
struct SubcommandSyntax {
  std::vector<std::string> value_options;   // options that take a value ("--noise", "-o"): the next word is theirs
  std::vector<std::string> output_options;  // options whose value is an output path ("--out", "-o", "--png")
  struct Positional {
    int words = 1;                // how many words it takes; -1: every remaining positional word
    bool output = false;          // each of its words is an output (convert's OUT)
    bool last_is_output = false;  // its last word is an output unless an output option is given (decimate's FILES)
  };
  std::vector<Positional> positionals;  // in order
};

// Syntax per subcommand, keyed by its name ("convert") or, for a nested one, both words ("calibrate noise").
using SubcommandSyntaxes = std::map<std::string, SubcommandSyntax>;

// The indices of the words of `arguments` (arguments[0] is the subcommand) that name outputs. A subcommand
// without an entry in `syntaxes` has the values of --out and -o as its only outputs.
std::vector<size_t> OutputWordIndices(const std::vector<std::string>& arguments, const SubcommandSyntaxes& syntaxes);

// Refuses a task whose outputs would not stay in its own folder: an output word (OutputWordIndices) that is
// absolute, or that leaves the folder through "..". Throws one Error naming `source`, the line and the word.
void CheckTaskOutputs(const ManifestTask& task, const SubcommandSyntaxes& syntaxes, const std::string& source);

// The path rule of a task (README, "Batch processing"): the command runs with the task's own output folder
// as its working folder, so a relative path names an output there; a word (or the VALUE of --option=VALUE)
// that is not in an output position (OutputWordIndices) and is a relative path naming an existing file or
// folder relative to `manifest_dir` is an input and is replaced by that absolute path. Absolute paths,
// options, outputs and words naming nothing beside the manifest are unchanged. `manifest_dir` must be absolute.
std::vector<std::string> ResolveTaskArguments(const std::vector<std::string>& arguments,
                                              const std::string& manifest_dir, const SubcommandSyntaxes& syntaxes);

// Quotes words for display and for a shell: a word with no special characters is kept, others are put in
// single quotes.
std::string QuoteForShell(const std::vector<std::string>& words);

}  // namespace rangebayes
