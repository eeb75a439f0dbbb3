#include "bayes/learn_prior_io.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <tuple>
#include <vector>

#include "bayes/smooth.h"
#include "core/error.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

TEST(LearnPriorIo, RoundTrip) {
  LearnedPrior prior;
  prior.spline.num_knots = 6;
  prior.theta = SplinePotential::SquareRootTheta(prior.spline);
  prior.theta[2] += 0.125;
  prior.noise_kind = "normal";
  prior.noise_k = 0.3;
  prior.training_set = "/data/with \"quotes\"/train_pairs.txt";
  prior.training_pairs = 8;
  prior.method = "interleaved";
  prior.date = UtcNowIso8601();
  const std::string path = TempPath("prior.yaml");
  WriteLearnedPrior(prior, path);
  const LearnedPrior read = ReadLearnedPrior(path);
  EXPECT_EQ(read.spline.num_knots, 6);
  EXPECT_EQ(read.theta, prior.theta);  // %.17g round-trips doubles exactly
  EXPECT_EQ(read.noise_kind, "normal");
  EXPECT_EQ(read.noise_k, 0.3);
  EXPECT_EQ(read.training_set, prior.training_set);
  EXPECT_EQ(read.training_pairs, 8);
  EXPECT_EQ(read.date, prior.date);
  EXPECT_TRUE(std::isnan(read.training_mse_le2));
  EXPECT_TRUE(std::isnan(read.noise_k_max));  // a single level: not written
  prior.noise_k_max = 0.5;
  WriteLearnedPrior(prior, path);
  EXPECT_EQ(ReadLearnedPrior(path).noise_k_max, 0.5);
  std::remove(path.c_str());
}

TEST(LearnPriorIo, RejectsBrokenFiles) {
  const std::string path = TempPath("broken.yaml");
  {
    std::ofstream out(path);
    out << "format: rangebayes-learned-prior-1\nnum_knots: 4\nepsilon_squared: 0.0001\ntheta: [0.01, 0.5, 1.0]\n";
  }
  EXPECT_THROW(ReadLearnedPrior(path), Error);  // 3 values for 4 knots
  {
    std::ofstream out(path);
    out << "format: rangebayes-learned-prior-1\nnum_knots: 3\nepsilon_squared: 0.0001\ntheta: [0.5, 1.0, 2.0]\n";
  }
  EXPECT_THROW(ReadLearnedPrior(path), Error);  // ends not the square root's
  {
    std::ofstream out(path);
    out << "something else\n";
  }
  EXPECT_THROW(ReadLearnedPrior(path), Error);
  EXPECT_THROW(ReadLearnedPrior(TempPath("does_not_exist.yaml")), Error);
  // The record's numbers: a count that is not a whole number in range (NaN was cast to int), weights that are not
  // finite, an empty item at the end of theta; each refused naming its key.
  LearnedPrior good;
  good.spline.num_knots = 4;
  good.theta = SplinePotential::SquareRootTheta(good.spline);
  WriteLearnedPrior(good, path);
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  in.close();
  ASSERT_NO_THROW(ReadLearnedPrior(path));
  const auto with = [&](const std::string& key, const std::string& value) {
    std::string edited = text;
    const size_t at = edited.find("\n" + key + ": ");
    EXPECT_NE(at, std::string::npos) << key;
    const size_t end = edited.find('\n', at + 1);
    edited.replace(at + 1, end - at - 1, key + ": " + value);
    std::ofstream(path, std::ios::trunc) << edited;
  };
  for (const auto& [key, value, what] : std::vector<std::tuple<std::string, std::string, std::string>>{
           {"training_pairs", ".nan", "'training_pairs' must be finite"},
           {"training_pairs", "1e30", "'training_pairs' must be a whole number"},
           {"training_pairs", "-3.7", "'training_pairs' must be finite and non-negative"},
           {"regularizer_weight", "nan", "'regularizer_weight' must be finite"},
           {"noise_k", "-inf", "'noise_k' must be finite and non-negative (or .nan)"}}) {
    with(key, value);
    try {
      ReadLearnedPrior(path);
      ADD_FAILURE() << key << ": " << value << " accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  }
  std::string trailing = text;
  trailing.replace(trailing.find("]\n"), 2, ",]\n");
  std::ofstream(path, std::ios::trunc) << trailing;
  try {
    ReadLearnedPrior(path);
    ADD_FAILURE() << "a trailing comma in theta accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("theta has an empty item"), std::string::npos) << e.what();
  }
  std::remove(path.c_str());
}

TEST(LearnPriorIo, PairsListResolvesRelativePaths) {
  const std::string path = TempPath("pairs.txt");
  PairsList list;
  list.noisy = {"a_noisy.ply", "/abs/b_noisy.ply"};
  list.truth = {"a_gt.ply", "/abs/b_gt.ply"};
  list.noise_kind = "scanner";
  list.noise_k = 0.5;
  WritePairsList(list, path);
  const PairsList read = ReadPairsList(path);
  const std::string folder = std::filesystem::path(path).parent_path().string() + "/";
  ASSERT_EQ(read.noisy.size(), 2u);
  EXPECT_EQ(read.noisy[0], folder + "a_noisy.ply");
  EXPECT_EQ(read.truth[1], "/abs/b_gt.ply");
  EXPECT_EQ(read.noise_kind, "scanner");
  EXPECT_EQ(read.noise_k, 0.5);
  EXPECT_TRUE(std::isnan(read.noise_k_max));
  list.noise_k_max = 0.75;  // a mixture of levels
  WritePairsList(list, path);
  EXPECT_EQ(ReadPairsList(path).noise_k_max, 0.75);
  EXPECT_EQ(ReadPairsList(path).noise_k, 0.5);
  {
    std::ofstream out(path);
    out << "only_one_path.ply\n";
  }
  EXPECT_THROW(ReadPairsList(path), Error);
  std::remove(path.c_str());
}

// One rule for smooth, live, replay and Python: an explicit beta always wins, even when it equals the
// default; else the learned prior's own; else the library default.
TEST(ResolvePriorWeight, ExplicitWinsThenLearnedThenDefault) {
  const double def = SmoothOptions{}.prior_weight;
  LearnedPrior learned;
  learned.prior_weight = 1.3;
  EXPECT_EQ(ResolvePriorWeight(def, &learned), def);
  EXPECT_EQ(ResolvePriorWeight(0.7, &learned), 0.7);
  EXPECT_EQ(ResolvePriorWeight(std::nullopt, &learned), 1.3);
  learned.prior_weight = 0;  // not recorded
  EXPECT_EQ(ResolvePriorWeight(std::nullopt, &learned), def);
  EXPECT_EQ(ResolvePriorWeight(std::nullopt, nullptr), def);
  EXPECT_EQ(ResolvePriorWeight(0.5, nullptr), 0.5);
}

}  // namespace
}  // namespace rangebayes
