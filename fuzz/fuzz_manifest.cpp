// libFuzzer entry for batch manifests (ParseManifest, SplitCommandLine, ResolveTaskArguments,
// QuoteForShell): any input parses or throws rangebayes::Error; every task parsed has a subcommand, and its
// words survive QuoteForShell → SplitCommandLine unchanged.
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
  for (size_t i = 0; i < tasks.size(); ++i) {
    const ManifestTask& task = tasks[i];
    fuzz::Require(task.index == static_cast<int>(i), "tasks are numbered in order");
    fuzz::Require(!task.arguments.empty() && !task.arguments[0].empty() && task.arguments[0][0] != '-',
                  "a task starts with a subcommand");
    const std::vector<std::string> again = SplitCommandLine(QuoteForShell(task.arguments));
    fuzz::Require(again == task.arguments, "QuoteForShell then SplitCommandLine gives the words back");
    const std::vector<std::string> resolved = ResolveTaskArguments(task.arguments, fuzz::ScratchDir());
    fuzz::Require(resolved.size() == task.arguments.size(), "resolving keeps the word count");
  }
  return 0;
}
