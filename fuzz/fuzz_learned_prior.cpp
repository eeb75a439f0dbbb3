// libFuzzer entry for learned priors (ReadLearnedPrior, prior.yaml) and training-pair lists
// (ReadPairsList): any input reads or throws rangebayes::Error; a prior read has N finite knot values, a
// usable spline and a finite weight.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "bayes/learn_prior_io.h"
#include "core/error.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rangebayes;
  const std::string path =
      fuzz::WriteScratch("prior.yaml", std::string_view(reinterpret_cast<const char*>(data), size));
  try {
    const LearnedPrior prior = ReadLearnedPrior(path);
    prior.spline.Check();
    fuzz::Require(prior.theta.size() == prior.spline.num_knots, "theta has N values");
    fuzz::RequireFinite(prior.theta, "theta");
    fuzz::RequireFinite(prior.prior_weight, "prior_weight");
    fuzz::RequireFinite(prior.regularizer_weight, "regularizer_weight");
    fuzz::Require(prior.training_pairs >= 0, "training_pairs >= 0");
  } catch (const Error&) {
  }
  try {
    const PairsList list = ReadPairsList(path);
    fuzz::Require(!list.noisy.empty() && list.noisy.size() == list.truth.size(), "pairs come in pairs");
  } catch (const Error&) {
  }
  return 0;
}
