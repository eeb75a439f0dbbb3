#include "calibration/stereo_calibration.h"

#include <glob.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/core/eigen.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <regex>
#include <set>
#include <string>

#include "calibration/image_read.h"
#include "core/error.h"
#include "core/files.h"

#ifdef RB_HAVE_ARUCO
#include <opencv2/aruco/charuco.hpp>
#endif

namespace rangebayes {
namespace {

// Fewest common corners for a ChArUco view to enter the calibration (homography plus margin).
constexpr int kMinCharucoCorners = 8;

std::vector<std::string> ExpandGlob(const std::string& pattern) {
  glob_t g{};
  const int rc = glob(pattern.c_str(), GLOB_NOSORT, nullptr, &g);
  std::vector<std::string> out;
  if (rc == 0) {
    for (size_t i = 0; i < g.gl_pathc; ++i) out.emplace_back(g.gl_pathv[i]);
  }
  globfree(&g);
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<std::string> ExpandAll(const std::vector<std::string>& patterns, const char* side) {
  std::vector<std::string> out;
  for (const std::string& p : patterns) {
    std::vector<std::string> m = ExpandGlob(p);
    RB_CHECK(!m.empty(), side, " images: '", p, "' matches no file");
    out.insert(out.end(), m.begin(), m.end());
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

// The last run of digits in the file name (not the folder), or nullopt.
std::optional<long> LastNumber(const std::string& path) {
  const std::string name = std::filesystem::path(path).filename().string();
  static const std::regex digits("[0-9]+");
  std::optional<long> last;
  for (auto it = std::sregex_iterator(name.begin(), name.end(), digits); it != std::sregex_iterator(); ++it) {
    const std::string s = it->str();
    if (s.size() < 10) last = std::stol(s);
  }
  return last;
}

std::optional<std::map<long, std::string>> ByNumber(const std::vector<std::string>& paths) {
  std::map<long, std::string> out;
  for (const std::string& p : paths) {
    const std::optional<long> n = LastNumber(p);
    if (!n || out.count(*n)) return std::nullopt;
    out[*n] = p;
  }
  return out;
}

struct Detection {
  bool found = false;
  std::vector<cv::Point2f> corners;
  std::vector<int> ids;  // board corner ids, one per corner
};

struct BoardModel {
  BoardSpec spec;
#ifdef RB_HAVE_ARUCO
  cv::Ptr<cv::aruco::Dictionary> dictionary;
  cv::Ptr<cv::aruco::CharucoBoard> charuco;
#endif

  cv::Point3f ObjectPoint(int id) const {
#ifdef RB_HAVE_ARUCO
    if (spec.type == BoardType::kCharuco) return charuco->chessboardCorners[static_cast<size_t>(id)];
#endif
    return cv::Point3f(static_cast<float>((id % spec.cols) * spec.square_m),
                       static_cast<float>((id / spec.cols) * spec.square_m), 0.0f);
  }
};

#ifdef RB_HAVE_ARUCO
int DictionaryId(const std::string& name) {
  static const std::map<std::string, int> table = {
      {"DICT_4X4_50", cv::aruco::DICT_4X4_50},       {"DICT_4X4_100", cv::aruco::DICT_4X4_100},
      {"DICT_4X4_250", cv::aruco::DICT_4X4_250},     {"DICT_4X4_1000", cv::aruco::DICT_4X4_1000},
      {"DICT_5X5_50", cv::aruco::DICT_5X5_50},       {"DICT_5X5_100", cv::aruco::DICT_5X5_100},
      {"DICT_5X5_250", cv::aruco::DICT_5X5_250},     {"DICT_5X5_1000", cv::aruco::DICT_5X5_1000},
      {"DICT_6X6_50", cv::aruco::DICT_6X6_50},       {"DICT_6X6_100", cv::aruco::DICT_6X6_100},
      {"DICT_6X6_250", cv::aruco::DICT_6X6_250},     {"DICT_6X6_1000", cv::aruco::DICT_6X6_1000},
      {"DICT_7X7_50", cv::aruco::DICT_7X7_50},       {"DICT_7X7_100", cv::aruco::DICT_7X7_100},
      {"DICT_7X7_250", cv::aruco::DICT_7X7_250},     {"DICT_7X7_1000", cv::aruco::DICT_7X7_1000},
      {"DICT_ARUCO_ORIGINAL", cv::aruco::DICT_ARUCO_ORIGINAL}};
  const auto it = table.find(name);
  RB_CHECK(it != table.end(), "ChArUco dictionary '", name,
           "' is not known (use an OpenCV name such as DICT_4X4_50, DICT_5X5_100, DICT_6X6_250)");
  return it->second;
}
#endif

BoardModel MakeBoard(const BoardSpec& spec) {
  BoardModel board;
  board.spec = spec;
  if (spec.type == BoardType::kCharuco) {
#ifdef RB_HAVE_ARUCO
    board.dictionary = cv::aruco::getPredefinedDictionary(DictionaryId(spec.dictionary));
    const double marker = spec.marker_m > 0 ? spec.marker_m : 0.75 * spec.square_m;
    board.charuco = cv::aruco::CharucoBoard::create(spec.cols, spec.rows, static_cast<float>(spec.square_m),
                                                    static_cast<float>(marker), board.dictionary);
#else
    RB_FAIL("ChArUco boards need OpenCV's aruco module (Debian: libopencv-contrib-dev), which this build lacks");
#endif
  }
  return board;
}

Detection DetectChessboard(const cv::Mat& gray, const BoardSpec& spec) {
  Detection d;
  const cv::Size pattern(spec.cols, spec.rows);
  // No board fits in an image with squares under 4 px (and OpenCV's classic detector asserts on images under
  // about 15 px, its adaptive threshold's window shrinking to 1 px).
  if (gray.cols < std::max(16, 4 * (spec.cols + 1)) || gray.rows < std::max(16, 4 * (spec.rows + 1))) return d;
  // The sector-based detector is the more accurate; the classic one with cornerSubPix catches boards the
  // former misses (strong blur, small boards).
  if (spec.detector == ChessboardDetector::kSectorBased) {
    const int flags = cv::CALIB_CB_NORMALIZE_IMAGE | (spec.accurate_corners ? cv::CALIB_CB_ACCURACY : 0);
    d.found = cv::findChessboardCornersSB(gray, pattern, d.corners, flags);
  }
  if (!d.found) {
    d.found = cv::findChessboardCorners(gray, pattern, d.corners,
                                        cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
    if (d.found) {
      cv::cornerSubPix(gray, d.corners, cv::Size(11, 11), cv::Size(-1, -1),
                       cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 30, 0.01));
    }
  }
  if (d.found) {
    d.ids.resize(d.corners.size());
    std::iota(d.ids.begin(), d.ids.end(), 0);
  }
  return d;
}

Detection DetectCharuco([[maybe_unused]] const cv::Mat& gray, [[maybe_unused]] const BoardModel& board) {
  Detection d;
#ifdef RB_HAVE_ARUCO
  std::vector<std::vector<cv::Point2f>> marker_corners;
  std::vector<int> marker_ids;
  cv::aruco::detectMarkers(gray, board.dictionary, marker_corners, marker_ids);
  if (marker_ids.size() < 2) return d;
  cv::Mat corners, ids;
  cv::aruco::interpolateCornersCharuco(marker_corners, marker_ids, gray, board.charuco, corners, ids);
  if (ids.total() < static_cast<size_t>(kMinCharucoCorners)) return d;
  for (size_t i = 0; i < ids.total(); ++i) {
    d.corners.push_back(corners.at<cv::Point2f>(static_cast<int>(i)));
    d.ids.push_back(ids.at<int>(static_cast<int>(i)));
  }
  d.found = true;
#endif
  return d;
}

struct PairDetection {
  int index = 0;  // into the input pairs
  std::vector<cv::Point3f> object;
  std::vector<cv::Point2f> left;
  std::vector<cv::Point2f> right;
};

// Keeps the corners seen in both views, in one order.
PairDetection Combine(const Detection& l, const Detection& r, const BoardModel& board) {
  PairDetection p;
  std::map<int, size_t> right_by_id;
  for (size_t i = 0; i < r.ids.size(); ++i) right_by_id[r.ids[i]] = i;
  for (size_t i = 0; i < l.ids.size(); ++i) {
    const auto it = right_by_id.find(l.ids[i]);
    if (it == right_by_id.end()) continue;
    p.object.push_back(board.ObjectPoint(l.ids[i]));
    p.left.push_back(l.corners[i]);
    p.right.push_back(r.corners[it->second]);
  }
  return p;
}

cv::Mat ReadGray(const std::string& path) { return ReadImage(path, cv::IMREAD_GRAYSCALE); }

struct StageResult {
  cv::Mat K_left, D_left, K_right, D_right, R, T;
  double rms_left = 0, rms_right = 0, rms_stereo = 0;
  std::vector<double> view_left, view_right, view_stereo;
};

StageResult Calibrate(const std::vector<PairDetection>& views, const cv::Size& size,
                      const StereoCalibrationOptions& options) {
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> left, right;
  for (const PairDetection& v : views) {
    object.push_back(v.object);
    left.push_back(v.left);
    right.push_back(v.right);
  }
  StageResult s;
  const int flags = options.rational_model ? cv::CALIB_RATIONAL_MODEL : 0;
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 100, 1e-9);
  std::vector<cv::Mat> rvecs, tvecs;
  cv::Mat std_int, std_ext, per_view;
  try {
    s.rms_left = cv::calibrateCamera(object, left, size, s.K_left, s.D_left, rvecs, tvecs, std_int, std_ext, per_view,
                                     flags, criteria);
    for (int i = 0; i < per_view.rows; ++i) s.view_left.push_back(per_view.at<double>(i));
    s.rms_right = cv::calibrateCamera(object, right, size, s.K_right, s.D_right, rvecs, tvecs, std_int, std_ext,
                                      per_view, flags, criteria);
    for (int i = 0; i < per_view.rows; ++i) s.view_right.push_back(per_view.at<double>(i));
    // Two stages: the stereo step estimates only R and T. Jointly re-estimating the intrinsics from the
    // pairs alone fits worse on OpenCV's samples (0.634 px against 0.448 px). The distortion model's flag goes
    // with it: without CALIB_RATIONAL_MODEL the stereo step reads only the first five of the eight coefficients
    // (a stereo RMS of 2e10 px on OpenCV's samples with --rational).
    cv::Mat E, F, stereo_view;
    s.rms_stereo = cv::stereoCalibrate(object, left, right, s.K_left, s.D_left, s.K_right, s.D_right, size, s.R, s.T, E,
                                       F, stereo_view, cv::CALIB_FIX_INTRINSIC | flags, criteria);
    for (int i = 0; i < stereo_view.rows; ++i) {
      const double a = stereo_view.at<double>(i, 0), b = stereo_view.at<double>(i, 1);
      s.view_stereo.push_back(std::sqrt(0.5 * (a * a + b * b)));
    }
  } catch (const cv::Exception& e) {
    RB_FAIL("calibration failed in OpenCV (", e.err, ")");
  }
  return s;
}

double Median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const size_t m = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + static_cast<long>(m), v.end());
  double med = v[m];
  if (v.size() % 2 == 0) med = 0.5 * (med + *std::max_element(v.begin(), v.begin() + static_cast<long>(m)));
  return med;
}

// Union-of-hulls and grid coverage of the detected corners of one camera.
void Coverage(const std::vector<std::vector<cv::Point2f>>& views, const cv::Size& size, int grid, double* hull_fraction,
              double* grid_fraction) {
  cv::Mat mask = cv::Mat::zeros(size, CV_8U);
  std::vector<char> cells(static_cast<size_t>(grid * grid), 0);
  for (const auto& pts : views) {
    std::vector<cv::Point2f> hull;
    cv::convexHull(pts, hull);
    std::vector<cv::Point> ihull;
    for (const auto& p : hull) ihull.emplace_back(cvRound(p.x), cvRound(p.y));
    cv::fillConvexPoly(mask, ihull, cv::Scalar(255));
    for (const auto& p : pts) {
      const int cx = std::clamp(static_cast<int>(p.x * grid / size.width), 0, grid - 1);
      const int cy = std::clamp(static_cast<int>(p.y * grid / size.height), 0, grid - 1);
      cells[static_cast<size_t>(cy * grid + cx)] = 1;
    }
  }
  *hull_fraction = static_cast<double>(cv::countNonZero(mask)) / static_cast<double>(size.area());
  *grid_fraction = static_cast<double>(std::count(cells.begin(), cells.end(), 1)) / static_cast<double>(cells.size());
}

template <typename EigenType>
void ToEigen(const cv::Mat& m, EigenType* out) {
  cv::Mat d;
  m.convertTo(d, CV_64F);
  cv::cv2eigen(d, *out);
}

}  // namespace

void BoardSpec::Check() const {
  // OpenCV's chessboard detectors assert more than 2 inner corners a side; a ChArUco board needs 3 squares.
  RB_CHECK(cols >= 3 && rows >= 3, "board: ", cols, "x", rows, " is too small (each side ≥ 3)");
  RB_CHECK(square_m > 0 && std::isfinite(square_m), "board: square size ", square_m, " m must be positive");
  RB_CHECK(marker_m >= 0 && marker_m < square_m, "board: marker size ", marker_m,
           " m must be in [0, square size)");
}

bool CharucoAvailable() {
#ifdef RB_HAVE_ARUCO
  return true;
#else
  return false;
#endif
}

void StereoCalibrationOptions::Check() const {
  board.Check();
  RB_CHECK(min_pairs >= 3, "min_pairs ", min_pairs, " must be at least 3");
  RB_CHECK(outlier_mad_factor >= 1 && outlier_mad_factor <= 10, "outlier_mad_factor ", outlier_mad_factor,
           " not in [1, 10]");
  RB_CHECK(outlier_min_ratio >= 1 && outlier_min_ratio <= 5, "outlier_min_ratio ", outlier_min_ratio,
           " not in [1, 5]");
  RB_CHECK(coverage_grid >= 2 && coverage_grid <= 64, "coverage_grid ", coverage_grid, " not in [2, 64]");
  RB_CHECK(max_rms_px > 0, "max_rms_px ", max_rms_px, " must be > 0 (inf: no limit)");
}

std::string CalibrationProblem(const StereoCalibrationSummary& summary, const StereoCalibrationOptions& options) {
  const double worst = std::max(summary.rms_stereo_px, summary.epipolar_error_mean_px);
  if (std::isfinite(summary.rms_stereo_px) && std::isfinite(summary.epipolar_error_mean_px) &&
      !(worst > options.max_rms_px)) {
    return "";
  }
  int flagged = 0;
  for (const CalibrationView& v : summary.views) flagged += v.flagged ? 1 : 0;
  char values[96];
  std::snprintf(values, sizeof(values), "stereo RMS %.4g px, mean epipolar error %.4g px", summary.rms_stereo_px,
                summary.epipolar_error_mean_px);
  std::string hints;
  if (flagged > 0 && !options.drop_outliers) hints += "rerun with --drop-outliers (views are flagged above), or ";
  if (options.rational_model) hints += "try without --rational or with more views, or ";
  hints += "check --board and that left and right images are paired";
  return StrCat("the calibration is not usable: ", values, " (limit ", options.max_rms_px, " px, --max-rms); ", hints);
}

void RectifiedPreviewOptions::Check() const {
  RB_CHECK(line_spacing_px >= 4 && line_spacing_px <= 1000, "line_spacing_px ", line_spacing_px,
           " not in [4, 1000]");
}

std::vector<CalibrationImagePair> PairCalibrationImages(const std::vector<std::string>& left_patterns,
                                                        const std::vector<std::string>& right_patterns,
                                                        std::vector<std::string>* unpaired) {
  RB_CHECK(!left_patterns.empty() && !right_patterns.empty(), "need left and right image patterns");
  const std::vector<std::string> left = ExpandAll(left_patterns, "left");
  const std::vector<std::string> right = ExpandAll(right_patterns, "right");
  std::vector<CalibrationImagePair> pairs;
  const auto left_by_number = ByNumber(left);
  const auto right_by_number = ByNumber(right);
  if (left_by_number && right_by_number) {
    for (const auto& [n, path] : *left_by_number) {
      const auto it = right_by_number->find(n);
      if (it == right_by_number->end()) {
        if (unpaired) unpaired->push_back(path);
        continue;
      }
      pairs.push_back({path, it->second});
    }
    for (const auto& [n, path] : *right_by_number) {
      if (!left_by_number->count(n) && unpaired) unpaired->push_back(path);
    }
    RB_CHECK(!pairs.empty(), "no left and right image share a number in its file name (",
             left.front(), " ... ", right.front(), ")");
    return pairs;
  }
  RB_CHECK(left.size() == right.size(), "cannot pair ", left.size(), " left images with ", right.size(),
           " right images (file names without one distinct number each are paired in sorted order)");
  for (size_t i = 0; i < left.size(); ++i) pairs.push_back({left[i], right[i]});
  return pairs;
}

namespace {

// Detects the board in every pair (a view per pair in sum->views, with the reason when it is skipped); the
// pairs seen in both images, their corners in the same order. size: the images' size.
std::vector<PairDetection> DetectPairs(const std::vector<CalibrationImagePair>& pairs,
                                       const StereoCalibrationOptions& options, const BoardModel& board,
                                       const ProgressCallback& progress, cv::Size* size_out,
                                       StereoCalibrationSummary* summary) {
  StereoCalibrationSummary& sum = *summary;
  cv::Size& size = *size_out;
  std::vector<PairDetection> found;
  for (size_t i = 0; i < pairs.size(); ++i) {
    if (progress) progress(static_cast<double>(i) / static_cast<double>(pairs.size() + 1), "detecting boards");
    CalibrationView view;
    view.left = pairs[i].left;
    view.right = pairs[i].right;
    const cv::Mat l = ReadGray(pairs[i].left), r = ReadGray(pairs[i].right);
    if (size.area() == 0) size = l.size();
    RB_CHECK(l.size() == size, pairs[i].left, ": image is ", l.cols, "x", l.rows, ", the first one is ", size.width,
             "x", size.height);
    RB_CHECK(r.size() == size, pairs[i].right, ": image is ", r.cols, "x", r.rows, ", the first one is ",
             size.width, "x", size.height);
    const bool charuco = options.board.type == BoardType::kCharuco;
    const Detection dl = charuco ? DetectCharuco(l, board) : DetectChessboard(l, options.board);
    const Detection dr = charuco ? DetectCharuco(r, board) : DetectChessboard(r, options.board);
    if (!dl.found || !dr.found) {
      view.skip_reason = !dl.found && !dr.found ? "board not found in either image"
                         : !dl.found            ? "board not found in the left image"
                                                : "board not found in the right image";
      sum.views.push_back(view);
      continue;
    }
    PairDetection p = Combine(dl, dr, board);
    if (charuco && static_cast<int>(p.object.size()) < kMinCharucoCorners) {
      view.skip_reason = "too few ChArUco corners seen in both images";
      sum.views.push_back(view);
      continue;
    }
    if (!charuco) {
      // The two detectors may start the corner order at opposite ends of a board; for a rig the board runs
      // the same way in both views.
      const cv::Point2f dir_l = p.left.back() - p.left.front(), dir_r = p.right.back() - p.right.front();
      if (dir_l.dot(dir_r) < 0) std::reverse(p.right.begin(), p.right.end());
    }
    p.index = static_cast<int>(sum.views.size());
    sum.views.push_back(view);
    found.push_back(std::move(p));
  }
  return found;
}

// Calibrates on the found pairs, flags views whose stereo RMS is far above the median (median + k·MAD), and
// when options.drop_outliers calibrates again without them. Returns the calibration; kept: the views it used.
StageResult CalibrateDroppingOutliers(const std::vector<PairDetection>& found, const cv::Size& size,
                                      const StereoCalibrationOptions& options, std::vector<PairDetection>* kept_out,
                                      StereoCalibrationSummary* summary) {
  StereoCalibrationSummary& sum = *summary;
  std::vector<PairDetection>& kept = *kept_out;
  StageResult stage = Calibrate(found, size, options);
  sum.rms_stereo_all_px = stage.rms_stereo;
  sum.median_view_rms_px = Median(stage.view_stereo);
  std::vector<double> deviations;
  for (double e : stage.view_stereo) deviations.push_back(std::abs(e - sum.median_view_rms_px));
  const double sigma_mad = 1.4826 * Median(deviations);
  sum.flag_threshold_px = std::max(sum.median_view_rms_px + options.outlier_mad_factor * sigma_mad,
                                   options.outlier_min_ratio * sum.median_view_rms_px);
  for (size_t i = 0; i < found.size(); ++i) {
    CalibrationView& v = sum.views[static_cast<size_t>(found[i].index)];
    v.flagged = stage.view_stereo[i] > sum.flag_threshold_px;
    v.rms_left_px = stage.view_left[i];
    v.rms_right_px = stage.view_right[i];
    v.rms_stereo_px = stage.view_stereo[i];
    if (options.drop_outliers && v.flagged) {
      v.dropped = true;
    } else {
      kept.push_back(found[i]);
    }
  }
  if (kept.size() != found.size()) {
    RB_CHECK(static_cast<int>(kept.size()) >= options.min_pairs, "after dropping ", found.size() - kept.size(),
             " flagged views only ", kept.size(), " remain; at least ", options.min_pairs, " are needed");
    stage = Calibrate(kept, size, options);
    for (size_t i = 0; i < kept.size(); ++i) {
      CalibrationView& v = sum.views[static_cast<size_t>(kept[i].index)];
      v.rms_left_px = stage.view_left[i];
      v.rms_right_px = stage.view_right[i];
      v.rms_stereo_px = stage.view_stereo[i];
    }
  }
  for (const PairDetection& p : kept) sum.views[static_cast<size_t>(p.index)].used = true;
  sum.pairs_used = static_cast<int>(kept.size());
  sum.rms_left_px = stage.rms_left;
  sum.rms_right_px = stage.rms_right;
  sum.rms_stereo_px = stage.rms_stereo;
  return stage;
}

// The rectified corners' vertical disagreement (mean and max) and the board's coverage of each image.
void MeasureRectification(const std::vector<PairDetection>& kept, const StageResult& stage, const cv::Mat& R1,
                          const cv::Mat& R2, const cv::Mat& P1, const cv::Mat& P2, const cv::Size& size,
                          const StereoCalibrationOptions& options, StereoCalibrationSummary* summary) {
  StereoCalibrationSummary& sum = *summary;
  std::vector<std::vector<cv::Point2f>> all_left, all_right;
  double sum_dy = 0, max_dy = 0;
  size_t count = 0;
  for (const PairDetection& p : kept) {
    all_left.push_back(p.left);
    all_right.push_back(p.right);
    std::vector<cv::Point2f> rl, rr;
    cv::undistortPoints(p.left, rl, stage.K_left, stage.D_left, R1, P1);
    cv::undistortPoints(p.right, rr, stage.K_right, stage.D_right, R2, P2);
    for (size_t i = 0; i < rl.size(); ++i) {
      const double dy = std::abs(static_cast<double>(rl[i].y) - rr[i].y);
      sum_dy += dy;
      max_dy = std::max(max_dy, dy);
      ++count;
    }
  }
  sum.epipolar_error_mean_px = count ? sum_dy / static_cast<double>(count) : -1.0;
  sum.epipolar_error_max_px = max_dy;
  // x_right = R x_left + T: the right centre is at −RᵀT in the left frame, on the left's right for a proper pair.
  const cv::Mat centre = -stage.R.t() * stage.T;
  sum.right_camera_on_the_left = centre.at<double>(0) < 0.0;
  Coverage(all_left, size, options.coverage_grid, &sum.coverage_left, &sum.grid_coverage_left);
  Coverage(all_right, size, options.coverage_grid, &sum.coverage_right, &sum.grid_coverage_right);
}

StereoRig MakeRig(const StageResult& stage, const cv::Mat& R1, const cv::Mat& R2, const cv::Mat& P1,
                  const cv::Mat& P2, const cv::Mat& Q, const cv::Size& size, const std::vector<PairDetection>& kept,
                  const StereoCalibrationSummary& sum) {
  StereoRig rig;
  rig.width = size.width;
  rig.height = size.height;
  ToEigen(stage.K_left, &rig.K_left);
  ToEigen(stage.K_right, &rig.K_right);
  Eigen::MatrixXd dl, dr;
  ToEigen(stage.D_left.reshape(1, static_cast<int>(stage.D_left.total())), &dl);
  ToEigen(stage.D_right.reshape(1, static_cast<int>(stage.D_right.total())), &dr);
  rig.distortion_left = dl.col(0);
  rig.distortion_right = dr.col(0);
  ToEigen(stage.R, &rig.R_right_from_left);
  Eigen::MatrixXd t;
  ToEigen(stage.T.reshape(1, 3), &t);
  rig.t_right_from_left_m = t.col(0);
  ToEigen(R1, &rig.R1);
  ToEigen(R2, &rig.R2);
  ToEigen(P1, &rig.P1);
  ToEigen(P2, &rig.P2);
  ToEigen(Q, &rig.Q);
  rig.rms_left_px = stage.rms_left;
  rig.rms_right_px = stage.rms_right;
  rig.rms_stereo_px = stage.rms_stereo;
  rig.epipolar_error_px = sum.epipolar_error_mean_px;
  for (const PairDetection& p : kept) {
    const CalibrationView& v = sum.views[static_cast<size_t>(p.index)];
    rig.view_names.push_back(std::filesystem::path(v.left).filename().string());
    rig.view_rms_stereo_px.push_back(v.rms_stereo_px);
  }
  return rig;
}

StereoRig CalibrateWithDetector(const std::vector<CalibrationImagePair>& pairs, const StereoCalibrationOptions& options,
                                StereoCalibrationSummary* summary, const ProgressCallback& progress) {
  const BoardModel board = MakeBoard(options.board);
  StereoCalibrationSummary local;
  StereoCalibrationSummary& sum = summary ? *summary : local;
  sum = StereoCalibrationSummary{};
  cv::Size size;
  const std::vector<PairDetection> found = DetectPairs(pairs, options, board, progress, &size, &sum);
  sum.pairs_found = static_cast<int>(found.size());
  RB_CHECK(sum.pairs_found >= options.min_pairs, "only ", sum.pairs_found, " of ", pairs.size(),
           " image pairs show the board in both images; at least ", options.min_pairs, " are needed");

  if (progress) progress(0.8, "calibrating");
  std::vector<PairDetection> kept;
  const StageResult stage = CalibrateDroppingOutliers(found, size, options, &kept, &sum);
  cv::Mat R1, R2, P1, P2, Q;
  try {
    cv::stereoRectify(stage.K_left, stage.D_left, stage.K_right, stage.D_right, size, stage.R, stage.T, R1, R2, P1, P2,
                      Q, cv::CALIB_ZERO_DISPARITY, 0.0);
  } catch (const cv::Exception& e) {
    RB_FAIL("stereo rectification failed in OpenCV (", e.err, ")");
  }
  MeasureRectification(kept, stage, R1, R2, P1, P2, size, options, &sum);
  StereoRig rig = MakeRig(stage, R1, R2, P1, P2, Q, size, kept, sum);
  if (progress) progress(1.0, "calibrating");
  sum.detector_used = options.board.detector;
  return rig;
}

}  // namespace

namespace {

void RecordSettings(const std::vector<CalibrationImagePair>& pairs, const StereoCalibrationOptions& options,
                    StereoCalibrationSummary* summary) {
  if (summary == nullptr) return;
  summary->pairs_given = static_cast<int>(pairs.size());
  summary->chessboard = options.board.type == BoardType::kChessboard;
  summary->detectors_compared = summary->chessboard && options.board.detector == ChessboardDetector::kBest;
  summary->coverage_grid = options.coverage_grid;
}

}  // namespace

StereoRig CalibrateStereoRig(const std::vector<CalibrationImagePair>& pairs, const StereoCalibrationOptions& options,
                             StereoCalibrationSummary* summary, const ProgressCallback& progress) {
  options.Check();
  if (options.board.type != BoardType::kChessboard || options.board.detector != ChessboardDetector::kBest) {
    StereoRig rig = CalibrateWithDetector(pairs, options, summary, progress);
    RecordSettings(pairs, options, summary);
    return rig;
  }
  // Both detectors, each through the whole calibration; the lower final stereo RMS wins. A detector that
  // finds too few pairs drops out (its error is rethrown only when both fail).
  StereoCalibrationSummary best_sum;
  std::optional<StereoRig> best;
  std::optional<Error> first_error;
  double rms[2] = {-1.0, -1.0};
  const ChessboardDetector candidates[2] = {ChessboardDetector::kSectorBased, ChessboardDetector::kClassic};
  for (int k = 0; k < 2; ++k) {
    StereoCalibrationOptions o = options;
    o.board.detector = candidates[k];
    const ProgressCallback part = progress ? ProgressCallback([&progress, k](double f, std::string_view what) {
      progress(0.5 * (k + f), what);
    })
                                           : ProgressCallback();
    StereoCalibrationSummary s;
    try {
      StereoRig rig = CalibrateWithDetector(pairs, o, &s, part);
      rms[k] = s.rms_stereo_px;
      if (!best || s.rms_stereo_px < best_sum.rms_stereo_px) {
        best = std::move(rig);
        best_sum = std::move(s);
      }
    } catch (const Error& e) {
      if (!first_error) first_error = e;
    }
  }
  if (!best) throw *first_error;
  best_sum.rms_stereo_sector_based_px = rms[0];
  best_sum.rms_stereo_classic_px = rms[1];
  if (summary) *summary = std::move(best_sum);
  RecordSettings(pairs, options, summary);
  return *best;
}

std::string StereoCalibrationSummary::BriefReport() const {
  std::string out;
  char line[512];
  std::snprintf(line, sizeof(line), "%-28s %9s %9s %9s  %s\n", "view (left image)", "left px", "right px",
                "stereo px", "note");
  out += line;
  int flagged = 0;
  for (const CalibrationView& v : views) {
    flagged += v.flagged;
    const std::string name = std::filesystem::path(v.left).filename().string();
    if (!v.skip_reason.empty()) {
      std::snprintf(line, sizeof(line), "%-28s %9s %9s %9s  skipped: %s\n", name.c_str(), "-", "-", "-",
                    v.skip_reason.c_str());
      out += line;
      continue;
    }
    std::string note = v.flagged ? "FLAGGED: far above the rest" : "";
    if (v.dropped) note += " (dropped)";
    if (v.dropped) {
      std::snprintf(line, sizeof(line), "%-28s %9s %9s %9.3f  %s\n", name.c_str(), "-", "-", v.rms_stereo_px,
                    note.c_str());
    } else {
      std::snprintf(line, sizeof(line), "%-28s %9.3f %9.3f %9.3f  %s\n", name.c_str(), v.rms_left_px,
                    v.rms_right_px, v.rms_stereo_px, note.c_str());
    }
    out += line;
  }
  std::snprintf(line, sizeof(line), "pairs: %d given, %d with the board in both images, %d used\n", pairs_given,
                pairs_found, pairs_used);
  out += line;
  std::snprintf(line, sizeof(line), "RMS reprojection error: left %.3f px, right %.3f px, stereo %.3f px\n",
                rms_left_px, rms_right_px, rms_stereo_px);
  out += line;
  if (chessboard) {
    const char* used = detector_used == ChessboardDetector::kClassic ? "classic" : "sb";
    if (detectors_compared) {
      const auto rms = [](double v) {
        char text[32];
        std::snprintf(text, sizeof(text), "%.4g px", v);  // to_string cut to 5 characters printed 2e10 as "20092"
        return v < 0 ? std::string("too few pairs") : std::string(text);
      };
      std::snprintf(line, sizeof(line), "corner detector: %s kept (stereo RMS sb %s, classic %s)\n", used,
                    rms(rms_stereo_sector_based_px).c_str(), rms(rms_stereo_classic_px).c_str());
    } else {
      std::snprintf(line, sizeof(line), "corner detector: %s\n", used);
    }
    out += line;
  }
  if (pairs_used != pairs_found) {
    std::snprintf(line, sizeof(line), "stereo RMS with all %d views: %.3f px\n", pairs_found, rms_stereo_all_px);
    out += line;
  }
  std::snprintf(line, sizeof(line), "flag threshold %.3f px (median view %.3f px): %d view(s) flagged\n",
                flag_threshold_px, median_view_rms_px, flagged);
  out += line;
  std::snprintf(line, sizeof(line),
                "board coverage: left %.0f%% of the image (%.0f%% of %dx%d cells), right %.0f%% (%.0f%%)\n",
                100 * coverage_left, 100 * grid_coverage_left, coverage_grid, coverage_grid, 100 * coverage_right,
                100 * grid_coverage_right);
  out += line;
  std::snprintf(line, sizeof(line), "epipolar error after rectification: mean %.3f px, max %.3f px\n",
                epipolar_error_mean_px, epipolar_error_max_px);
  out += line;
  if (right_camera_on_the_left) {
    out += "warning: the right camera sits to the left of the left one: are --left and --right swapped?\n";
  }
  return out;
}

RgbImage RenderRectifiedPair(const StereoRig& rig, const CalibrationImagePair& pair,
                             const RectifiedPreviewOptions& options) {
  options.Check();
  const cv::Mat l = ReadGray(pair.left), r = ReadGray(pair.right);
  const cv::Size size(rig.width, rig.height);
  RB_CHECK(l.size() == size && r.size() == size, pair.left, ": image size differs from the rig's ", rig.width, "x",
           rig.height);
  auto to_mat = [](const auto& e) {
    cv::Mat m;
    cv::eigen2cv(Eigen::MatrixXd(e), m);
    return m;
  };
  cv::Mat rect_l, rect_r;
  const auto rectify = [&](const cv::Mat& img, const Eigen::Matrix3d& K, const Eigen::VectorXd& D,
                           const Eigen::Matrix3d& R, const Eigen::Matrix<double, 3, 4>& P, cv::Mat* out) {
    if (rig.is_rectified) {
      *out = img;
      return;
    }
    cv::Mat map1, map2;
    cv::Mat dist = D.size() > 0 ? to_mat(D) : cv::Mat();
    cv::initUndistortRectifyMap(to_mat(K), dist, to_mat(R), to_mat(P), size, CV_32FC1, map1, map2);
    cv::remap(img, *out, map1, map2, cv::INTER_LINEAR);
  };
  rectify(l, rig.K_left, rig.distortion_left, rig.R1, rig.P1, &rect_l);
  rectify(r, rig.K_right, rig.distortion_right, rig.R2, rig.P2, &rect_r);
  cv::Mat both;
  cv::hconcat(rect_l, rect_r, both);
  cv::Mat color;
  cv::cvtColor(both, color, cv::COLOR_GRAY2RGB);
  static const std::array<cv::Scalar, 4> colours = {cv::Scalar(255, 0, 0), cv::Scalar(0, 200, 0),
                                                    cv::Scalar(0, 0, 255), cv::Scalar(230, 160, 0)};
  int k = 0;
  for (int y = options.line_spacing_px / 2; y < color.rows; y += options.line_spacing_px, ++k) {
    cv::line(color, cv::Point(0, y), cv::Point(color.cols - 1, y), colours[static_cast<size_t>(k) % colours.size()],
             1);
  }
  RgbImage out(color.cols, color.rows);
  for (int y = 0; y < color.rows; ++y) {
    std::copy(color.ptr<std::uint8_t>(y), color.ptr<std::uint8_t>(y) + 3 * color.cols, out.at(0, y));
  }
  return out;
}

}  // namespace rangebayes
