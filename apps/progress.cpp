#include "apps/progress.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace rangebayes::apps {
namespace {

// Longest silence of the line-per-decile form (s).
constexpr double kLogHeartbeatS = 5.0;

}  // namespace

ProgressPrinter::ProgressPrinter(bool quiet)
    : quiet_(quiet),
      is_terminal_(isatty(STDERR_FILENO) != 0),
      start_(std::chrono::steady_clock::now()),
      last_print_(start_) {}

ProgressPrinter::~ProgressPrinter() { Finish(); }

ProgressCallback ProgressPrinter::callback() {
  return [this](double fraction, std::string_view stage) { Update(fraction, stage); };
}

void ProgressPrinter::Update(double fraction, std::string_view stage) {
  if (quiet_) return;
  const auto now = std::chrono::steady_clock::now();
  const double elapsed_s = std::chrono::duration<double>(now - start_).count();
  if (elapsed_s < 1.0) return;
  if (!std::isfinite(fraction)) fraction = 0.0;
  fraction = std::fmin(std::fmax(fraction, 0.0), 1.0);
  // The bar never goes back within a stage: estimates that move both ways would otherwise print a line at
  // every decile they cross, in either direction.
  if (stage != stage_) {
    stage_.assign(stage.data(), stage.size());
    shown_fraction_ = 0.0;
    last_decile_ = -1;
  }
  shown_fraction_ = fraction = std::fmax(fraction, shown_fraction_);
  const double left_s = fraction > 0.01 ? elapsed_s * (1.0 - fraction) / fraction : -1.0;
  char eta[32] = "";
  if (left_s >= 0) std::snprintf(eta, sizeof(eta), ", %.0f s left", left_s);
  if (is_terminal_) {
    if (std::chrono::duration<double>(now - last_print_).count() < 0.1 && shown_) return;
    last_print_ = now;
    const int width = 30;
    const int filled = static_cast<int>(fraction * width);
    std::fprintf(stderr, "\r%.*s [%-*s] %3.0f%% %.1f s%s   ", static_cast<int>(stage.size()), stage.data(), width,
                 std::string(static_cast<size_t>(filled), '#').c_str(), fraction * 100.0, elapsed_s, eta);
    shown_ = true;
  } else {
    const int decile = static_cast<int>(fraction * 10.0);
    const bool quiet_for_long = std::chrono::duration<double>(now - last_print_).count() >= kLogHeartbeatS;
    if (decile <= last_decile_ && !quiet_for_long) return;
    last_decile_ = std::max(decile, last_decile_);
    last_print_ = now;
    std::fprintf(stderr, "%.*s: %3.0f%% after %.1f s%s\n", static_cast<int>(stage.size()), stage.data(),
                 fraction * 100.0, elapsed_s, eta);
  }
  std::fflush(stderr);
}

void ProgressPrinter::Finish() {
  if (shown_ && is_terminal_) std::fprintf(stderr, "\n");
  shown_ = false;
}

void Notice(bool quiet, const std::string& line) {
  if (!quiet) std::fprintf(stderr, "rangebayes: %s\n", line.c_str());
}

}  // namespace rangebayes::apps
