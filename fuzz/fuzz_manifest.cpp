// libFuzzer entry for batch manifests (ParseManifest, SplitCommandLine, OutputWordIndices, CheckTaskOutputs,
// ResolveTaskArguments, QuoteForShell): any input parses or throws rangebayes::Error; every task parsed has a
// subcommand, its words survive QuoteForShell → SplitCommandLine unchanged, and its output words are words of
// the line that resolving leaves as they are.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "batch/manifest.h"
#include "core/error.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rangebayes;
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::vector<ManifestTask> tasks;
  try {
    tasks = ParseManifest(text, "fuzz.txt");
  } catch (const Error&) {
    return 0;
  }
  fuzz::Require(!tasks.empty(), "a manifest has tasks");
  SubcommandSyntaxes syntaxes;
  syntaxes["convert"].positionals = {{1, false, false}, {1, true, false}};
  syntaxes["smooth"].value_options = {"--noise", "--png"};
  syntaxes["smooth"].output_options = {"--png"};
  syntaxes["smooth"].positionals = {{1, false, false}, {1, true, false}};
  syntaxes["decimate"].value_options = {"--out", "-o"};
  syntaxes["decimate"].output_options = {"--out", "-o"};
  syntaxes["decimate"].positionals = {{-1, false, true}};
  for (size_t i = 0; i < tasks.size(); ++i) {
    const ManifestTask& task = tasks[i];
    fuzz::Require(task.index == static_cast<int>(i), "tasks are numbered in order");
    fuzz::Require(!task.arguments.empty() && !task.arguments[0].empty() && task.arguments[0][0] != '-',
                  "a task starts with a subcommand");
    const std::vector<std::string> again = SplitCommandLine(QuoteForShell(task.arguments));
    fuzz::Require(again == task.arguments, "QuoteForShell then SplitCommandLine gives the words back");
    const std::vector<std::string> resolved = ResolveTaskArguments(task.arguments, fuzz::ScratchDir(), syntaxes);
    fuzz::Require(resolved.size() == task.arguments.size(), "resolving keeps the word count");
    for (const size_t k : OutputWordIndices(task.arguments, syntaxes)) {
      fuzz::Require(k > 0 && k < task.arguments.size(), "an output is a word of the line after the subcommand");
      fuzz::Require(resolved[k] == task.arguments[k], "an output is never resolved");
    }
    try {
      CheckTaskOutputs(task, syntaxes, "fuzz.txt");
    } catch (const Error&) {
    }
  }
  return 0;
}
