#include "apps/flags.h"

namespace rangebayes::apps {

void AddQuietFlag(CLI::App* sub, bool* quiet) {
  sub->add_flag("--quiet,-q", *quiet, "No progress or notices on stderr");
}

void AddPriorWeightOption(CLI::App* sub, std::optional<double>* prior_weight) {
  sub->add_option("--prior-weight", *prior_weight,
                  "Smoothing prior weight beta (unitless, [0, 1e6]); default: a learned prior's own beta, else the "
                  "library's measured default")
      ->check(CLI::Range(0.0, 1e6));
}

void AddToleranceOption(CLI::App* sub, std::string* tolerance) {
  sub->add_option("--tolerance", *tolerance, "Smoothing stopping preset: fast, default or tight")
      ->check(CLI::IsMember({"fast", "default", "tight"}));
}

void AddThreadsOption(CLI::App* sub, int* threads) {
  sub->add_option("--threads", *threads, "Worker threads (0: all cores)")
      ->check(CLI::Range(0, 1024));
}

void AddWindowOption(CLI::App* sub, int* window_px, const std::string& default_note, int min_px) {
  sub->add_option("--window", *window_px, "Matching window side (px, odd, 1-31; " + default_note + ")")
      ->check(CLI::Range(min_px, 31));
}

}  // namespace rangebayes::apps
