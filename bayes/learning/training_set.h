// A training set for LearnPrior read from a pairs list (bayes/learn_prior_io.h: what `rangebayes synth-meshes`
// writes), and the prior.yaml record of a training run: what `rangebayes learn-prior` does around LearnPrior.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

#include "bayes/learn_prior_io.h"
#include "bayes/learning/learn_prior.h"
#include "core/progress.h"

namespace rangebayes {

struct TrainingSetOptions {
  // σ / l_e of the noisy meshes that carry no covariance (they get the generic model of bayes/noise_model.h);
  // NaN: the pairs list's `# noise:` line, else estimated per mesh. (0, 5] or NaN.
  double noise_k = std::numeric_limits<double>::quiet_NaN();
  ProgressCallback progress;  // once per pair read
  void Check() const;
};

struct TrainingSet {
  std::string pairs_list;  // the list's path, absolute and normalised
  std::vector<TrainingPair> pairs;
  // The training noise as prior.yaml records it: the list's kind, else "generic" (covariances built here) or
  // "covariance" (every noisy mesh carried its own); k the mean k used for the generic model, else the list's;
  // k_max the list's (a mixture) when every mesh carried its covariance, else NaN.
  std::string noise_kind;
  double noise_k = std::numeric_limits<double>::quiet_NaN();
  double noise_k_max = std::numeric_limits<double>::quiet_NaN();
};

// Reads every pair of the list (noisy mesh with or without covariance, ground truth). Throws Error naming the
// file on an unreadable list or mesh, or a pair whose two meshes differ in vertex count or faces.
TrainingSet ReadTrainingSet(const std::string& pairs_list_path, const TrainingSetOptions& options = {});

// The prior.yaml record of θ learned on `set` with `options` (`summary` from that LearnPrior call), dated now.
LearnedPrior MakeLearnedPrior(const TrainingSet& set, const LearnPriorOptions& options, const Eigen::VectorXd& theta,
                              const LearnPriorSummary& summary);

}  // namespace rangebayes
