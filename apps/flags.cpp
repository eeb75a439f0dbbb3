#include "apps/flags.h"

#include <cmath>
#include <functional>
#include <limits>
#include <string>

#include "apps/command.h"
#include "bayes/learn_prior_io.h"
#include "core/error.h"
#include "stereo/sgbm_matcher.h"

namespace rangebayes::apps {

void AddQuietFlag(CLI::App* sub, bool* quiet) {
  sub->add_flag("--quiet,-q", *quiet, "No progress or notices on stderr");
}

void AddPriorWeightOption(CLI::App* sub, std::optional<double>* prior_weight) {
  sub->add_option("--prior-weight", *prior_weight,
                  "Smoothing prior weight beta (unitless, [0, 1e6]) at every pixel; meshes with pixel positions "
                  "and covariances (stereo) use beta / their pixel stride (at most 4); default: a learned prior's "
                  "own beta, else the library's measured default")
      ->check(RealRange(0.0, 1e6));
}

void AddPriorOption(CLI::App* sub, std::string* prior) {
  sub->add_option("--prior", *prior,
                  "Pairwise potential: sqrt (paper), quadratic, cauchy, or a learned prior FILE.yaml from "
                  "'rangebayes learn-prior' (its beta is used unless --prior-weight is given)")
      ->check([](const std::string& v) {
        return (v == "sqrt" || v == "quadratic" || v == "cauchy" || IsLearnedPriorFile(v))
                   ? std::string()
                   : std::string("expected sqrt, quadratic, cauchy or a .yaml learned prior");
      });
}

void AddToleranceOption(CLI::App* sub, std::string* tolerance) {
  sub->add_option("--tolerance", *tolerance, "Smoothing stopping preset: fast, default or tight")
      ->check(CLI::IsMember({"fast", "default", "tight"}));
}

Eigen::Vector3d ViewDirectionOption(const std::vector<double>& xyz) {
  if (xyz.size() != 3) UsageError("--view needs a nonzero, finite direction x y z");
  const Eigen::Vector3d d(xyz[0], xyz[1], xyz[2]);
  if (!d.allFinite() || !(d.stableNorm() > 0)) UsageError("--view needs a nonzero, finite direction x y z");
  return d;
}

void AddThreadsOption(CLI::App* sub, int* threads) {
  sub->add_option("--threads", *threads, "Worker threads (0: all cores)")
      ->check(CLI::Range(0, 1024));
}

namespace {

// A check of one value of type T (double or long long): empty string when it passes, else the message; text that
// is no T is "'TEXT' is not <what>".
template <typename T>
CLI::Validator ValueCheck(const std::string& description, const std::string& what,
                          const std::function<std::string(T)>& check) {
  return CLI::Validator(
      [check, what](std::string& text) -> std::string {
        T value = 0;
        if (!CLI::detail::lexical_cast(text, value)) return "'" + text + "' is not " + what;
        return check(value);
      },
      description);
}

CLI::Validator RealCheck(const std::string& description, const std::function<std::string(double)>& check) {
  return ValueCheck<double>(description, "a number", check);
}

CLI::Validator IntegerCheck(const std::string& description, const std::function<std::string(long long)>& check) {
  return ValueCheck<long long>(description, "an integer", check);
}

}  // namespace

void AddWindowOption(CLI::App* sub, int* window_px, const std::string& default_note, int min_px) {
  sub->add_option("--window", *window_px, "Matching window side (px, odd, 1-31; " + default_note + ")")
      ->check(CLI::Range(min_px, 31))
      ->check(IntegerCheck("", [](long long w) {
        return w == 0 || w % 2 == 1 ? std::string() : "must be odd, got " + std::to_string(w);
      }));
}

void CheckSgbmWindow(int window_px) {
  if (window_px > kSgbmMaxBlockSizePx) {
    UsageError(StrCat("--window: sgbm takes at most ", kSgbmMaxBlockSizePx, " px"));
  }
}

CLI::Validator PositiveReal() {
  return RealCheck("POSITIVE", [](double v) {
    return std::isfinite(v) && v > 0 ? std::string() : "must be a finite number > 0, got " + CLI::detail::to_string(v);
  });
}

CLI::Validator PositiveUpTo(double hi) {
  return RealCheck("(0, " + CLI::detail::to_string(hi) + "]", [hi](double v) {
    return v > 0 && v <= hi ? std::string()
                            : "must be in (0, " + CLI::detail::to_string(hi) + "], got " + CLI::detail::to_string(v);
  });
}

CLI::Validator PositiveOrInf() {
  return RealCheck("POSITIVE or inf", [](double v) {
    return v > 0 ? std::string() : "must be a number > 0 or inf, got " + CLI::detail::to_string(v);
  });
}

CLI::Validator NonNegativeReal() {
  return RealCheck("NONNEGATIVE", [](double v) {
    return std::isfinite(v) && v >= 0 ? std::string() : "must be a finite number >= 0, got " + CLI::detail::to_string(v);
  });
}

CLI::Validator RealRange(double lo, double hi) {
  const std::string range = "[" + CLI::detail::to_string(lo) + ", " + CLI::detail::to_string(hi) + "]";
  return RealCheck("REAL in " + range, [lo, hi, range](double v) {
    return v >= lo && v <= hi ? std::string() : "must be a number in " + range + ", got " + CLI::detail::to_string(v);
  });
}

CLI::Validator PositiveInteger() {
  return IntegerCheck("POSITIVE", [](long long v) {
    return v > 0 ? std::string() : "must be an integer > 0, got " + std::to_string(v);
  });
}

CLI::Validator NonNegativeInteger() {
  return IntegerCheck("NONNEGATIVE", [](long long v) {
    return v >= 0 ? std::string() : "must be an integer >= 0, got " + std::to_string(v);
  });
}

CLI::Validator CountOrAll() {
  return IntegerCheck("-1 or 1..2147483647", [](long long v) {
    return v == -1 || (v >= 1 && v <= std::numeric_limits<int>::max())
               ? std::string()
               : "must be -1 (all) or an integer in 1..2147483647, got " + std::to_string(v);
  });
}

}  // namespace rangebayes::apps
