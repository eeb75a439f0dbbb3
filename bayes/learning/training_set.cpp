#include "bayes/learning/training_set.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "bayes/noise_model.h"
#include "core/error.h"
#include "core/mesh_io.h"
#include "core/validate.h"

namespace rangebayes {

void TrainingSetOptions::Check() const {
  RB_CHECK(std::isnan(noise_k) || (noise_k > 0 && noise_k <= 5), "training set: noise k must be in (0, 5], got ",
           noise_k);
}

TrainingSet ReadTrainingSet(const std::string& pairs_list_path, const TrainingSetOptions& options) {
  options.Check();
  const PairsList list = ReadPairsList(pairs_list_path);
  const double k = !std::isnan(options.noise_k) ? options.noise_k : list.noise_k;
  RB_CHECK(std::isnan(k) || (k > 0 && k <= 5), pairs_list_path, ": its '# noise:' line gives k = ", k,
           ", outside (0, 5] (noise-free pairs teach nothing); give learn-prior --noise K");
  TrainingSet set;
  set.pairs_list = std::filesystem::absolute(pairs_list_path).lexically_normal().string();
  double k_used_sum = 0;
  int k_used_count = 0;
  for (size_t i = 0; i < list.noisy.size(); ++i) {
    TrainingPair pair;
    pair.name = list.noisy[i];
    pair.noisy = ReadNoisyMesh(list.noisy[i]);
    pair.truth = ReadMesh(list.truth[i]);
    RB_CHECK(SameConnectivity(pair.truth, pair.noisy.mesh), "pair ", i + 1, ": '", list.noisy[i], "' and '",
             list.truth[i], "' differ in vertices or faces");
    // The noisy mesh is checked by the smoother; a truth with a non-finite vertex made every loss NaN, written.
    CheckComputableScale(pair.truth.V, StrCat("pair ", i + 1, ": ", list.truth[i]));
    if (!pair.noisy.has_covariance()) {
      GenericNoiseOptions noise;
      if (!std::isnan(k)) noise.noise_edge_multiple = k;  // else estimated from the mesh
      GenericNoiseSummary noise_summary;
      pair.noisy = MakeGenericNoisyMesh(pair.noisy.mesh, noise, &noise_summary);
      k_used_sum += noise_summary.noise_edge_multiple;
      ++k_used_count;
    }
    set.pairs.push_back(std::move(pair));
    if (options.progress) options.progress(static_cast<double>(i + 1) / list.noisy.size(), "reading pairs");
  }
  set.noise_kind = list.noise_kind.empty() ? (k_used_count > 0 ? "generic" : "covariance") : list.noise_kind;
  set.noise_k = k_used_count > 0 ? k_used_sum / k_used_count : k;
  if (k_used_count == 0) set.noise_k_max = list.noise_k_max;
  return set;
}

LearnedPrior MakeLearnedPrior(const TrainingSet& set, const LearnPriorOptions& options, const Eigen::VectorXd& theta,
                              const LearnPriorSummary& summary) {
  LearnedPrior prior;
  prior.spline = options.spline;
  prior.theta = theta;
  prior.prior_weight = options.prior_weight;
  prior.noise_kind = set.noise_kind;
  prior.noise_k = set.noise_k;
  prior.noise_k_max = set.noise_k_max;
  prior.training_set = set.pairs_list;
  prior.training_pairs = static_cast<int>(set.pairs.size());
  prior.method = summary.method;
  prior.regularizer_weight = options.regularizer_weight;
  prior.training_mse_le2 = summary.final_data_loss / std::max(1, summary.num_vertices);
  prior.date = UtcNowIso8601();
  return prior;
}

}  // namespace rangebayes
