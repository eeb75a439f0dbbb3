#include "apps/command.h"

#include <algorithm>
#include <utility>
#include <vector>

namespace rangebayes::apps {
namespace {

std::vector<std::pair<int, CommandAdder>>& Registry() {
  static std::vector<std::pair<int, CommandAdder>> registry;
  return registry;
}
int& ExitCodeStorage() {
  static int code = 0;
  return code;
}

}  // namespace

bool RegisterCommands(int order, CommandAdder adder) {
  Registry().emplace_back(order, std::move(adder));
  return true;
}

void AddRegisteredCommands(CLI::App& app) {
  auto& registry = Registry();
  std::stable_sort(registry.begin(), registry.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& [order, adder] : registry) adder(app);
}

void SetExitCode(int code) { ExitCodeStorage() = code; }
int ExitCode() { return ExitCodeStorage(); }

void UsageError(const std::string& message) { throw CLI::ValidationError(message); }

}  // namespace rangebayes::apps
