// Chessboard calibration per corner detector: final stereo RMS and pairs used for the sector-based detector,
// the classic detector with cornerSubPix, and the default (kBest: both, the lower RMS kept), on every set
// given, and on derived versions of each set (half size; Gaussian blur σ 1.5 px; added noise σ 4 grey
// levels) that stand in for cameras we have no chessboard images of. BENCHMARKS.md has the command.
//
//   bench_calibration NAME:LEFT_GLOB:RIGHT_GLOB:COLSxROWS ...
#include <unistd.h>

#include <cstdio>
#include <exception>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <regex>
#include <stdexcept>
#include <string>
#include <vector>

#include "bench/bench_main.h"
#include "calibration/stereo_calibration.h"

namespace rb = rangebayes;
namespace fs = std::filesystem;

namespace {

// Writes each image of `pairs` transformed by `variant` into dir and returns the new pairs.
std::vector<rb::CalibrationImagePair> Derive(const std::vector<rb::CalibrationImagePair>& pairs,
                                             const std::string& variant, const fs::path& dir) {
  fs::create_directories(dir);
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 4.0f);
  auto convert = [&](const std::string& in) {
    cv::Mat img = cv::imread(in, cv::IMREAD_GRAYSCALE);
    if (variant == "half") cv::resize(img, img, cv::Size(), 0.5, 0.5, cv::INTER_AREA);
    if (variant == "blur") cv::GaussianBlur(img, img, cv::Size(0, 0), 1.5);
    if (variant == "noise") {
      cv::Mat f;
      img.convertTo(f, CV_32F);
      for (int y = 0; y < f.rows; ++y)
        for (int x = 0; x < f.cols; ++x) f.at<float>(y, x) += noise(rng);
      f.convertTo(img, CV_8U);
    }
    const fs::path out = dir / fs::path(in).filename().replace_extension(".png");
    cv::imwrite(out.string(), img);
    return out.string();
  };
  std::vector<rb::CalibrationImagePair> out;
  for (const auto& p : pairs) out.push_back({convert(p.left), convert(p.right)});
  return out;
}

}  // namespace

int RunBench(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: bench_calibration NAME:LEFT_GLOB:RIGHT_GLOB:COLSxROWS ...\n");
    return 2;
  }
  std::printf("%-24s %6s | %-16s | %-16s | %-22s\n", "set", "pairs", "sb rms (used)", "classic rms (used)",
              "default rms (kept)");
  int worse = 0, rows = 0;
  const fs::path tmp = fs::temp_directory_path() / ("bench_calibration_" + std::to_string(::getpid()));
  for (int a = 1; a < argc; ++a) {
    const std::string spec = argv[a];
    const size_t c1 = spec.find(':'), c2 = spec.find(':', c1 + 1), c3 = spec.rfind(':');
    if (c1 == std::string::npos || c2 == std::string::npos || c3 == c2 ||
        !std::regex_match(spec.substr(c3 + 1), std::regex("[0-9]{1,4}x[0-9]{1,4}"))) {
      throw std::invalid_argument("'" + spec + "' is not NAME:LEFT_GLOB:RIGHT_GLOB:COLSxROWS");
    }
    const std::string name = spec.substr(0, c1), left = spec.substr(c1 + 1, c2 - c1 - 1),
                      right = spec.substr(c2 + 1, c3 - c2 - 1), board = spec.substr(c3 + 1);
    const size_t x = board.find('x');
    rb::StereoCalibrationOptions options;
    options.board.cols = std::stoi(board.substr(0, x));
    options.board.rows = std::stoi(board.substr(x + 1));
    const std::vector<rb::CalibrationImagePair> base = rb::PairCalibrationImages({left}, {right});
    for (const std::string variant : {"original", "half", "blur", "noise"}) {
      const std::vector<rb::CalibrationImagePair> pairs =
          variant == std::string("original") ? base : Derive(base, variant, tmp / (name + "_" + variant));
      double rms[3] = {-1, -1, -1};
      int used[3] = {0, 0, 0};
      std::string kept;
      const rb::ChessboardDetector detectors[3] = {rb::ChessboardDetector::kSectorBased,
                                                   rb::ChessboardDetector::kClassic, rb::ChessboardDetector::kBest};
      for (int k = 0; k < 3; ++k) {
        rb::StereoCalibrationOptions o = options;
        o.board.detector = detectors[k];
        rb::StereoCalibrationSummary s;
        try {
          rb::CalibrateStereoRig(pairs, o, &s);
          rms[k] = s.rms_stereo_px;
          used[k] = s.pairs_used;
          if (k == 2) kept = s.detector_used == rb::ChessboardDetector::kClassic ? "classic" : "sb";
        } catch (const std::exception& e) {
          std::fprintf(stderr, "%s %s: %s\n", name.c_str(), variant.c_str(), e.what());
        }
      }
      ++rows;
      if (rms[1] >= 0 && !(rms[2] >= 0 && rms[2] <= rms[1] + 1e-12)) ++worse;
      const std::string label = name + (variant == std::string("original") ? "" : " (" + std::string(variant) + ")");
      std::printf("%-24s %6zu | %8.4f (%3d)   | %8.4f (%3d)    | %8.4f (%3d, %-7s)\n", label.c_str(), pairs.size(),
                  rms[0], used[0], rms[1], used[1], rms[2], used[2], kept.c_str());
      std::fflush(stdout);
    }
  }
  fs::remove_all(tmp);
  std::printf("default worse than classic + cornerSubPix on %d of %d sets\n", worse, rows);
  return 0;
}

// Bad input (a missing file, a wrong option or value) ends with one error line and exit code 1, not an abort.
int main(int argc, char** argv) { return rangebayes::bench::Main("bench_calibration", RunBench, argc, argv); }
