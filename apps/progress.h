// Progress on stderr for long runs: silent for the first second and when quiet, a single updating line on a
// terminal, and a line per 10% otherwise (logs stay short), or after 5 s without one (a log shows the run is
// alive while an estimate stands still). Within a stage the fraction shown never decreases.
#pragma once

#include <chrono>
#include <string>

#include "core/progress.h"

namespace rangebayes::apps {

class ProgressPrinter {
 public:
  explicit ProgressPrinter(bool quiet);
  ~ProgressPrinter();
  ProgressPrinter(const ProgressPrinter&) = delete;
  ProgressPrinter& operator=(const ProgressPrinter&) = delete;

  // The callback to hand to library code; valid while this printer lives.
  ProgressCallback callback();
  void Update(double fraction, std::string_view stage);
  // Ends the progress line (if one was shown).
  void Finish();

 private:
  bool quiet_;
  bool is_terminal_;
  bool shown_ = false;
  int last_decile_ = -1;
  std::string stage_;            // the stage of the last update
  double shown_fraction_ = 0.0;  // the largest fraction of that stage so far
  std::chrono::steady_clock::time_point start_;
  std::chrono::steady_clock::time_point last_print_;
};

// Prints a one-line notice to stderr unless quiet ("rangebayes: " prefix).
void Notice(bool quiet, const std::string& line);

}  // namespace rangebayes::apps
