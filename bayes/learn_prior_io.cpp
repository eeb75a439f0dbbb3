#include "bayes/learn_prior_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>
#include <vector>

#include "bayes/smooth.h"
#include "core/error.h"
#include "core/files.h"

namespace rangebayes {
namespace {

std::string Quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

std::string Number(double value) {
  if (std::isnan(value)) return ".nan";
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.17g", value);
  return buffer;
}

std::string Trim(const std::string& s) {
  size_t b = 0, e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return s.substr(b, e - b);
}

struct Value {
  std::string text;
  int line = 0;
};

}  // namespace

std::string UtcNowIso8601() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char buffer[32];
  std::strftime(buffer, sizeof(buffer), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return buffer;
}

void WriteLearnedPrior(const LearnedPrior& prior, const std::string& path) {
  SplinePotential(prior.spline, prior.theta);  // validates N, ε² and the clamped ends
  std::ostringstream out;
  out << "# rangebayes learned prior: cubic spline potential phi(d) over d = |n_s - n_t| in [0, 2] (paper section 5).\n"
      << "# phi(d) = sqrt(d^2 + epsilon_squared) + S(d), S the clamped cubic spline through theta_j - sqrt(t_j^2 + eps2)\n"
      << "# at t_j = 2 j / (num_knots - 1); theta_j is phi at knot j, the first and last are the square root's.\n"
      << "format: rangebayes-learned-prior-1\n"
      << "num_knots: " << prior.spline.num_knots << "\n"
      << "epsilon_squared: " << Number(prior.spline.epsilon_squared) << "\n"
      << "theta: [";
  for (Eigen::Index j = 0; j < prior.theta.size(); ++j) out << (j > 0 ? ", " : "") << Number(prior.theta[j]);
  out << "]\n"
      << "prior_weight: " << Number(prior.prior_weight) << "\n"
      << "noise_kind: " << Quote(prior.noise_kind) << "\n"
      << "noise_k: " << Number(prior.noise_k) << "\n";
  if (std::isfinite(prior.noise_k_max)) out << "noise_k_max: " << Number(prior.noise_k_max) << "\n";
  out
      << "training_set: " << Quote(prior.training_set) << "\n"
      << "training_pairs: " << prior.training_pairs << "\n"
      << "method: " << Quote(prior.method) << "\n"
      << "regularizer_weight: " << Number(prior.regularizer_weight) << "\n"
      << "training_mse_le2: " << Number(prior.training_mse_le2) << "\n"
      << "date: " << Quote(prior.date) << "\n";
  WriteFileAtomically(path, out.str());
}

LearnedPrior ReadLearnedPrior(const std::string& path) {
  std::ifstream in(path);
  RB_CHECK(in.good(), "cannot open learned prior '", path, "'");
  std::map<std::string, Value> values;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const std::string trimmed = Trim(line);
    if (trimmed.empty() || trimmed[0] == '#') continue;
    const size_t colon = trimmed.find(':');
    RB_CHECK(colon != std::string::npos && colon > 0, path, ":", number, ": expected 'key: value'");
    values[Trim(trimmed.substr(0, colon))] = Value{Trim(trimmed.substr(colon + 1)), number};
  }
  auto get = [&](const std::string& key) -> const Value& {
    auto it = values.find(key);
    RB_CHECK(it != values.end(), path, ": missing key '", key, "'");
    return it->second;
  };
  auto number_of = [&](const std::string& key, const std::string& text, int at) {
    if (text == ".nan" || text == "nan") return std::numeric_limits<double>::quiet_NaN();
    size_t used = 0;
    double v = 0;
    try {
      v = std::stod(text, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    RB_CHECK(used == text.size() && used > 0, path, ":", at, ": '", key, "' is not a number: '", text, "'");
    return v;
  };
  auto real = [&](const std::string& key) {
    const Value& v = get(key);
    return number_of(key, v.text, v.line);
  };
  auto text = [&](const std::string& key) -> std::string {
    auto it = values.find(key);
    if (it == values.end()) return "";
    std::string s = it->second.text;
    if (s.size() >= 2 && s.front() == '"' && s.back() == '"') {
      std::string out;
      for (size_t i = 1; i + 1 < s.size(); ++i) {
        if (s[i] == '\\' && i + 2 < s.size()) ++i;
        out += s[i];
      }
      return out;
    }
    return s;
  };
  RB_CHECK(text("format") == "rangebayes-learned-prior-1", path, ": not a rangebayes learned prior (format '",
           text("format"), "')");
  LearnedPrior prior;
  const double knots = real("num_knots");
  RB_CHECK(knots == std::floor(knots) && knots >= 3 && knots <= 256, path, ":", get("num_knots").line,
           ": num_knots must be an integer in [3, 256]");
  prior.spline.num_knots = static_cast<int>(knots);
  prior.spline.epsilon_squared = real("epsilon_squared");
  const Value& theta = get("theta");
  RB_CHECK(theta.text.size() >= 2 && theta.text.front() == '[' && theta.text.back() == ']', path, ":", theta.line,
           ": theta must be a list [a, b, ...]");
  std::vector<double> list;
  std::stringstream items(theta.text.substr(1, theta.text.size() - 2));
  std::string item;
  while (std::getline(items, item, ',')) list.push_back(number_of("theta", Trim(item), theta.line));
  // getline drops an empty last item ("[a, b,]"): as many items as commas + 1.
  RB_CHECK(static_cast<size_t>(std::count(theta.text.begin(), theta.text.end(), ',')) + 1 == list.size(), path, ":",
           theta.line, ": theta has an empty item");
  RB_CHECK(static_cast<int>(list.size()) == prior.spline.num_knots, path, ":", theta.line, ": theta has ", list.size(),
           " values, num_knots is ", prior.spline.num_knots);
  prior.theta = Eigen::Map<const Eigen::VectorXd>(list.data(), static_cast<Eigen::Index>(list.size()));
  try {
    SplinePotential(prior.spline, prior.theta);
  } catch (const Error& e) {
    RB_FAIL(path, ": ", e.what());
  }
  if (values.count("prior_weight")) prior.prior_weight = real("prior_weight");
  RB_CHECK(prior.prior_weight >= 0 && std::isfinite(prior.prior_weight), path, ": prior_weight must be finite and non-negative");
  prior.noise_kind = text("noise_kind");
  // The record's numbers: finite and non-negative, or .nan where the writer records "unknown".
  auto record = [&](const std::string& key, bool nan_allowed) {
    const double v = real(key);
    RB_CHECK((nan_allowed && std::isnan(v)) || (std::isfinite(v) && v >= 0), path, ":", get(key).line, ": '", key,
             "' must be finite and non-negative", nan_allowed ? " (or .nan)" : "", ", not ", get(key).text);
    return v;
  };
  if (values.count("noise_k")) prior.noise_k = record("noise_k", true);
  if (values.count("noise_k_max")) prior.noise_k_max = record("noise_k_max", true);
  prior.training_set = text("training_set");
  if (values.count("training_pairs")) {
    const double pairs = record("training_pairs", false);
    RB_CHECK(pairs == std::floor(pairs) && pairs <= std::numeric_limits<int>::max(), path, ":",
             get("training_pairs").line, ": 'training_pairs' must be a whole number");
    prior.training_pairs = static_cast<int>(pairs);
  }
  prior.method = text("method");
  if (values.count("regularizer_weight")) prior.regularizer_weight = record("regularizer_weight", false);
  if (values.count("training_mse_le2")) prior.training_mse_le2 = record("training_mse_le2", true);
  prior.date = text("date");
  return prior;
}

PairsList ReadPairsList(const std::string& path) {
  std::ifstream in(path);
  RB_CHECK(in.good(), "cannot open pairs list '", path, "'");
  const size_t slash = path.find_last_of('/');
  const std::string folder = slash == std::string::npos ? "" : path.substr(0, slash + 1);
  auto resolve = [&](const std::string& p) { return (p.empty() || p[0] == '/') ? p : folder + p; };
  PairsList list;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const std::string trimmed = Trim(line);
    if (trimmed.empty()) continue;
    if (trimmed[0] == '#') {
      std::istringstream comment(trimmed.substr(1));
      std::string key, kind, k, k_max;
      comment >> key >> kind >> k >> k_max;
      if (key == "noise:" && !kind.empty()) {
        list.noise_kind = kind;
        if (k.rfind("k=", 0) == 0) {
          try {
            list.noise_k = std::stod(k.substr(2));
          } catch (const std::exception&) {
            RB_FAIL(path, ":", number, ": bad noise level '", k, "'");
          }
        }
        if (k_max.rfind("k_max=", 0) == 0) {
          try {
            list.noise_k_max = std::stod(k_max.substr(6));
          } catch (const std::exception&) {
            RB_FAIL(path, ":", number, ": bad noise level '", k_max, "'");
          }
        }
      }
      continue;
    }
    std::istringstream fields(trimmed);
    std::string noisy, truth, extra;
    fields >> noisy >> truth >> extra;
    RB_CHECK(!noisy.empty() && !truth.empty() && extra.empty(), path, ":", number,
             ": expected 'NOISY GROUND_TRUTH', got '", trimmed, "'");
    list.noisy.push_back(resolve(noisy));
    list.truth.push_back(resolve(truth));
  }
  RB_CHECK(!list.noisy.empty(), "pairs list '", path, "' has no pairs");
  return list;
}

void WritePairsList(const PairsList& list, const std::string& path) {
  std::ofstream out(path);
  RB_CHECK(out.good(), "cannot write pairs list '", path, "'");
  out << "# NOISY GROUND_TRUTH (paths relative to this file)\n";
  if (!list.noise_kind.empty()) {
    out << "# noise: " << list.noise_kind << " k=" << Number(list.noise_k);
    if (std::isfinite(list.noise_k_max)) out << " k_max=" << Number(list.noise_k_max);
    out << "\n";
  }
  for (size_t i = 0; i < list.noisy.size(); ++i) out << list.noisy[i] << " " << list.truth[i] << "\n";
  out.close();
  RB_CHECK(!out.fail(), "cannot write pairs list '", path, "'");
}

double ResolvePriorWeight(std::optional<double> explicit_prior_weight, const LearnedPrior* learned) {
  if (explicit_prior_weight.has_value()) return *explicit_prior_weight;
  if (learned != nullptr && learned->prior_weight > 0) return learned->prior_weight;
  return SmoothOptions{}.prior_weight;
}

bool IsLearnedPriorFile(const std::string& name) {
  const auto ends = [&](const std::string& suffix) {
    return name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
  };
  return ends(".yaml") || ends(".yml");
}

SmoothingPrior ApplySmoothingPrior(const std::string& name, std::optional<double> explicit_prior_weight,
                                   SmoothOptions* options) {
  SmoothingPrior result;
  if (IsLearnedPriorFile(name)) {
    result.learned = ReadLearnedPrior(name);
    result.potential = std::make_shared<const SplinePotential>(result.learned->spline, result.learned->theta);
    options->potential = result.potential.get();
  } else {
    options->prior = ParsePriorKind(name);
    options->potential = nullptr;
  }
  options->prior_weight = ResolvePriorWeight(explicit_prior_weight, result.learned ? &*result.learned : nullptr);
  return result;
}

}  // namespace rangebayes
