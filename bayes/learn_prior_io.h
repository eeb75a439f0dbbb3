// prior.yaml: a learned spline potential and where it came from (what `rangebayes learn-prior` writes and
// `rangebayes smooth --prior` reads). A small YAML subset (one `key: value` per line, flow lists, quoted
// strings, # comments), written and read here so that bayes/ needs no YAML library.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bayes/smooth.h"
#include "bayes/spline_potential.h"

namespace rangebayes {

struct LearnedPrior {
  SplinePotentialOptions spline;  // N and ε² of the square-root base
  Eigen::VectorXd theta;          // N knot values φ(t_j), t_j = 2j/(N−1)
  double prior_weight = 0;        // β the potential was trained with (use the same β when smoothing); 0: not recorded
  std::string noise_kind;         // "normal", "scanner", or what the pairs list said; may be empty
  double noise_k = std::numeric_limits<double>::quiet_NaN();  // σ / l_e of the training noise; NaN: unknown
  // A mixture of levels: the training noise spans [noise_k, noise_k_max]; NaN: a single level.
  double noise_k_max = std::numeric_limits<double>::quiet_NaN();
  std::string training_set;  // the pairs list it was trained on
  int training_pairs = 0;
  std::string method;               // LearnPriorSummary::method: "none + bump search (filtering, 6 moves)"
  double regularizer_weight = 1.0;  // w
  double training_mse_le2 = std::numeric_limits<double>::quiet_NaN();  // D per vertex at the end
  std::string date;                                                    // UTC, ISO 8601
};

// Throws Error naming the file on I/O failure.
void WriteLearnedPrior(const LearnedPrior& prior, const std::string& path);
// Throws Error naming the file and line on a malformed file, a missing key, or θ that does not fit N
// (or whose ends are not the square root's).
LearnedPrior ReadLearnedPrior(const std::string& path);

// The prior weight β of a smoothing run, one rule for every command: an explicit value always wins; without
// one, a learned prior's own β (when it records one, > 0); otherwise SmoothOptions{}.prior_weight.
// learned may be null (no learned prior).
double ResolvePriorWeight(std::optional<double> explicit_prior_weight, const LearnedPrior* learned);

// True for a name that is a learned prior's file (.yaml or .yml), not a potential's name.
bool IsLearnedPriorFile(const std::string& name);

// The prior of a smoothing run by name, one rule for every entry point (`smooth --prior`, `replay`/`live --prior`,
// Python): "sqrt", "quadratic" or "cauchy" set options->prior; a learned prior's file sets options->potential to
// its spline (held by the result: keep it alive while the options are used). options->prior_weight then follows
// ResolvePriorWeight. Throws Error on another name or a bad file. (`replay --prior cauchy` was refused as a file.)
struct SmoothingPrior {
  std::optional<LearnedPrior> learned;               // when the name is a file
  std::shared_ptr<const SplinePotential> potential;  // its spline, which options->potential points at
};
SmoothingPrior ApplySmoothingPrior(const std::string& name, std::optional<double> explicit_prior_weight,
                                   SmoothOptions* options);

// A list of training pairs: one `NOISY GROUND_TRUTH` per line (paths without spaces, relative ones taken from
// the list's folder), blank lines and `#` comments skipped. A comment `# noise: KIND k=K` (what synth-meshes
// writes) records the noise the pairs carry; `# noise: KIND k=K k_max=KMAX` a mixture of levels in [K, KMAX]
// (the noisy meshes then carry their own covariances).
struct PairsList {
  std::vector<std::string> noisy;
  std::vector<std::string> truth;
  std::string noise_kind;                                         // empty when the list does not say
  double noise_k = std::numeric_limits<double>::quiet_NaN();      // NaN when the list does not say
  double noise_k_max = std::numeric_limits<double>::quiet_NaN();  // NaN unless a mixture of levels
};
// Throws Error naming the file and line on a malformed line or an empty list.
PairsList ReadPairsList(const std::string& path);
// Paths are written as given; a noise line is written when noise_kind is not empty.
void WritePairsList(const PairsList& list, const std::string& path);

// The current UTC time as 2026-11-22T03:04:05Z.
std::string UtcNowIso8601();

}  // namespace rangebayes
