#include "apps/command.h"

#include <algorithm>
#include <filesystem>
#include <system_error>
#include <utility>
#include <vector>

namespace rangebayes::apps {
namespace {

// CLI11 lists a negated flag as "--no-x{false}", which reads as "the default is false"; the descriptions say
// which of the pair is the default.
class Formatter : public CLI::Formatter {
 public:
  std::string make_option_name(const CLI::Option* option, bool is_positional) const override {
    std::string name = CLI::Formatter::make_option_name(option, is_positional);
    for (const std::string value : {"{false}", "{true}"}) {
      for (size_t at = name.find(value); at != std::string::npos; at = name.find(value)) name.erase(at, value.size());
    }
    return name;
  }
};

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

std::unique_ptr<CLI::App> MakeApp() {
  auto app = std::make_unique<CLI::App>(
      "rangebayes: stereo range scanning to clean, compact meshes (Diebel, Thrun, Bruenig, ACM TOG 2006).\n"
      "Run 'rangebayes SUBCOMMAND --help' for the options of each subcommand.");
  app->name("rangebayes");
  app->require_subcommand(1);
  app->set_version_flag("--version", "rangebayes 0.1.0");
  app->option_defaults()->always_capture_default();
  app->formatter(std::make_shared<Formatter>());
  AddRegisteredCommands(*app);
  return app;
}

std::string ParsedCommandName(const CLI::App& app) {
  std::string name = "rangebayes";
  const CLI::App* current = &app;
  while (true) {
    const auto subs = current->get_subcommands();
    if (subs.empty()) break;
    current = subs.front();
    name += " " + current->get_name();
  }
  return name;
}

void SetExitCode(int code) { ExitCodeStorage() = code; }
int ExitCode() { return ExitCodeStorage(); }

void UsageError(const std::string& message) { throw CLI::ValidationError(message); }

void RequireDistinctOutputs(const std::vector<std::pair<std::string, std::string>>& outputs) {
  namespace fs = std::filesystem;
  std::vector<fs::path> resolved;
  for (const auto& [option, path] : outputs) {
    std::error_code ec;
    fs::path p = path.empty() ? fs::path() : fs::weakly_canonical(fs::absolute(path), ec);
    if (ec) p = fs::absolute(path).lexically_normal();
    resolved.push_back(p);
  }
  for (size_t i = 0; i < outputs.size(); ++i) {
    for (size_t k = 0; k < i; ++k) {
      if (resolved[i].empty() || resolved[i] != resolved[k]) continue;
      UsageError(outputs[k].first + " and " + outputs[i].first + " name the same file (" + outputs[i].second +
                 "): the second would replace the first");
    }
  }
}

}  // namespace rangebayes::apps
