// Flags that several subcommands share, each defined once here: one spelling, one meaning, one help text.
#pragma once

#include <CLI/CLI.hpp>
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

namespace rangebayes::apps {

// --quiet,-q: no progress bar and no notices on stderr (results on stdout and errors are still printed).
void AddQuietFlag(CLI::App* sub, bool* quiet);

// --prior-weight B: the smoothing prior weight β (unitless, [0, 1e6]). Left empty when not given, so that the
// library's rule (bayes/learn_prior_io.h ResolvePriorWeight) picks a learned prior's own β or the default.
void AddPriorWeightOption(CLI::App* sub, std::optional<double>* prior_weight);

// --prior NAME: sqrt, quadratic, cauchy or a learned prior FILE.yaml (bayes/learn_prior_io.h ApplySmoothingPrior).
void AddPriorOption(CLI::App* sub, std::string* prior);

// --tolerance fast|default|tight: the smoother's stopping preset (ParseSmoothTolerance).
void AddToleranceOption(CLI::App* sub, std::string* tolerance);

// --threads N: worker threads (0: all cores, [0, 1024]).
void AddThreadsOption(CLI::App* sub, int* threads);

// The direction of a --view x y z option (three numbers): a usage error unless it is finite and nonzero. Any
// length is a direction (the renderer normalises it stably: 1e200 and 1e-300 included).
Eigen::Vector3d ViewDirectionOption(const std::vector<double>& xyz);

// --window W: the matching window side (px, odd, 1-31; 0 where allowed: the matcher's default).
// default_note says what the default is for this subcommand.
void AddWindowOption(CLI::App* sub, int* window_px, const std::string& default_note, int min_px);

// --window with the sgbm matcher: a usage error above OpenCV's largest block (kSgbmMaxBlockSizePx).
void CheckSgbmWindow(int window_px);

// Checks of real-valued options with plain messages (CLI11's PositiveNumber and NonNegativeNumber print the
// largest double as the end of their range, and let NaN through).
CLI::Validator PositiveReal();     // a finite number > 0
CLI::Validator PositiveOrInf();    // a number > 0, inf included (no limit)
CLI::Validator NonNegativeReal();  // a finite number ≥ 0
CLI::Validator RealRange(double lo, double hi);  // a number in [lo, hi] (NaN refused)
CLI::Validator PositiveUpTo(double hi);          // a number in (0, hi]
// Counts and indices: CLI11's checks for these print the largest double as the range's end.
CLI::Validator PositiveInteger();     // an integer > 0
CLI::Validator NonNegativeInteger();  // an integer ≥ 0
CLI::Validator CountOrAll();          // -1 (all) or an int count in 1..2147483647

}  // namespace rangebayes::apps
