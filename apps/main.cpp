// rangebayes: one binary, subcommands registered by apps/cmd_*.cpp.
#include <CLI/CLI.hpp>
#include <malloc.h>

#include <cstdio>
#include <exception>
#include <string>

#include "apps/command.h"
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

}  // namespace

int main(int argc, char** argv) {
  // Per frame the pipeline allocates and frees the same buffers again (the solver's, the images'): served from
  // glibc's default mmap threshold (128 KiB, adapting upward) and trimmed back to the system, each frame paid
  // its page faults again (a third of a live-path smoothing call; BENCHMARKS.md "Capture and pipeline").
  // Blocks up to 32 MiB (glibc's maximum) come from the heap, and up to 256 MiB of free heap stay mapped.
  mallopt(M_MMAP_THRESHOLD, 32 << 20);
  mallopt(M_TRIM_THRESHOLD, 256 << 20);
  CLI::App app{
      "rangebayes: stereo range scanning to clean, compact meshes (Diebel, Thrun, Bruenig, ACM TOG 2006).\n"
      "Run 'rangebayes SUBCOMMAND --help' for the options of each subcommand."};
  app.name("rangebayes");
  app.require_subcommand(1);
  app.set_version_flag("--version", "rangebayes 0.1.0");
  app.option_defaults()->always_capture_default();
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
    std::fprintf(stderr, "%s: error: %s (see --help)\n", ParsedName(app).c_str(), message.c_str());
    return 2;
  } catch (const rangebayes::Error& e) {
    std::fprintf(stderr, "%s: error: %s\n", ParsedName(app).c_str(), e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "%s: error: out of memory\n", ParsedName(app).c_str());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: error: %s\n", ParsedName(app).c_str(), e.what());
    return 1;
  }
  return rangebayes::apps::ExitCode();
}
