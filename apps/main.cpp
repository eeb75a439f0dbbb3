// rangebayes: one binary, subcommands registered by apps/cmd_*.cpp.
#include <CLI/CLI.hpp>
#include <cstdio>
#include <exception>
#include <memory>
#include <string>

#include "apps/command.h"
#include "core/allocator.h"
#include "core/error.h"

namespace {

using rangebayes::apps::ParsedCommandName;

// The one error line of a failed command (`suffix` after the message). What the command printed comes before
// it, also when both streams go to one file (2>&1): stdout is flushed first.
int PrintError(const CLI::App& app, const std::string& message, const char* suffix, int exit_code) {
  std::fflush(stdout);
  std::fprintf(stderr, "%s: error: %s%s\n", ParsedCommandName(app).c_str(), message.c_str(), suffix);
  return exit_code;
}

// "unknown subcommand 'X' (the subcommands: ...)" when the first argument is a word that names no subcommand;
// empty otherwise.
std::string UnknownSubcommand(const CLI::App& app, int argc, char** argv) {
  if (argc < 2 || argv[1][0] == '-') return {};
  std::string names;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; })) {
    if (sub->check_name(argv[1])) return {};
    names += (names.empty() ? "" : ", ") + sub->get_name();
  }
  return std::string("unknown subcommand '") + argv[1] + "' (the subcommands: " + names + ")";
}

}  // namespace

int main(int argc, char** argv) {
  rangebayes::ConfigureMallocForRepeatedBuffers();
  const std::unique_ptr<CLI::App> app_owner = rangebayes::apps::MakeApp();
  CLI::App& app = *app_owner;
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    // `rangebayes capture --help` printed the general help with exit 0, as if `capture` were a command.
    const std::string unknown = UnknownSubcommand(app, argc, argv);
    if (!unknown.empty()) return PrintError(app, unknown, " (see --help)", 2);
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line, exit 2, for every usage error (CLI11's own codes vary by kind).
    std::string message = e.what();
    // A first word that is no subcommand: named, with the subcommands there are (CLI11 said "A subcommand is
    // required").
    const std::string unknown = UnknownSubcommand(app, argc, argv);
    if (!unknown.empty()) message = unknown;
    for (char& c : message) {
      if (c == '\n') c = ' ';
    }
    return PrintError(app, message, " (see --help)", 2);
  } catch (const rangebayes::Error& e) {
    return PrintError(app, e.what(), "", 1);
  } catch (const std::bad_alloc&) {
    return PrintError(app, "out of memory", "", 1);
  } catch (const std::exception& e) {
    return PrintError(app, e.what(), "", 1);
  }
  // What a command printed as its result (a report, JSON) must have reached standard output: on a full disk
  // (`eval ... > r.json`) the file would hold less than the command printed while it exited 0.
  if (std::fflush(stdout) != 0 || std::ferror(stdout)) {
    std::fprintf(stderr, "%s: error: writing standard output failed\n", ParsedCommandName(app).c_str());
    return 1;
  }
  return rangebayes::apps::ExitCode();
}
