// The rangebayes binary as a user meets it: help, unknown subcommands, bad flags.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

#include "tests/apps/run_binary.h"

namespace rangebayes {
namespace {

TEST(Cli, HelpExitsZeroAndListsSubcommands) {
  const RunResult r = RunRangebayes("--help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.output.find("rangebayes"), std::string::npos);
}

TEST(Cli, UnknownSubcommandIsOneLineExitTwo) {
  const RunResult r = RunRangebayes("frobnicate");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("error"), std::string::npos);
  EXPECT_EQ(r.output.find('\n'), r.output.size() - 1) << r.output;
}

TEST(Cli, NoSubcommandIsUsageError) {
  const RunResult r = RunRangebayes("");
  EXPECT_EQ(r.exit_code, 2);
}

}  // namespace
}  // namespace rangebayes
