// Writes a Middlebury 2014 scene (im0/im1, calib.txt, disp0GT.pfm) as a one-frame recording
// (recordings/README.md): rig.yaml from calib.txt (rectified, with doffs), frame 0, and ground_truth/ with
// the left disparity and the depth Z = f·B / (d + doffs). How recordings/middlebury2014_artl_quarter was made.
//
//   make_middlebury_recording SCENE_FOLDER OUT_FOLDER
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>

#include "bench/bench_main.h"
#include "capture/recording.h"
#include "core/error.h"
#include "stereo/disparity_io.h"
#include "stereo/pfm.h"

namespace rb = rangebayes;

namespace {

int RunBench(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: make_middlebury_recording SCENE_FOLDER OUT_FOLDER\n");
    return 2;
  }
  const rb::MiddleburyScene scene = rb::ReadMiddleburyScene(argv[1]);
  RB_CHECK(scene.layout == "2014" && scene.rig.has_value(), argv[1], ": not a Middlebury 2014 scene with calib.txt");
  RB_CHECK(!scene.gt_disparity_px.empty(), argv[1], ": scene has no disp0GT.pfm");
  const std::string name = std::filesystem::path(argv[1]).filename().string();
  rb::RecordingWriterOptions wo;
  wo.png_compression = 9;
  wo.overwrite = true;
  rb::RecordingWriter writer(argv[2], scene.rig,
                             {{"source", "Middlebury 2014 " + name + " (trainingQ, quarter size)"},
                              {"citation",
                               "D. Scharstein et al., High-resolution stereo datasets with "
                               "subpixel-accurate ground truth, GCPR 2014"},
                              {"num_disparities", std::to_string(scene.num_disparities)}},
                             wo);
  rb::StereoFrame frame;
  frame.left = scene.left;
  frame.right = scene.right;
  writer.Write(frame);
  writer.Finish();
  const std::filesystem::path gt = std::filesystem::path(argv[2]) / "ground_truth";
  std::filesystem::create_directories(gt);
  const rb::StereoRig& rig = *scene.rig;
  const double fb = rig.P1(0, 0) * rig.baseline_m();
  cv::Mat depth(scene.gt_disparity_px.size(), CV_32F);
  for (int y = 0; y < depth.rows; ++y)
    for (int x = 0; x < depth.cols; ++x) {
      const float d = scene.gt_disparity_px.at<float>(y, x);
      depth.at<float>(y, x) = std::isfinite(d) ? static_cast<float>(fb / (d + rig.doffs_px)) : NAN;
    }
  rb::WritePfm(scene.gt_disparity_px, (gt / "disparity_left_px.pfm").string());
  rb::WritePfm(depth, (gt / "depth_left_m.pfm").string());
  std::printf("wrote %s: %dx%d, %d disparities\n", argv[2], scene.left.cols, scene.left.rows, scene.num_disparities);
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return rangebayes::bench::Main("make_middlebury_recording", RunBench, argc, argv); }
