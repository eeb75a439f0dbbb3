// Synthetic stereo recordings of known scenes under projected light, with exact ground truth: the test and
// demo input of the stereo and space-time matchers.
#pragma once

#include <atomic>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "calibration/stereo_rig.h"
#include "core/camera.h"
#include "core/progress.h"

namespace rangebayes {

enum class SynthScene {
  kPlane,     // one fronto-parallel plane at 1.0 m
  kPlanes,    // tilted back wall, floor, a fronto-parallel panel in front
  kBox,       // a box turned 30° about the vertical on the floor before the wall
  kSphere,    // a sphere before the wall
  kCylinder,  // a vertical capped cylinder before the wall
  kStairs,    // four steps rising towards the wall
};
enum class SynthPattern {
  kRandom,    // band-limited random texture, a new one every frame
  kGrayCode,  // vertical Gray-code stripes (projector columns), each bit then its inverse, finest bits last
};

// Parses "plane", "planes", "box", "sphere", "cylinder", "stairs" / "random", "graycode"; throws Error otherwise.
SynthScene ParseSynthScene(const std::string& name);
SynthPattern ParseSynthPattern(const std::string& name);
std::string ToString(SynthScene scene);
std::string ToString(SynthPattern pattern);

struct SynthOptions {
  SynthScene scene = SynthScene::kPlanes;
  SynthPattern pattern = SynthPattern::kRandom;
  int frames = 8;                  // 1–256: stereo pairs, one projected pattern each
  double image_noise_gray = 2.0;   // ≥ 0: σ of the Gaussian noise added to each 8-bit grey level
  std::uint64_t seed = 1;          // patterns and noise; same seed, same images (on one platform)
  int width = 320;                 // 16–4096 pixels
  int height = 240;                // 16–4096 pixels
  double focal_px = 0.0;           // > 0, or 0: equal to the width (53° horizontal field of view)
  double baseline_m = 0.1;         // > 0: right camera at (B, 0, 0) in the left camera frame
  double pattern_cell_px = 2.3;    // 0.5–64: size of one projector pixel (random cell, finest Gray stripe),
                                   // in camera pixels at the image centre
  double projector_roll_deg = 8.0; // ±45: rotation of the projected image about the projector's axis
  double optics_blur_px = 0.5;     // 0–5: σ of the lens blur (Gaussian), camera pixels
  double ambient = 0.08;           // 0–1: light not from the projector (share of full scale)
  int supersample = 3;             // 1–8: samples per pixel side (anti-aliased stripes and edges)
  // Pixel localisation error (docs/design.md §2, σ_px): 0–2 px, 0 off. The left pixel (u, v) is rendered from the
  // ray through (u + δu, v + δv), δ ~ N(0, σ²) per component, fixed for the whole sequence: a residual
  // distortion of the rectified rig that calibration did not capture. The field is smooth (random values
  // on a grid of pixel_jitter_cell_px, interpolated with weights renormalised so each pixel's δ stays
  // exactly N(0, σ²)), and the right camera sees each surface point with the same δ as the left camera,
  // so the disparity stays exact and the reconstructed point errs only across the ray, by Z/f·|δ|: the
  // lateral term of the stereo covariance. The ground truth (depth_m, disparity_px) is that of the
  // jittered ray; pixel_jitter_px holds δ.
  double pixel_jitter_px = 0.0;
  double pixel_jitter_cell_px = 8.0;  // 1–256: correlation length of the jitter field, camera pixels
  void Check() const;
};

// Rectified by construction: both cameras share K (f, principal point at the image centre) and look along
// +z; the projector sits half way between them.
struct SynthRecording {
  std::vector<cv::Mat> left, right;  // CV_8U, height × width, one per frame
  std::vector<int> pattern_ids;
  cv::Mat depth_m;                   // CV_32F ground truth in the left view (Z at the pixel centre), NaN none
  cv::Mat disparity_px;              // CV_32F f·B/Z, NaN none
  cv::Mat pixel_jitter_px;           // CV_32FC2 (δu, δv) per left pixel: its ray passes through (u+δu, v+δv);
                                     // empty when pixel_jitter_px is 0 (the ray through the pixel centre)
  StereoRig rig;                     // is_rectified, P1/P2 filled
  CameraIntrinsics intrinsics;

  // One line: the scene and pattern of `options` (those it was rendered with), frames, size, disparity range.
  std::string BriefReport(const SynthOptions& options) const;
};

// Renders by analytic ray casting (planes, oriented boxes, spheres, capped cylinders), Lambertian shading
// by the projector with cast shadows, supersampled, then noise and 8-bit quantisation.
SynthRecording RenderSynthetic(const SynthOptions& options);

// The recording format of capture/recording.h in FOLDER (rig.yaml, meta.yaml, frames.csv, left/ right/ PNGs) plus
// ground_truth/depth_left_m.pfm and ground_truth/disparity_left_px.pfm (and, with pixel jitter,
// ground_truth/points_left_m.pfm: the true 3-D point of each left pixel's ray, 3-channel). Throws Error when
// FOLDER already holds a recording and `overwrite` is false, or on a write failure.
struct SynthWriteOptions {
  bool overwrite = false;                      // replace a recording in the folder (RecordingWriterOptions)
  std::string overwrite_flag = "--overwrite";  // how the caller sets `overwrite`, named when it is refused
  ProgressCallback progress;                   // WriteSynthetic: after each frame (stage "frames")
  const std::atomic<bool>* stop = nullptr;     // WriteSynthetic: polled between frames (e.g. &StopFlag())
  void Check() const {}
};

// Writes a rendered recording.
void WriteSyntheticRecording(const SynthRecording& recording, const SynthOptions& options, const std::string& folder,
                             const SynthWriteOptions& write_options = {});

// Renders and writes frame by frame, holding one frame in memory; the ground truth is written first. On a stop
// request the recording is finished with the frames written so far (meta.yaml: `frames` and `stopped` say how
// many of how many). Returns the recording without its images: pattern_ids holds one id per frame written.
SynthRecording WriteSynthetic(const SynthOptions& options, const std::string& folder,
                              const SynthWriteOptions& write_options = {});

}  // namespace rangebayes
