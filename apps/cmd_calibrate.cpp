// `rangebayes calibrate ...`: the stereo rig from board images, and (see below) the disparity noise model.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <regex>
#include <string>
#include <vector>

#include "apps/command.h"
#include "apps/flags.h"
#include "apps/progress.h"
#include "calibration/disparity_noise_model.h"
#include "calibration/middlebury.h"
#include "calibration/stereo_calibration.h"
#include "calibration/stereo_rig.h"
#include "capture/recording.h"
#include "core/error.h"
#include "core/files.h"
#include "pipeline/png.h"
#include "stereo/noise_calibration.h"
#include "stereo/noise_report.h"

namespace rangebayes::apps {
namespace {

struct RigArgs {
  std::vector<std::string> left;
  std::vector<std::string> right;
  std::string board = "9x6";
  double square_m = 0.025;
  bool charuco = false;
  double marker_m = 0.0;
  std::string dictionary = "DICT_4X4_50";
  std::string detector = "best";
  bool accurate = false;
  int min_pairs = 5;
  bool drop_outliers = false;
  bool rational = false;
  double max_rms_px = StereoCalibrationOptions{}.max_rms_px;
  std::string out;
  std::string png;
  bool quiet = false;
};

void ParseBoardSize(const std::string& text, BoardSpec* board) {
  static const std::regex re("([0-9]+)[xX]([0-9]+)");
  std::smatch m;
  if (!std::regex_match(text, m, re)) UsageError("--board '" + text + "' is not COLSxROWS (e.g. 9x6)");
  board->cols = std::stoi(m[1]);
  board->rows = std::stoi(m[2]);
}

void RunRig(const RigArgs& a) {
  StereoCalibrationOptions options;
  ParseBoardSize(a.board, &options.board);
  options.board.square_m = a.square_m;
  options.board.marker_m = a.marker_m;
  options.board.dictionary = a.dictionary;
  options.board.detector = a.detector == "classic" ? ChessboardDetector::kClassic
                           : a.detector == "sb"     ? ChessboardDetector::kSectorBased
                                                    : ChessboardDetector::kBest;
  options.board.accurate_corners = a.accurate;
  if (a.charuco) {
    if (!CharucoAvailable()) {
      RB_FAIL("--charuco needs OpenCV's aruco module (Debian package libopencv-contrib-dev), which this build lacks");
    }
    options.board.type = BoardType::kCharuco;
  }
  options.min_pairs = a.min_pairs;
  options.drop_outliers = a.drop_outliers;
  options.rational_model = a.rational;
  options.max_rms_px = a.max_rms_px;
  options.Check();
  CheckFileToWrite(a.out);
  if (!a.png.empty()) CheckFileToWrite(a.png);

  std::vector<std::string> unpaired;
  const std::vector<CalibrationImagePair> pairs = PairCalibrationImages(a.left, a.right, &unpaired);
  for (const std::string& u : unpaired) Notice(a.quiet, "no partner image for " + u + " (skipped)");

  StereoCalibrationSummary s;
  StereoRig rig;
  {
    ProgressPrinter progress(a.quiet);
    rig = CalibrateStereoRig(pairs, options, &s, progress.callback());
    progress.Finish();
  }
  std::fputs(s.BriefReport().c_str(), stdout);
  std::printf("baseline %.4f m, rectified f %.1f px\n", rig.baseline_m(), rig.P1(0, 0));
  // A rig that cannot work is not written (a --rational fit once wrote one of stereo RMS 2e10 px, exit 0).
  const std::string problem = CalibrationProblem(s, options);
  RB_CHECK(problem.empty(), problem, "; ", a.out, " not written");
  WriteStereoRig(rig, a.out);
  int flagged = 0;
  for (const CalibrationView& v : s.views) flagged += v.flagged;
  if (flagged > 0 && !a.drop_outliers) std::printf("rerun with --drop-outliers to calibrate without them\n");
  std::printf("wrote %s\n", a.out.c_str());
  if (!a.png.empty()) {
    for (const CalibrationView& v : s.views) {
      if (!v.used) continue;
      WritePng(RenderRectifiedPair(rig, {v.left, v.right}), a.png);
      std::printf("wrote %s (rectified %s with epipolar lines)\n", a.png.c_str(),
                  std::filesystem::path(v.left).filename().string().c_str());
      break;
    }
  }
}

void AddRig(CLI::App* calibrate) {
  auto a = std::make_shared<RigArgs>();
  CLI::App* sub = calibrate->add_subcommand(
      "rig", "Calibrate a stereo rig from board image pairs: intrinsics, extrinsics, rectification -> rig.yaml");
  sub->add_option("--left", a->left,
                  "Left images: glob pattern(s) such as 'DIR/left*.jpg' (quote them) or file names; paired with "
                  "--right by the last number in the file name, else by sorted order")
      ->required();
  sub->add_option("--right", a->right, "Right images: glob pattern(s) or file names")->required();
  sub->add_option("--board", a->board,
                  "Board size COLSxROWS: inner corners for a chessboard, squares for a ChArUco board");
  sub->add_option("--square", a->square_m, "Board square side in metres (sets the unit of the baseline)")
      ->check(PositiveReal());
  sub->add_flag("--charuco", a->charuco, "The board is a ChArUco board (needs OpenCV's aruco module)");
  sub->add_option("--marker", a->marker_m, "ChArUco marker side in metres; 0 = 0.75 x square");
  sub->add_option("--dictionary", a->dictionary, "ChArUco dictionary (OpenCV name)");
  sub->add_option("--detector", a->detector,
                  "Chessboard corner detector: best (calibrate with both, keep the lower stereo RMS), sb "
                  "(findChessboardCornersSB) or classic (findChessboardCorners + cornerSubPix)")
      ->check(CLI::IsMember({"best", "sb", "classic"}));
  sub->add_flag("--accurate", a->accurate, "Sector-based detector with CALIB_CB_ACCURACY (about 4x slower)");
  sub->add_option("--min-pairs", a->min_pairs, "Fewest usable pairs (board found in both images)")
      ->check(CLI::Range(3, 10000));
  sub->add_flag("--drop-outliers", a->drop_outliers,
                "Recalibrate without the flagged views (stereo RMS above max(median + 3 x 1.4826 x MAD, 1.5 x "
                "median))");
  sub->add_flag("--rational", a->rational, "8-coefficient rational distortion model (needs many views)");
  sub->add_option("--max-rms", a->max_rms_px,
                  "Refuse (and write nothing) when the stereo RMS or the mean rectified epipolar error is above "
                  "this, px (inf: no limit)")
      ->check(PositiveOrInf());
  sub->add_option("--out,-o", a->out, "Output rig file (OpenCV FileStorage YAML)")->required();
  sub->add_option("--png", a->png, "Write the first used pair, rectified, with horizontal epipolar lines");
  AddQuietFlag(sub, &a->quiet);
  sub->callback([a] { RunRig(*a); });
}

struct NoiseArgs {
  std::vector<std::string> inputs;
  std::string rig;
  std::string target = "plane";
  std::string out;
  std::string matcher;  // empty: the target's default (plane: block; ground-truth: the library's, sgbm)
  std::string form = "auto";
  int frame = 0;
  int frames = 0;
  int min_disparity_px = 0;
  int num_disparities = 64;
  int window_px = 0;  // 0: the matcher's (the library's default)
  double image_noise_gray = 2.0;
  std::vector<int> roi;
  int stride_px = 1;
  std::string png;
  bool quiet = false;
};

void RunNoiseFromGroundTruth(const NoiseArgs& a, const CLI::App& sub) {
  for (const char* plane_only : {"--rig", "--frame", "--frames", "--min-disparity", "--num-disparities", "--roi"}) {
    if (sub.count(plane_only) > 0) {
      UsageError(std::string(plane_only) + " applies to --target plane (ground truth gives each scene's range)");
    }
  }
  if (!a.matcher.empty() && a.matcher != "sgbm" && a.matcher != "block") {
    UsageError("--target ground-truth: --matcher must be sgbm or block");
  }
  if (a.form != "auto" && a.form != "learned") UsageError("--target ground-truth fits the learned form only");
  if (!a.png.empty()) UsageError("--png draws the plane target's report; --target ground-truth prints its own");
  CheckFileToWrite(a.out);
  GroundTruthNoiseOptions options;
  if (!a.matcher.empty()) options.matcher = ParseNoiseCalibrationMatcher(a.matcher);
  if (a.window_px > 0) options.window_px = a.window_px;
  options.image_noise_gray = a.image_noise_gray;
  options.stride_px = a.stride_px;
  GroundTruthNoiseSummary summary;
  ProgressPrinter progress(a.quiet);
  options.progress = progress.callback();
  const DisparityNoiseModel model = CalibrateDisparityNoiseFromGroundTruth(a.inputs, options, &summary);
  progress.Finish();
  WriteDisparityNoiseModel(model, a.out);
  std::fputs(summary.BriefReport(model).c_str(), stdout);
  std::printf("wrote %s (%s, %d samples)\n", a.out.c_str(), NoiseFormName(model.form), model.samples);
}

void RunNoise(const NoiseArgs& a, const CLI::App& sub) {
  if (a.target == "ground-truth") return RunNoiseFromGroundTruth(a, sub);
  if (a.inputs.size() != 1) UsageError("--target plane takes one recording");
  NoiseCalibrationOptions options;
  if (!a.matcher.empty()) options.matcher = ParseNoiseCalibrationMatcher(a.matcher);
  if (a.form != "auto") options.form = ParseNoiseForm(a.form);
  if (options.form == NoiseForm::kFloorPlusScale && options.matcher == NoiseCalibrationMatcher::kSgbm) {
    UsageError("--form floor-plus-scale needs a matcher that predicts sigma_d (block or spacetime), not sgbm");
  }
  // The single-frame matchers read one frame (--frames was read and ignored with them).
  if (sub.count("--frames") > 0 && options.matcher != NoiseCalibrationMatcher::kSpaceTime) {
    UsageError("--frames applies to --matcher spacetime (block and sgbm match one frame: --frame)");
  }
  options.first_frame = a.frame;
  options.frames = a.frames;
  options.min_disparity_px = a.min_disparity_px;
  options.num_disparities = a.num_disparities;
  options.window_px = a.window_px;
  options.image_noise_gray = a.image_noise_gray;
  if (!a.roi.empty()) {
    if (a.roi.size() != 4) UsageError("--roi takes four numbers: x y width height");
    options.roi = cv::Rect(a.roi[0], a.roi[1], a.roi[2], a.roi[3]);
  }
  options.stride_px = a.stride_px;
  CheckFileToWrite(a.out);
  if (!a.png.empty()) CheckFileToWrite(a.png);

  RecordingReadSummary read_summary;
  const std::string& recording = a.inputs[0];
  const Recording rec = OpenRecording(recording, &read_summary);
  for (const std::string& n : read_summary.notices) Notice(a.quiet, n);
  StereoRig rig;
  if (!a.rig.empty()) {
    rig = ReadStereoRig(a.rig);
  } else {
    RB_CHECK(rec.rig.has_value(), recording, ": recording has no rig.yaml; give --rig");
    rig = *rec.rig;
  }
  RB_CHECK(a.frame >= 0 && a.frame < rec.num_frames(), recording, ": frame ", a.frame, " not in [0, ",
           rec.num_frames(), ")");
  NoiseCalibrationSummary summary;
  const DisparityNoiseModel model = CalibrateDisparityNoise(rec, rig, options, &summary);
  WriteDisparityNoiseModel(model, a.out);
  std::fputs(summary.BriefReport(model).c_str(), stdout);
  for (const std::string& notice : summary.notices) Notice(a.quiet, notice);
  std::printf("wrote %s (%s, %d samples)\n", a.out.c_str(), NoiseFormName(model.form), model.samples);
  if (!a.png.empty()) {
    WritePng(NoiseReportFigure(summary.samples, model, summary.fit), a.png);
    std::printf("wrote %s\n", a.png.c_str());
  }
}

void AddNoise(CLI::App* calibrate) {
  auto a = std::make_shared<NoiseArgs>();
  CLI::App* sub = calibrate->add_subcommand(
      "noise",
      "Fit the disparity noise model (noise.yaml) from a recording of a known target (one plane) or from scenes "
      "with ground-truth disparity (learned form)");
  sub->add_option("INPUT", a->inputs,
                  "plane: the recording folder (frames.csv, rig.yaml); ground-truth: Middlebury scene folders")
      ->required();
  sub->add_option("--rig", a->rig, "Rig file; default: the recording's rig.yaml");
  sub->add_option("--target", a->target,
                  "plane (a recording of one plane) or ground-truth (scenes with ground-truth disparity: fits "
                  "sigma_d from cost curvature and neighbour jump, plus the outlier share, for sgbm or block)")
      ->check(CLI::IsMember({"plane", "ground-truth"}));
  sub->add_option("--out,-o", a->out, "Output noise model (OpenCV FileStorage YAML)")->required();
  sub->add_option("--matcher", a->matcher,
                  "block (single frame, predicts sigma_d), spacetime (all frames from --frame, predicts sigma_d) or "
                  "sgbm (single frame, no prediction); default: block for a plane, sgbm (the matcher of `stereo`) for "
                  "ground truth")
      ->check(CLI::IsMember({"block", "spacetime", "sgbm"}));
  sub->add_option(
         "--form", a->form,
         "Model form: auto (plane: floor-plus-scale when the matcher predicts sigma_d; ground-truth: learned), "
         "constant, floor-plus-scale, learned")
      ->check(CLI::IsMember({"auto", "constant", "floor-plus-scale", "learned"}));
  sub->add_option("--frame", a->frame, "First frame used (index into frames.csv)")->check(NonNegativeInteger());
  sub->add_option("--frames", a->frames, "spacetime: frames used from --frame (0: all)")->check(NonNegativeInteger());
  sub->add_option("--min-disparity", a->min_disparity_px, "Smallest disparity searched (px)");
  sub->add_option("--num-disparities", a->num_disparities, "Disparities searched (px, 3-1024)")
      ->check(CLI::Range(3, 1024));
  AddWindowOption(sub, &a->window_px,
                  "0: the matcher's command's default, block 5, spacetime 7 below 16 frames else 5, sgbm 5; sgbm "
                  "uses at most 11",
                  0);
  sub->add_option("--image-noise", a->image_noise_gray,
                  "Image noise sigma_n for the predicted sigma_d (grey levels, > 0)")
      ->check(PositiveReal());
  sub->add_option("--roi", a->roi, "Region of the target in the rectified left image: x y width height (px)")
      ->expected(4);
  sub->add_option("--stride", a->stride_px, "Use every n-th pixel in x and y (1-64)")->check(CLI::Range(1, 64));
  sub->add_option("--png", a->png, "Report picture: residual histogram against the model, sigma_d against depth");
  AddQuietFlag(sub, &a->quiet);
  sub->callback([a, sub] { RunNoise(*a, *sub); });
}

void AddCheckNoise(CLI::App* calibrate) {
  struct Args {
    std::vector<std::string> scenes;
    std::string model;
    int stride_px = 2;
    bool quiet = false;
  };
  auto a = std::make_shared<Args>();
  CLI::App* sub = calibrate->add_subcommand(
      "check-noise",
      "Test a learned noise.yaml on scenes with ground truth: do the normalised residuals (d - d_gt) / sigma_d follow "
      "the model? Exit 0 either way; the last line says whether it passed");
  sub->add_option("SCENE", a->scenes, "Middlebury scene folders (held out from the fit)")->required();
  sub->add_option("--noise-model", a->model, "noise.yaml of form learned (rangebayes calibrate noise --target "
                  "ground-truth)")->required();
  sub->add_option("--stride", a->stride_px, "Use every n-th pixel in x and y (1-64)")->check(CLI::Range(1, 64));
  AddQuietFlag(sub, &a->quiet);
  sub->callback([a] {
    const DisparityNoiseModel model = ReadDisparityNoiseModel(a->model);
    ProgressPrinter progress(a->quiet);
    const NoiseModelCheck check = CheckDisparityNoiseOnGroundTruth(model, a->scenes, a->stride_px, progress.callback());
    progress.Finish();
    std::fputs(check.BriefReport().c_str(), stdout);
  });
}

void AddImportMiddlebury(CLI::App* calibrate) {
  struct Args {
    std::string calib;
    std::string out;
  };
  auto a = std::make_shared<Args>();
  CLI::App* sub = calibrate->add_subcommand(
      "import-middlebury", "Turn a Middlebury 2014 calib.txt (rectified views) into a rig.yaml");
  sub->add_option("CALIB_TXT", a->calib, "Middlebury calib.txt")->required();
  sub->add_option("--out,-o", a->out, "Output rig file (OpenCV FileStorage YAML)")->required();
  sub->callback([a] {
    const MiddleburyCalib calib = ReadMiddleburyCalib(a->calib);
    const StereoRig rig = StereoRigFromMiddlebury(calib);
    WriteStereoRig(rig, a->out);
    std::printf("rig: %dx%d, f %.3f px, baseline %.4f m, doffs %.3f px (rectified); wrote %s\n", rig.width, rig.height,
                rig.K_left(0, 0), rig.baseline_m(), rig.doffs_px, a->out.c_str());
  });
}

}  // namespace

RB_REGISTER_COMMANDS(60, [](CLI::App& app) {
  CLI::App* calibrate = app.add_subcommand("calibrate", "Calibrate the stereo rig and the disparity noise model");
  calibrate->require_subcommand(1);
  AddRig(calibrate);
  AddNoise(calibrate);
  AddCheckNoise(calibrate);
  AddImportMiddlebury(calibrate);
});

}  // namespace rangebayes::apps
