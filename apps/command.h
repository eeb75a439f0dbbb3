// Self-registering subcommands of the one `rangebayes` binary.
//
// Each apps/cmd_*.cpp defines a function that adds its subcommand(s) to the CLI11 app and registers it with
// RB_REGISTER_COMMANDS(order, function). A subcommand's callback does the work; it reports failure by
// throwing rangebayes::Error (main prints one line "rangebayes SUB: error: ..." and exits 1) or by calling
// SetExitCode. Usage errors (unknown subcommand, bad flag value) exit 2.
#pragma once

#include <CLI/CLI.hpp>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace rangebayes::apps {

using CommandAdder = std::function<void(CLI::App& app)>;

// Commands are added in ascending `order` (the order --help lists them in).
bool RegisterCommands(int order, CommandAdder adder);
void AddRegisteredCommands(CLI::App& app);

// The `rangebayes` command line that main parses: every registered subcommand with its options. batch makes a
// second one to check its task lines with the same parser.
std::unique_ptr<CLI::App> MakeApp();

// "rangebayes SUB [SUBSUB]": the subcommands `app` parsed, or had reached when parsing threw.
std::string ParsedCommandName(const CLI::App& app);

// The process exit code, for commands that succeed partially (default 0).
void SetExitCode(int code);
int ExitCode();

// Usage error from inside a callback (a combination of options CLI11 cannot check): exit code 2.
[[noreturn]] void UsageError(const std::string& message);

// A usage error when two of the files a command will write (each named by its option, e.g. {"--out", path}) are
// one file (the same path after resolving links and ".."): the second write replaced the first (`learn-prior
// --out p.png` wrote its plot over its prior, exit 0). Empty paths are skipped.
void RequireDistinctOutputs(const std::vector<std::pair<std::string, std::string>>& outputs);

}  // namespace rangebayes::apps

#define RB_CONCAT_INNER(a, b) a##b
#define RB_CONCAT(a, b) RB_CONCAT_INNER(a, b)
#define RB_REGISTER_COMMANDS(order, adder) \
  static const bool RB_CONCAT(rb_registered_, __LINE__) = ::rangebayes::apps::RegisterCommands(order, adder)
