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
    std::fflush(stdout);  // what the command printed comes before its error, also in one file (2>&1)
    std::fprintf(stderr, "%s: error: %s (see --help)\n", ParsedName(app).c_str(), message.c_str());
    return 2;
  } catch (const rangebayes::Error& e) {
    std::fflush(stdout);
    std::fprintf(stderr, "%s: error: %s\n", ParsedName(app).c_str(), e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fflush(stdout);
    std::fprintf(stderr, "%s: error: out of memory\n", ParsedName(app).c_str());
    return 1;
  } catch (const std::exception& e) {
    std::fflush(stdout);
    std::fprintf(stderr, "%s: error: %s\n", ParsedName(app).c_str(), e.what());
    return 1;
  }
  // What a command printed as its result (a report, JSON) must have reached standard output: on a full disk
  // (`eval ... > r.json`) the file would hold less than the command printed while it exited 0.
  if (std::fflush(stdout) != 0 || std::ferror(stdout)) {
    std::fprintf(stderr, "%s: error: writing standard output failed\n", ParsedName(app).c_str());
    return 1;
  }
  return rangebayes::apps::ExitCode();
}
