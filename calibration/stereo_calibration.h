// Stereo rig calibration from image pairs of a planar board (chessboard or ChArUco): detection with sub-pixel
// corners, each camera's intrinsics, the stereo extrinsics with the intrinsics fixed, rectification, and the
// feedback a rig operator needs (per-view RMS, flagged views, board coverage, epipolar error).
#pragma once

#include <string>
#include <vector>

#include "calibration/stereo_rig.h"
#include "core/image.h"
#include "core/progress.h"

namespace rangebayes {

enum class BoardType { kChessboard, kCharuco };

// Chessboard corner detector: OpenCV's sector-based findChessboardCornersSB (falls back to the classic one
// when it finds nothing), the classic findChessboardCorners + cornerSubPix (11×11 window), or kBest (the
// default): calibrate with each of the two and keep the one with the lower stereo RMS, so the choice is never
// worse than the classic detector on any set (neither detector wins on every set: BENCHMARKS.md,
// calibration detector).
enum class ChessboardDetector { kBest, kSectorBased, kClassic };

// The calibration target. Chessboard: cols × rows INNER corners (OpenCV's 9x6 sample board is 9 × 6).
// ChArUco: cols × rows SQUARES (its inner corners are (cols−1) × (rows−1)), markers of marker_m inside the
// squares, from an OpenCV predefined dictionary.
struct BoardSpec {
  BoardType type = BoardType::kChessboard;
  int cols = 9;                       // chessboard: inner corners across; ChArUco: squares across; ≥ 3
  int rows = 6;                       // chessboard: inner corners down; ChArUco: squares down; ≥ 3
  double square_m = 0.025;            // square side in metres (sets the unit of the baseline); > 0
  double marker_m = 0.0;              // ChArUco marker side in metres; 0 = 0.75 × square_m; < square_m
  std::string dictionary = "DICT_4X4_50";  // ChArUco: an OpenCV predefined dictionary name
  ChessboardDetector detector = ChessboardDetector::kBest;  // chessboard only
  // Sector-based detector with CALIB_CB_ACCURACY: about 4× slower; on OpenCV's samples stereo RMS 0.281 → 0.273 px.
  bool accurate_corners = false;
  void Check() const;
};

// True when this build has OpenCV's aruco module (ChArUco boards need it).
bool CharucoAvailable();

// One stereo pair of calibration images (file paths).
struct CalibrationImagePair {
  std::string left;
  std::string right;
};

// Expands shell-style glob patterns (each entry a pattern or a literal path; patterns are expanded here, so
// quoting them on the command line is safe) for the left and right images and pairs them: by the last
// number in the file name when every name has one (a number present on one side only is reported in
// *unpaired), otherwise by sorted order (then the counts must match). Throws Error when a pattern matches
// nothing or the sides cannot be paired.
std::vector<CalibrationImagePair> PairCalibrationImages(const std::vector<std::string>& left_patterns,
                                                        const std::vector<std::string>& right_patterns,
                                                        std::vector<std::string>* unpaired = nullptr);

struct StereoCalibrationOptions {
  BoardSpec board;
  int min_pairs = 5;                  // fewer usable pairs than this is an error; ≥ 3
  // A view is flagged when its stereo RMS exceeds BOTH median + outlier_mad_factor · 1.4826 · MAD and
  // outlier_min_ratio × median (the ratio keeps a uniformly good set from having flags).
  double outlier_mad_factor = 3.0;    // [1, 10]
  double outlier_min_ratio = 1.5;     // [1, 5]
  bool drop_outliers = false;         // recalibrate without the flagged views (needs min_pairs left)
  bool rational_model = false;        // 8-coefficient distortion (k4..k6); needs many views
  // A rig whose stereo RMS or mean rectified epipolar error exceeds this is not usable (a misdetected board,
  // the wrong board size, a distortion model that failed): CalibrationProblem says so. > 0; inf: no limit.
  double max_rms_px = 2.0;
  int coverage_grid = 8;              // coverage grid cells per side for the grid coverage figure; [2, 64]
  void Check() const;
};

// Feedback for one image pair.
struct CalibrationView {
  std::string left;
  std::string right;
  bool used = false;            // board found in both images and the pair entered the final calibration
  bool dropped = false;         // flagged and dropped by drop_outliers
  std::string skip_reason;      // non-empty when the board was not found ("board not found in the left image")
  double rms_left_px = -1.0;    // per-view reprojection RMS, each camera's own calibration
  double rms_right_px = -1.0;
  double rms_stereo_px = -1.0;  // per-view RMS (both images) of the stereo calibration
  bool flagged = false;         // far above the rest (see StereoCalibrationOptions)
};

struct StereoCalibrationSummary {
  std::vector<CalibrationView> views;
  int pairs_found = 0;          // board found in both images
  int pairs_used = 0;           // entered the final calibration
  double rms_left_px = -1.0;    // final single-camera RMS
  double rms_right_px = -1.0;
  double rms_stereo_px = -1.0;  // final stereo RMS (both images, all used views)
  double rms_stereo_all_px = -1.0;  // stereo RMS with every found view, before any drop
  double flag_threshold_px = 0.0;   // per-view stereo RMS above which a view was flagged
  double median_view_rms_px = 0.0;
  // Fraction of the image covered by the union of the convex hulls of the detected boards, and the
  // fraction of coverage_grid² cells that contain at least one corner.
  double coverage_left = 0.0;
  double coverage_right = 0.0;
  double grid_coverage_left = 0.0;
  double grid_coverage_right = 0.0;
  // |y_left − y_right| of the board corners after rectification, over all used views, pixels.
  double epipolar_error_mean_px = -1.0;
  double epipolar_error_max_px = -1.0;
  // The right camera's centre lies on the left camera's left (T_x > 0 in the left frame): the images were most
  // likely given swapped (--left / --right), and stereo would match the wrong way round.
  bool right_camera_on_the_left = false;
  // The detector the result comes from (kBest: the one kept) and, for kBest, each candidate's final stereo
  // RMS (−1: fewer than min_pairs pairs found with it).
  ChessboardDetector detector_used = ChessboardDetector::kSectorBased;
  double rms_stereo_sector_based_px = -1.0;
  double rms_stereo_classic_px = -1.0;
  // The run's settings the report names: pairs given, a chessboard, both detectors compared (kBest),
  // StereoCalibrationOptions::coverage_grid.
  int pairs_given = 0;
  bool chessboard = true;
  bool detectors_compared = false;
  int coverage_grid = 0;

  // A table of the views (file name, left / right / stereo RMS, flagged or dropped), then pairs, RMS, the
  // detector, flagging, board coverage and the epipolar error after rectification, one per line.
  std::string BriefReport() const;
};

// Calibrates the rig: detection (chessboard: see ChessboardDetector; kBest runs everything below once per
// detector), calibrateCamera per camera, stereoCalibrate with the intrinsics fixed, stereoRectify
// (alpha 0). Pairs whose board is not found in either image are skipped and named in the summary.
// Throws Error when an image cannot be read, sizes differ, or fewer than min_pairs pairs are usable.
StereoRig CalibrateStereoRig(const std::vector<CalibrationImagePair>& pairs, const StereoCalibrationOptions& options,
                             StereoCalibrationSummary* summary = nullptr, const ProgressCallback& progress = {});

// Why the calibration summarised is not usable (its stereo RMS or mean epipolar error above options.max_rms_px,
// or not finite), with what to try; empty when it is. `calibrate rig` prints the summary first and then fails with
// this line without writing the rig; Python's calibrate_rig raises it.
std::string CalibrationProblem(const StereoCalibrationSummary& summary, const StereoCalibrationOptions& options);

// The rectified pair side by side with horizontal lines every line_spacing_px rows (corresponding points lie
// on one line when the rectification is right).
struct RectifiedPreviewOptions {
  int line_spacing_px = 32;  // [4, 1000]
  void Check() const;
};
RgbImage RenderRectifiedPair(const StereoRig& rig, const CalibrationImagePair& pair,
                             const RectifiedPreviewOptions& options = {});

}  // namespace rangebayes
