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

// The name of the subcommand that was parsed, for error messages ("rangebayes smooth: error: ...").
std::string ParsedName(const CLI::App& app) {
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

// The one error line of a failed command (`suffix` after the message). What the command printed comes before
// it, also when both streams go to one file (2>&1): stdout is flushed first.
int PrintError(const CLI::App& app, const std::string& message, const char* suffix, int exit_code) {
  std::fflush(stdout);
  std::fprintf(stderr, "%s: error: %s%s\n", ParsedName(app).c_str(), message.c_str(), suffix);
  return exit_code;
}

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

}  // namespace

int main(int argc, char** argv) {
  rangebayes::ConfigureMallocForRepeatedBuffers();
  CLI::App app{
      "rangebayes: stereo range scanning to clean, compact meshes (Diebel, Thrun, Bruenig, ACM TOG 2006).\n"
      "Run 'rangebayes SUBCOMMAND --help' for the options of each subcommand."};
  app.name("rangebayes");
  app.require_subcommand(1);
  app.set_version_flag("--version", "rangebayes 0.1.0");
  app.option_defaults()->always_capture_default();
  app.formatter(std::make_shared<Formatter>());
  rangebayes::apps::AddRegisteredCommands(app);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    // One line, exit 2, for every usage error (CLI11's own codes vary by kind).
    std::string message = e.what();
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
    std::fprintf(stderr, "%s: error: writing standard output failed\n", ParsedName(app).c_str());
    return 1;
  }
  return rangebayes::apps::ExitCode();
}
