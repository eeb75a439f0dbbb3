#include "calibration/stereo_calibration.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#ifdef RB_HAVE_ARUCO
#include <opencv2/aruco/charuco.hpp>
#endif

#include "calibration/stereo_rig.h"
#include "core/error.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

namespace fs = std::filesystem;

const char* kLeft = "tests/data/calibration/opencv_stereo/left*.jpg";
const char* kRight = "tests/data/calibration/opencv_stereo/right*.jpg";

// The plain two-stage OpenCV calibration (classic detector + cornerSubPix, calibrateCamera per camera,
// stereoCalibrate with the intrinsics fixed) measured 0.448 px on these 13 pairs (issue 8); a joint one-stage
// call measured 0.634 px.
constexpr double kTwoStageBarPx = 0.448;

StereoCalibrationOptions SampleOptions() {
  StereoCalibrationOptions o;
  o.board.cols = 9;
  o.board.rows = 6;
  o.board.square_m = 0.025;
  return o;
}

const CalibrationView& Worst(const StereoCalibrationSummary& s) {
  return *std::max_element(s.views.begin(), s.views.end(),
                           [](const auto& a, const auto& b) { return a.rms_stereo_px < b.rms_stereo_px; });
}

TEST(PairCalibrationImages, PairsOpenCvSamplesByNumber) {
  std::vector<std::string> unpaired;
  const auto pairs = PairCalibrationImages({kLeft}, {kRight}, &unpaired);
  ASSERT_EQ(pairs.size(), 13u);
  EXPECT_TRUE(unpaired.empty());
  EXPECT_NE(pairs[1].left.find("left02.jpg"), std::string::npos);
  EXPECT_NE(pairs[1].right.find("right02.jpg"), std::string::npos);
  EXPECT_NE(pairs[9].left.find("left11.jpg"), std::string::npos);
  EXPECT_NE(pairs[9].right.find("right11.jpg"), std::string::npos);
}

TEST(PairCalibrationImages, PatternWithoutMatchNamesIt) {
  try {
    PairCalibrationImages({"tests/data/calibration/nothing*.jpg"}, {kRight});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("nothing*.jpg"), std::string::npos) << e.what();
  }
}

TEST(CalibrateStereoRig, OpenCvSamplesBeatTwoStageBar) {
  // One test for everything that reads the default calibration: CTest runs each test in its own process.
  const auto pairs = PairCalibrationImages({kLeft}, {kRight});
  StereoCalibrationSummary s;
  const StereoRig rig = CalibrateStereoRig(pairs, SampleOptions(), &s);
  std::printf("stereo RMS %.4f px (left %.4f, right %.4f), epipolar mean %.4f max %.4f px, worst view %.4f px\n",
              s.rms_stereo_px, s.rms_left_px, s.rms_right_px, s.epipolar_error_mean_px, s.epipolar_error_max_px,
              Worst(s).rms_stereo_px);
  EXPECT_EQ(s.pairs_found, 13);
  EXPECT_EQ(s.pairs_used, 13);
  // The default (kBest) calibrates with both detectors and keeps the lower stereo RMS: here the
  // sector-based corners, measured 0.273 px (left 0.256, right 0.250) against 0.447 px for the classic ones.
  EXPECT_EQ(s.detector_used, ChessboardDetector::kSectorBased);
  EXPECT_NEAR(s.rms_stereo_sector_based_px, s.rms_stereo_px, 1e-12);
  EXPECT_GT(s.rms_stereo_classic_px, 0.0);
  EXPECT_LE(s.rms_stereo_px, s.rms_stereo_classic_px);
  EXPECT_NEAR(s.rms_stereo_classic_px, 0.447, 0.01);
  EXPECT_LE(s.rms_stereo_px, kTwoStageBarPx);
  EXPECT_LE(s.rms_stereo_px, 0.30);
  EXPECT_NEAR(rig.rms_stereo_px, s.rms_stereo_px, 1e-12);
  // Measured mean |Δy| 0.114 px after rectification.
  EXPECT_LT(s.epipolar_error_mean_px, 0.2);
  // Board in the 640x480 samples: measured fx 531.9 px, baseline 3.32 squares (OpenCV's sample reports ≈ 3.34).
  EXPECT_NEAR(rig.K_left(0, 0), 532.0, 10.0);
  EXPECT_NEAR(rig.baseline_m() / 0.025, 3.33, 0.1);
  EXPECT_GT(rig.P1(0, 0), 0.0);
  EXPECT_GT(s.coverage_left, 0.3);
  EXPECT_GT(s.grid_coverage_left, 0.5);
  // With good corners no view is far above the rest.
  for (const auto& v : s.views) EXPECT_FALSE(v.flagged) << v.left << " " << v.rms_stereo_px;
  EXPECT_FALSE(s.right_camera_on_the_left);
  EXPECT_EQ(s.BriefReport().find("swapped"), std::string::npos);

  // rig.yaml round trip.
  {
    const TempDir dir("calibration");
    const std::string path = (fs::path(dir.path()) / "rig.yaml").string();
    WriteStereoRig(rig, path);
    const StereoRig back = ReadStereoRig(path);
    EXPECT_TRUE(back.K_left.isApprox(rig.K_left));
    EXPECT_TRUE(back.P2.isApprox(rig.P2));
    EXPECT_EQ(back.distortion_left.size(), 5);
    EXPECT_NEAR(back.epipolar_error_px, rig.epipolar_error_px, 1e-9);
    ASSERT_EQ(back.view_rms_stereo_px.size(), 13u);
    EXPECT_EQ(back.view_names[1], "left02.jpg");
    // Readable by plain OpenCV code as well.
    cv::FileStorage fsr(path, cv::FileStorage::READ);
    cv::Mat K;
    fsr["K_left"] >> K;
    EXPECT_NEAR(K.at<double>(0, 0), rig.K_left(0, 0), 1e-9);
  }

  const RgbImage img = RenderRectifiedPair(rig, pairs[0]);
  EXPECT_EQ(img.width, 1280);
  EXPECT_EQ(img.height, 480);
}

TEST(CalibrateStereoRig, ClassicCornersFlagPair02AndDroppingItHelps) {
  const auto pairs = PairCalibrationImages({kLeft}, {kRight});
  StereoCalibrationOptions o = SampleOptions();
  o.board.detector = ChessboardDetector::kClassic;
  StereoCalibrationSummary s;
  CalibrateStereoRig(pairs, o, &s);
  // This is exactly the two-stage method behind the bar: measured 0.4469 px.
  EXPECT_LE(s.rms_stereo_px, kTwoStageBarPx + 0.002);
  const CalibrationView& worst = Worst(s);
  EXPECT_NE(worst.left.find("left02.jpg"), std::string::npos);
  EXPECT_TRUE(worst.flagged);
  int flagged = 0;
  for (const auto& v : s.views) flagged += v.flagged;
  EXPECT_EQ(flagged, 1);  // measured: pair 02 at 1.22 px, the next 0.51 px, threshold 0.55 px

  o.drop_outliers = true;
  StereoCalibrationSummary dropped;
  CalibrateStereoRig(pairs, o, &dropped);
  std::printf("classic corners: stereo RMS %.4f px, after dropping %d flagged: %.4f px\n", s.rms_stereo_px,
              13 - dropped.pairs_used, dropped.rms_stereo_px);
  EXPECT_EQ(dropped.pairs_used, 12);
  EXPECT_NEAR(dropped.rms_stereo_all_px, s.rms_stereo_px, 1e-9);
  EXPECT_LT(dropped.rms_stereo_px, s.rms_stereo_px - 0.05);
  EXPECT_TRUE(dropped.views[1].dropped);
  EXPECT_FALSE(dropped.views[1].used);
}

// The rational distortion model on the same pairs: the stereo step read only five of its eight coefficients (stereo
// RMS 2e10 px, mean epipolar error 118 px, and the rig was written). Measured with all eight: 0.279 px, as the
// five-coefficient model's 0.273 px.
TEST(CalibrateStereoRig, RationalModelGivesAUsableRig) {
  const auto pairs = PairCalibrationImages({kLeft}, {kRight});
  StereoCalibrationOptions o = SampleOptions();
  o.rational_model = true;
  StereoCalibrationSummary s;
  const StereoRig rig = CalibrateStereoRig(pairs, o, &s);
  EXPECT_GE(rig.distortion_left.size(), 8);  // k1 k2 p1 p2 k3 k4 k5 k6 (OpenCV may return its 14-slot vector)
  EXPECT_LE(s.rms_stereo_px, 0.35);
  EXPECT_LT(s.epipolar_error_mean_px, 0.2);
  EXPECT_NEAR(rig.baseline_m() / 0.025, 3.33, 0.1);
  EXPECT_EQ(CalibrationProblem(s, o), "");
}

// Left and right given the wrong way round calibrate just as well, with the right camera on the left: the report says
// so (stereo then matched a quarter of the pixels instead of half, without a word).
TEST(CalibrateStereoRig, SwappedImagesAreNamed) {
  StereoCalibrationOptions o = SampleOptions();
  o.board.detector = ChessboardDetector::kSectorBased;
  StereoCalibrationSummary s;
  CalibrateStereoRig(PairCalibrationImages({kRight}, {kLeft}), o, &s);
  EXPECT_TRUE(s.right_camera_on_the_left);
  EXPECT_NE(s.BriefReport().find("are --left and --right swapped?"), std::string::npos) << s.BriefReport();
}

// A calibration above the limit (one right view turned upside down: its corners are matched to the wrong board
// corners) is named with what to try, and flagged views point to --drop-outliers.
TEST(CalibrateStereoRig, AnUnusableCalibrationIsNamed) {
  const TempDir dir("calibration_unusable");
  auto pairs = PairCalibrationImages({kLeft}, {kRight});
  cv::Mat turned;
  cv::rotate(cv::imread(pairs[4].right), turned, cv::ROTATE_180);
  pairs[4].right = (fs::path(dir.path()) / "right05.png").string();
  ASSERT_TRUE(cv::imwrite(pairs[4].right, turned));
  StereoCalibrationOptions o = SampleOptions();
  StereoCalibrationSummary s;
  CalibrateStereoRig(pairs, o, &s);
  std::printf("one view turned: stereo RMS %.3f px, epipolar mean %.3f px\n", s.rms_stereo_px,
              s.epipolar_error_mean_px);
  const std::string problem = CalibrationProblem(s, o);
  EXPECT_NE(problem.find("not usable: stereo RMS"), std::string::npos) << problem;
  EXPECT_NE(problem.find("--drop-outliers"), std::string::npos) << problem;
  o.max_rms_px = std::numeric_limits<double>::infinity();
  EXPECT_EQ(CalibrationProblem(s, o), "");
  o.max_rms_px = 0.0;
  EXPECT_THROW(o.Check(), Error);
}

TEST(CalibrateStereoRig, SkipsPairsWithoutBoardAndNeedsMinimum) {
  const TempDir dir("calibration");
  const fs::path src = "tests/data/calibration/opencv_stereo";
  for (const char* n : {"01", "03", "04", "06"}) {
    fs::copy_file(src / (std::string("left") + n + ".jpg"), fs::path(dir.path()) / (std::string("left") + n + ".jpg"));
    fs::copy_file(src / (std::string("right") + n + ".jpg"),
                  fs::path(dir.path()) / (std::string("right") + n + ".jpg"));
  }
  cv::imwrite((fs::path(dir.path()) / "left20.jpg").string(), cv::Mat(480, 640, CV_8U, cv::Scalar(128)));
  fs::copy_file(src / "right11.jpg", fs::path(dir.path()) / "right20.jpg");
  const auto pairs = PairCalibrationImages({(fs::path(dir.path()) / "left*.jpg").string()},
                                           {(fs::path(dir.path()) / "right*.jpg").string()});
  ASSERT_EQ(pairs.size(), 5u);
  StereoCalibrationOptions o = SampleOptions();
  o.board.detector = ChessboardDetector::kClassic;  // fast on the blank image
  StereoCalibrationSummary s;
  try {
    CalibrateStereoRig(pairs, o, &s);
    FAIL() << "expected an error: 4 usable pairs, minimum 5";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("at least 5"), std::string::npos) << e.what();
  }
  o.min_pairs = 4;
  CalibrateStereoRig(pairs, o, &s);
  EXPECT_EQ(s.pairs_used, 4);
  ASSERT_EQ(s.views.size(), 5u);
  EXPECT_FALSE(s.views[4].used);
  EXPECT_EQ(s.views[4].skip_reason, "board not found in the left image");
}

// Images too small to hold the board are pairs without it (OpenCV's classic detector asserted on them).
// A chessboard of 2 inner corners a side stopped with OpenCV's assertion text; both detectors need 3.
TEST(BoardSpec, TwoCornersASideAreTooFew) {
  BoardSpec board;
  board.cols = 2;
  board.rows = 5;
  try {
    board.Check();
    ADD_FAILURE() << "a 2x5 board was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("2x5 is too small (each side ≥ 3)"), std::string::npos) << e.what();
  }
  board.cols = 3;
  EXPECT_NO_THROW(board.Check());
}

TEST(CalibrateStereoRig, TinyImagesShowNoBoard) {
  const TempDir dir("calibration");
  cv::Mat tiny(12, 12, CV_8U);
  cv::randu(tiny, 0, 255);
  for (const char* n : {"01", "02", "03", "04", "05"}) {
    cv::imwrite((fs::path(dir.path()) / (std::string("left") + n + ".png")).string(), tiny);
    cv::imwrite((fs::path(dir.path()) / (std::string("right") + n + ".png")).string(), tiny);
  }
  const auto pairs = PairCalibrationImages({(fs::path(dir.path()) / "left*.png").string()},
                                           {(fs::path(dir.path()) / "right*.png").string()});
  ASSERT_EQ(pairs.size(), 5u);
  for (ChessboardDetector detector : {ChessboardDetector::kClassic, ChessboardDetector::kSectorBased}) {
    StereoCalibrationOptions o = SampleOptions();
    o.board.detector = detector;
    try {
      CalibrateStereoRig(pairs, o);
      ADD_FAILURE() << "a rig was calibrated from 12 px images";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("only 0 of 5 image pairs show the board"), std::string::npos) << e.what();
    }
  }
}

// A ChArUco board with an unknown dictionary: the error names it (a build without the aruco module says that
// instead, which is the other clean report).
TEST(BoardSpec, CharucoAvailabilityIsReportedCleanly) {
  StereoCalibrationOptions o = SampleOptions();
  o.board.type = BoardType::kCharuco;
  o.board.cols = 5;
  o.board.rows = 7;
  o.board.dictionary = "DICT_NOPE";
  try {
    CalibrateStereoRig(PairCalibrationImages({kLeft}, {kRight}), o);
    ADD_FAILURE() << "an unknown dictionary was accepted";
  } catch (const Error& e) {
    const std::string expected = CharucoAvailable()
                                     ? "ChArUco dictionary 'DICT_NOPE' is not known (use an OpenCV name such as "
                                       "DICT_4X4_50, DICT_5X5_100, DICT_6X6_250)"
                                     : "ChArUco boards need OpenCV's aruco module";
    EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
  }
}

#ifdef RB_HAVE_ARUCO
// A ChArUco calibration of a rig known by construction: a 5×7 board (40 mm squares, 30 mm markers) drawn by
// OpenCV, seen by two pinhole cameras without distortion (f = 800 px, 640×480, principal point at the centre,
// the right camera 10 cm along +x of the left) from twelve poses 0.45–0.7 m away, tilted up to 30°; each view
// rendered by the board plane's homography. The calibration must find that rig: focal lengths and baseline to
// 1%, the principal point to 10 px (2% of the width: it is the weakly determined part of a calibration, traded
// against the tangential distortion that the 5-coefficient model estimates; measured 2.6 px off here, up to 6.7 px
// with other poses tried), a stereo RMS under 0.5 px (OpenCV's sample chessboards give 0.27 px; measured 0.18 px
// here). Board corners 5% too far apart (a wrong object model) put the baseline 5% off.
TEST(CalibrateStereoRig, CharucoBoardOfAKnownRig) {
  const TempDir dir("charuco_rig");
  const double square_m = 0.04, marker_m = 0.03, f_px = 800, baseline_m = 0.1;
  const int cols = 5, rows = 7, width = 640, height = 480, board_px_per_m = 5000;
  const cv::Ptr<cv::aruco::CharucoBoard> board =
      cv::aruco::CharucoBoard::create(cols, rows, static_cast<float>(square_m), static_cast<float>(marker_m),
                                      cv::aruco::getPredefinedDictionary(cv::aruco::DICT_4X4_50));
  cv::Mat picture;
  board->draw(
      cv::Size(static_cast<int>(cols * square_m * board_px_per_m), static_cast<int>(rows * square_m * board_px_per_m)),
      picture, 0, 1);
  Eigen::Matrix3d K;
  K << f_px, 0, width / 2.0, 0, f_px, height / 2.0, 0, 0, 1;
  // Board pixel (u, v) is the point (u, v, 0) / board_px_per_m of the board plane, centred on the board.
  Eigen::Matrix3d board_from_picture;
  board_from_picture << 1.0 / board_px_per_m, 0, -cols * square_m / 2, 0, 1.0 / board_px_per_m, -rows * square_m / 2, 0,
      0, 1;
  const double tilts_deg[][3] = {{0, 0, 0},      {30, 0, 5},    {-30, 0, -5},   {0, 30, 10},
                                 {0, -30, -10},  {25, 25, 30},  {-25, 20, -20}, {20, -25, 15},
                                 {-20, -25, 40}, {30, 10, -35}, {10, 30, 60},   {-15, -30, -50}};
  const int views = static_cast<int>(std::size(tilts_deg));
  std::vector<CalibrationImagePair> pairs;
  for (int k = 0; k < views; ++k) {
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(tilts_deg[k][0] * M_PI / 180, Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(tilts_deg[k][1] * M_PI / 180, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(tilts_deg[k][2] * M_PI / 180, Eigen::Vector3d::UnitZ()))
                                  .toRotationMatrix();
    const Eigen::Vector3d t_left(0.1 * (k % 2) - 0.05, 0.02 * (k % 3) - 0.02, 0.45 + 0.02 * k);
    for (const bool right : {false, true}) {
      // The right camera at x = +baseline in the left frame: p_right = p_left − (baseline, 0, 0).
      const Eigen::Vector3d t = t_left - (right ? Eigen::Vector3d(baseline_m, 0, 0) : Eigen::Vector3d::Zero());
      Eigen::Matrix3d plane;
      plane << R.col(0), R.col(1), t;
      const Eigen::Matrix3d H = K * plane * board_from_picture;
      cv::Mat H_cv(3, 3, CV_64F);
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) H_cv.at<double>(i, j) = H(i, j);
      cv::Mat view;
      cv::warpPerspective(picture, view, H_cv, cv::Size(width, height), cv::INTER_AREA, cv::BORDER_CONSTANT,
                          cv::Scalar(128));
      const std::string path =
          (fs::path(dir.path()) / ((right ? "right" : "left") + std::to_string(k) + ".png")).string();
      cv::imwrite(path, view);
      (right ? pairs.back().right : (pairs.emplace_back(), pairs.back().left)) = path;
    }
  }
  StereoCalibrationOptions o;
  o.board.type = BoardType::kCharuco;
  o.board.cols = cols;
  o.board.rows = rows;
  o.board.square_m = square_m;
  o.board.marker_m = marker_m;
  o.board.dictionary = "DICT_4X4_50";
  StereoCalibrationSummary s;
  const StereoRig rig = CalibrateStereoRig(pairs, o, &s);
  std::printf("ChArUco: %d of %d pairs used, stereo RMS %.3f px, f %.2f / %.2f px, c (%.2f, %.2f), baseline %.5f m\n",
              s.pairs_used, views, s.rms_stereo_px, rig.K_left(0, 0), rig.K_right(0, 0), rig.K_left(0, 2),
              rig.K_left(1, 2), rig.baseline_m());
  EXPECT_EQ(s.pairs_used, views);
  EXPECT_LT(s.rms_stereo_px, 0.5);
  for (const Eigen::Matrix3d* k : {&rig.K_left, &rig.K_right}) {
    EXPECT_NEAR((*k)(0, 0), f_px, 0.01 * f_px);
    EXPECT_NEAR((*k)(1, 1), f_px, 0.01 * f_px);
    EXPECT_NEAR((*k)(0, 2), width / 2.0, 10.0);
    EXPECT_NEAR((*k)(1, 2), height / 2.0, 10.0);
  }
  EXPECT_NEAR(rig.baseline_m(), baseline_m, 0.01 * baseline_m);
  EXPECT_NEAR(rig.t_right_from_left_m.x(), -baseline_m, 0.01 * baseline_m);
}
#endif  // RB_HAVE_ARUCO

}  // namespace
}  // namespace rangebayes

namespace rangebayes {
namespace {

// A 320×240 rig of focal length 400 px and a 10 cm baseline, without distortion.
StereoRig SmallRig() {
  StereoRig rig;
  rig.width = 320;
  rig.height = 240;
  rig.K_left << 400, 0, 160, 0, 400, 120, 0, 0, 1;
  rig.K_right = rig.K_left;
  rig.t_right_from_left_m << -0.1, 0, 0;
  return rig;
}

// A rig without distortion (a rectified Middlebury rig, or a synthetic one) writes empty distortion vectors;
// reading the file back must accept them.
TEST(StereoRigYaml, RoundTripWithoutDistortion) {
  StereoRig rig = SmallRig();
  rig.is_rectified = true;
  const std::string path = TempPath("rig_no_distortion.yaml");
  WriteStereoRig(rig, path);
  const StereoRig back = ReadStereoRig(path);
  EXPECT_EQ(back.distortion_left.size(), 0);
  EXPECT_EQ(back.distortion_right.size(), 0);
  EXPECT_EQ(back.width, 320);
  EXPECT_TRUE(back.is_rectified);
  EXPECT_DOUBLE_EQ(back.K_left(0, 0), 400.0);
  EXPECT_DOUBLE_EQ(back.baseline_m(), 0.1);
  std::filesystem::remove(path);
}

// R must be a rotation: a scaled or mirrored matrix bent every depth without a word. Refused when a rig is
// checked (the Rectifier, Python's stereo), written and read (a hand-edited file).
TEST(StereoRigYaml, NonRotationIsRefused) {
  StereoRig rig = SmallRig();
  rig.R_right_from_left = Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitY()).toRotationMatrix();
  EXPECT_NO_THROW(rig.Check());
  const std::string path = TempPath("rig_not_a_rotation.yaml");
  std::filesystem::remove(path);
  for (const Eigen::Matrix3d& bad : {Eigen::Matrix3d(Eigen::Vector3d(1, 1, 0).asDiagonal()),
                                     Eigen::Matrix3d(Eigen::Vector3d(1, 1, -1).asDiagonal())}) {
    StereoRig wrong = rig;
    wrong.R_right_from_left = bad;
    EXPECT_THROW(wrong.Check(), Error);
    EXPECT_THROW(WriteStereoRig(wrong, path), Error);
    EXPECT_FALSE(std::filesystem::exists(path));
  }
  // A distortion vector of a length no OpenCV model has (it failed inside OpenCV's rectification maps with an
  // assertion that named neither the file nor the field).
  for (const int n : {3, 7}) {
    StereoRig wrong = rig;
    wrong.distortion_right = Eigen::VectorXd::Zero(n);
    try {
      wrong.Check();
      ADD_FAILURE() << "no error for " << n << " coefficients";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("D_right has " + std::to_string(n) + " coefficients"), std::string::npos)
          << e.what();
    }
  }
  // A file whose R was edited by hand into a mirror.
  rig.R_right_from_left.setIdentity();
  WriteStereoRig(rig, path);
  std::ifstream in(path);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  in.close();
  const std::string identity = "data: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]";
  const size_t at = text.find(identity, text.find("\nR:"));
  ASSERT_NE(at, std::string::npos) << text;
  text.replace(at, identity.size(), "data: [ 1., 0., 0., 0., 1., 0., 0., 0., -1. ]");
  std::ofstream(path, std::ios::trunc) << text;
  try {
    ReadStereoRig(path);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("R is not a rotation"), std::string::npos) << e.what();
  }
  std::filesystem::remove(path);
}

// A malformed file on which OpenCV's YAML parser throws std::length_error (found by fuzz_rig_yaml; the same
// bytes are the seed fuzz/corpus/rig_yaml/regress_length_error): an Error naming the file.
TEST(StereoRigYaml, FilesThatBreakOpenCvsParserAreErrors) {
  const std::string path = TempPath("rig_length_error.yaml");
  std::ofstream(path, std::ios::binary) << "%YAML:1.0 \n   s:t: d\n   : 3]\n";
  try {
    ReadStereoRig(path);
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  // A file on which OpenCV's YAML parser never returns (found by fuzz_noise_yaml): refused before it parses.
  std::ofstream(path, std::ios::binary | std::ios::trunc) << "%YAML:1.0\n---f: c\nab\n-";
  EXPECT_THROW(ReadStereoRig(path), Error);
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace rangebayes
