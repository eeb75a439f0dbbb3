// The rangebayes binary as a user meets it: help, unknown subcommands, bad flags.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <string>
#include <utility>

#include "tests/apps/run_binary.h"

namespace rangebayes {
namespace {

// Every subcommand that apps/cmd_*.cpp registers, on a line of its own under "Subcommands:" (the word "rangebayes"
// alone is also in the error line a help that failed would print).
TEST(Cli, HelpExitsZeroAndListsSubcommands) {
  const RunResult r = RunRangebayes("--help");
  EXPECT_EQ(r.exit_code, 0);
  const size_t list = r.output.find("\nSubcommands:\n");
  ASSERT_NE(list, std::string::npos) << r.output;
  const std::string subcommands = r.output.substr(list);
  for (const char* name :
       {"info", "convert", "smooth", "eval", "stereo", "spacetime", "synth", "eval-depth", "fuse", "decimate",
        "cameras", "record", "live", "replay", "calibrate", "synth-meshes", "learn-prior", "batch"}) {
    EXPECT_NE(subcommands.find("\n  " + std::string(name) + " "), std::string::npos) << name << "\n" << r.output;
  }
  EXPECT_EQ(r.output.find("error"), std::string::npos) << r.output;
}

TEST(Cli, UnknownSubcommandIsOneLineExitTwo) {
  const RunResult r = RunRangebayes("frobnicate");
  EXPECT_EQ(r.exit_code, 2);
  // Named, with the subcommands there are (it said "A subcommand is required").
  EXPECT_NE(r.output.find("error: unknown subcommand 'frobnicate' (the subcommands: info, "), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find('\n'), r.output.size() - 1) << r.output;
  // With --help it printed the general help and exit 0, as if the word were a command.
  const RunResult help = RunRangebayes("frobnicate --help");
  EXPECT_EQ(help.exit_code, 2);
  EXPECT_NE(help.output.find("error: unknown subcommand 'frobnicate'"), std::string::npos) << help.output;
  EXPECT_EQ(RunRangebayes("info --help").exit_code, 0);
}

TEST(Cli, NoSubcommandIsUsageError) {
  const RunResult r = RunRangebayes("");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.output, "rangebayes: error: A subcommand is required (see --help)\n");
}

// Numeric options: one plain line and exit 2 for a value out of range or NaN (CLI11's own checks printed the
// largest double as the range's end, and let NaN through), and a NaN is never taken for an option left out.
TEST(Cli, BadNumericValuesAreOnePlainLine) {
  const std::string mesh = "tests/data/meshes/fandisk_noisy_gauss0.3.obj";
  const std::pair<std::string, std::string> cases[] = {
      {"decimate " + mesh + " /tmp/rb_cli_never.ply --lambda nan", "--lambda: must be a finite number > 0, got nan"},
      {"decimate " + mesh + " /tmp/rb_cli_never.ply --lambda -2", "--lambda: must be a finite number > 0, got -2"},
      {"decimate " + mesh + " /tmp/rb_cli_never.ply --chain-tolerance x", "--chain-tolerance: 'x' is not a number"},
      {"calibrate rig --left a --right b --board 9x6 --square 0 --out /tmp/rb_cli_never.yaml",
       "--square: must be a finite number > 0, got 0"},
      {"smooth " + mesh + " /tmp/rb_cli_never.ply --noise nan", "--noise: must be a finite number > 0, got nan"},
      {"smooth " + mesh + " /tmp/rb_cli_never.ply --sigma NaN", "--sigma: must be a finite number > 0, got nan"},
      // The ranges the help states, checked as usage (they failed in the library, exit 1, after reading the mesh).
      {"smooth " + mesh + " /tmp/rb_cli_never.ply --noise 0", "--noise: must be a finite number > 0, got 0"},
      {"smooth " + mesh + " /tmp/rb_cli_never.ply --noise 20", "--noise: must be a number in [0, 10], got 20"},
      {"smooth " + mesh + " /tmp/rb_cli_never.ply --eps2 0", "--eps2: must be a finite number > 0, got 0"},
      {"smooth " + mesh + " /tmp/rb_cli_never.ply --across-ratio 0.5",
       "--across-ratio: must be a number in [1, 100], got 0.5"},
      // Options that did nothing where they were given.
      {"decimate " + mesh + " /tmp/rb_cli_never.ply --chain-reserve 0.5", "--chain-reserve requires --target-faces"},
      {"stereo tests/data/stereo/tsukuba/imL.png tests/data/stereo/tsukuba/imR.png --out /tmp/rb_cli_never "
       "--cost zncc",
       "--cost applies to --matcher block, not sgbm"},
      {"stereo tests/data/stereo/tsukuba/imL.png tests/data/stereo/tsukuba/imR.png --out /tmp/rb_cli_never "
       "--window 4",
       "--window: must be odd, got 4"},
      {"replay recordings/synth_planes_320x240 --out /tmp/rb_cli_never --window 4", "--window: must be odd, got 4"},
      // The library's limits, checked as usage with the flag named (they failed naming its fields: block_size_px).
      {"replay recordings/synth_planes_320x240 --out /tmp/rb_cli_never --window 13",
       "--window: sgbm takes at most 11 px"},
      {"stereo tests/data/stereo/tsukuba/imL.png tests/data/stereo/tsukuba/imR.png --out /tmp/rb_cli_never "
       "--matcher block --image-noise -5",
       "--image-noise: must be a finite number > 0, got -5"},
      {"stereo tests/data/stereo/tsukuba/imL.png tests/data/stereo/tsukuba/imR.png --out /tmp/rb_cli_never "
       "--max-jump-sigma -5",
       "--max-jump-sigma: must be a finite number > 0, got -5"},
      {"synth --out /tmp/rb_cli_never --baseline -1", "--baseline: must be a finite number > 0, got -1"},
      {"synth --out /tmp/rb_cli_never --cell 100", "--cell: must be a number in [0.5, 64], got 100"},
      {"fuse " + mesh + " " + mesh + " --out /tmp/rb_cli_never --sigma-range -1",
       "--sigma-range: must be a finite number > 0, got -1"},
      {"eval-depth a.pfm tests/data/stereo/tsukuba --gt-scale -3",
       "--gt-scale: must be a number in [0, 1e+06], got -3"},
      {"eval-depth a.pfm tests/data/stereo/tsukuba --mask-value 70000", "--mask-value: Value 70000 not in range"},
      {"eval-depth a.pfm tests/data/stereo/tsukuba/groundtruth.png --scene tests/data/stereo/tsukuba",
       "give GROUND_TRUTH or --scene, not both"},
      {"smooth " + mesh + " /tmp/rb_cli_never.ply --prior-weight nan",
       "--prior-weight: must be a number in [0, 1e+06], got nan"},
      {"decimate " + mesh + " /tmp/rb_cli_never.ply --chain-reserve 2",
       "--chain-reserve: must be a number in [0, 0.99], got 2"},
      {"decimate " + mesh + " /tmp/rb_cli_never.ply --target-faces 0", "--target-faces: must be an integer > 0, got 0"},
      {"decimate " + mesh + " /tmp/rb_cli_never.ply --target-faces 2.5", "--target-faces: '2.5' is not an integer"},
      {"replay recordings/synth_planes_320x240 --out /tmp/rb_cli_never --smooth-budget 1e300",
       "--smooth-budget: must be a number in [-1, 1e+09], got 1e+300"},
      // --count is an int: 2147483648 was "Could not convert", -2 and 0 errors of the library (exit 1).
      {"replay recordings/synth_planes_320x240 --out /tmp/rb_cli_never --count 2147483648",
       "--count: must be -1 (all) or an integer in 1..2147483647, got 2147483648"},
      {"replay recordings/synth_planes_320x240 --out /tmp/rb_cli_never --count -2",
       "--count: must be -1 (all) or an integer in 1..2147483647, got -2"},
      {"replay recordings/synth_planes_320x240 --out /tmp/rb_cli_never --count 0",
       "--count: must be -1 (all) or an integer in 1..2147483647, got 0"},
  };
  for (const auto& [args, message] : cases) {
    const RunResult r = RunRangebayes(args);
    EXPECT_EQ(r.exit_code, 2) << args;
    EXPECT_NE(r.output.find(message), std::string::npos) << args << "\n" << r.output;
    EXPECT_EQ(r.output.find('\n'), r.output.size() - 1) << r.output;
  }
}

// The libcamera source has no frame rate, pixel format or side-by-side mode: those flags are refused with
// --libcamera (they were ignored without a word), before any camera is opened or folder created.
TEST(Cli, V4l2OnlyCameraFlagsAreRefusedWithLibcamera) {
  const std::pair<std::string, std::string> cases[] = {
      {"--fps 15", "--fps is not supported with --libcamera"},
      {"--format grey", "--format is a V4L2 pixel format"},
      {"--side-by-side", "--side-by-side is for one V4L2 device"},
  };
  for (const auto& [flag, message] : cases) {
    const RunResult r = RunRangebayes("record --libcamera " + flag + " --out /tmp/rb_cli_never_rec");
    EXPECT_EQ(r.exit_code, 2) << flag << "\n" << r.output;
    EXPECT_NE(r.output.find(message), std::string::npos) << flag << "\n" << r.output;
    EXPECT_EQ(r.output.find('\n'), r.output.size() - 1) << r.output;
  }
  EXPECT_FALSE(std::filesystem::exists("/tmp/rb_cli_never_rec"));
}

// A calibration that cannot work is refused after its table is printed, and no rig is written (a rig of stereo RMS
// 2e10 px once went out with exit 0): the OpenCV samples with one right image replaced by another view's.
TEST(Cli, CalibrateRigRefusesAnUnusableRig) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / "rb_cli_unusable_rig";
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const auto& entry : fs::directory_iterator(fs::path(RB_SOURCE_DIR) / "tests/data/calibration/opencv_stereo")) {
    fs::copy_file(entry.path(), dir / entry.path().filename());
  }
  fs::copy_file(dir / "right09.jpg", dir / "right05.jpg", fs::copy_options::overwrite_existing);
  const std::string args = "calibrate rig --left '" + (dir / "left*.jpg").string() + "' --right '" +
                           (dir / "right*.jpg").string() + "' -q --out " + (dir / "rig.yaml").string();
  RunResult r = RunRangebayes(args);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("FLAGGED"), std::string::npos) << r.output;  // the table first
  EXPECT_NE(r.output.find("error: the calibration is not usable: stereo RMS"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("--drop-outliers"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "rig.yaml"));
  r = RunRangebayes(args + " --drop-outliers");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "rig.yaml"));
  fs::remove_all(dir);
}

}  // namespace
}  // namespace rangebayes
