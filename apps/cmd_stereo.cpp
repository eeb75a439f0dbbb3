// Subcommands stereo, spacetime, synth and eval-depth: from image pairs and sequences to disparity, depth,
// σ and meshes, and scoring disparities against ground truth.
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <string>
#include <vector>

#include "apps/command.h"
#include "apps/flags.h"
#include "apps/progress.h"
#include "calibration/disparity_noise_model.h"
#include "calibration/stereo_rig.h"
#include "capture/recording.h"
#include "capture/stop_signal.h"
#include "core/error.h"
#include "core/files.h"
#include "core/mesh_io.h"
#include "pipeline/png.h"
#include "reconstruction/triangulate.h"
#include "stereo/colormap.h"
#include "stereo/depth_frame.h"
#include "stereo/disparity_features.h"
#include "stereo/disparity_io.h"
#include "stereo/evaluate.h"
#include "stereo/pfm.h"
#include "stereo/rectify.h"
#include "stereo/sgbm_matcher.h"
#include "stereo/spacetime_matcher.h"
#include "stereo/synth.h"

namespace rangebayes::apps {
namespace {

namespace fs = std::filesystem;

struct MatchCliOptions {
  int min_disparity_px = 0;
  int num_disparities = 64;
  int window_px = 0;              // 0: the base options' window (5 for stereo; by T for spacetime)
  std::string cost = "auto";
  double image_noise_gray = 2.0;
  double sigma_floor_px = -1.0;  // < 0: the matcher's fitted default
  double sigma_scale = -1.0;
  double max_sigma_px = 0.0;
  int downsample = 1;
  double max_jump_sigma = 6.0;
  int subpixel_iterations = -1;   // < 0: the base options' (SpaceTimeMatcherOptions{} or the static preset)
  double edge_reject_px = -1.0;   // < 0: the base options' (off in both)
  double doubtful_jump_px = std::numeric_limits<double>::quiet_NaN();  // NaN: the base options' 
  bool no_mesh = false;
  bool quiet = false;
  std::string noise_model;  // noise.yaml from `rangebayes calibrate noise`
  std::optional<DisparityNoiseModel> model;  // noise_model as read once by ReadNoiseModelOption
};

// Reads --noise-model once, before any image is read (a broken file fails first).
void ReadNoiseModelOption(MatchCliOptions* o) {
  if (!o->noise_model.empty()) o->model = ReadDisparityNoiseModel(o->noise_model);
}

// by_frames: the defaults are SpaceTimeStaticSceneOptions(T) (spacetime), else SpaceTimeMatcherOptions{}.
void AddMatchOptions(CLI::App* sub, MatchCliOptions* o, bool by_frames) {
  // stereo: these options set our block matcher (--matcher block); OpenCV's SGBM has no such setting.
  const auto block = [by_frames](std::string text) {
    if (by_frames) {
      text[0] = static_cast<char>(std::toupper(static_cast<unsigned char>(text[0])));
      return text;
    }
    return "--matcher block: " + text;
  };
  sub->add_option("--min-disparity", o->min_disparity_px, "Smallest disparity searched (px)");
  sub->add_option("--num-disparities", o->num_disparities,
                  by_frames ? "Number of disparities searched (px, 3-1024)"
                            : "Number of disparities searched (px, 3-1024; sgbm searches the next multiple of 16)")
      ->check(CLI::Range(3, 1024));
  AddWindowOption(sub, &o->window_px,
                  by_frames ? "0: the default, 7 for T < 16 frames, 5 for T >= 16" : "0: the default, 5; sgbm 1-11", 0);
  sub->add_option("--image-noise", o->image_noise_gray,
                  block("image noise sigma_n for the disparity sigma (grey levels, > 0)"))
      ->check(PositiveReal());
  sub->add_option(
         "--sigma-floor", o->sigma_floor_px,
         block(std::string("disparity sigma floor (px): sigma = sqrt(floor^2 + (k*pred)^2); < 0: the fitted default ") +
               (by_frames ? "0.01 (0.03 with --subpixel-iterations 0)" : "0.03 (0.01 with --subpixel-iterations > 0)")))
      ->default_str(by_frames ? "0.01" : "0.03");
  sub->add_option(
         "--sigma-scale", o->sigma_scale,
         block(std::string("disparity sigma scale k (unitless); < 0: the fitted default ") +
               (by_frames ? "1.8 (1.7 with --subpixel-iterations 0)" : "1.7 (1.8 with --subpixel-iterations > 0)")))
      ->default_str(by_frames ? "1.8" : "1.7");
  sub->add_option("--max-sigma", o->max_sigma_px, "Drop pixels whose disparity sigma exceeds this (px; 0: keep all)")
      ->check(NonNegativeReal());
  sub->add_option("--subpixel-iterations", o->subpixel_iterations,
                  block("Gauss-Newton sub-pixel steps after the parabola (0-5; 0: parabola only, fastest)"))
      ->check(CLI::Range(0, 5))
      ->default_str(by_frames ? "1" : "0");
  sub->add_option("--edge-reject", o->edge_reject_px,
                  block("drop pixels within w/2+1 px of a hole or of a disparity jump larger than this per px of "
                        "distance (px/px; < 0: off, the default)"));
  sub->add_option(
         "--doubtful-jump", o->doubtful_jump_px,
         block(std::string("keep such pixels instead where a small window confirms them (") +
               (by_frames ? "5x5xT, 3x3xT at T >= 16" : "3x3") +
               "), with sigma_d^2 + 1 px^2 + the jump^2 (px/px; < 0: off" + (by_frames ? ")" : ", the default)")))
      ->default_str(by_frames ? "1" : "");
  sub->add_option("--downsample", o->downsample, "Mesh: use every n-th pixel (1-64)")->check(CLI::Range(1, 64));
  sub->add_option("--max-jump-sigma", o->max_jump_sigma,
                  "Mesh: cut edges whose depth jump exceeds this many depth sigmas (plus a slope allowance; > 0)")
      ->check(PositiveReal());
  sub->add_flag("--no-mesh", o->no_mesh, "Do not write mesh.ply");
  sub->add_option("--noise-model", o->noise_model,
                  "noise.yaml from 'rangebayes calibrate noise': replaces --sigma-floor/--sigma-scale (and the sigma_d "
                  "of matchers without one); a learned model (--target ground-truth) gives every pixel its sigma_d; "
                  "a model of another matcher or (learned) resolution is an error");
  AddQuietFlag(sub, &o->quiet);
}

SpaceTimeCost ParseCost(const std::string& name) {
  if (name == "auto") return SpaceTimeCost::kAuto;
  if (name == "ssd") return SpaceTimeCost::kSsd;
  if (name == "zncc") return SpaceTimeCost::kZnccTime;
  if (name == "zncc-space") return SpaceTimeCost::kZnccSpace;
  UsageError("--cost must be auto, ssd, zncc or zncc-space, not '" + name + "'");
}

// base: SpaceTimeMatcherOptions{} or SpaceTimeStaticSceneOptions(T); the flags given replace its fields.
SpaceTimeMatcherOptions BlockOptions(const MatchCliOptions& o, const SpaceTimeMatcherOptions& base) {
  SpaceTimeMatcherOptions m = base;
  m.min_disparity_px = o.min_disparity_px;
  m.num_disparities = o.num_disparities;
  if (o.window_px > 0) m.window_px = o.window_px;
  m.cost = ParseCost(o.cost);
  m.image_noise_gray = o.image_noise_gray;
  if (o.subpixel_iterations >= 0) SetSubpixelIterations(o.subpixel_iterations, &m);
  if (o.sigma_floor_px >= 0.0) m.sigma_floor_px = o.sigma_floor_px;
  if (o.sigma_scale >= 0.0) m.sigma_scale = o.sigma_scale;
  m.max_sigma_disparity_px = o.max_sigma_px;
  if (o.edge_reject_px >= 0.0) m.edge_reject_jump_px = o.edge_reject_px;
  if (std::isfinite(o.doubtful_jump_px)) m.doubtful_jump_px = o.doubtful_jump_px;
  if (o.model) ApplyDisparityNoiseModel(*o.model, &m);
  return m;
}

// --noise-model: refuses a model of another matcher or (learned form) resolution; a learned model replaces the
// disparity's σ_d by its own, from the frames and the disparity; a constant one gives SGBM (which has none) its
// σ_d, so that sigma_disparity.pfm and sigma_depth.pfm hold what the mesh uses. --max-sigma is applied to a σ_d
// given here (the block matcher applies it to its own while matching; SGBM has none until a model gives one).
void ApplyNoiseModelAfterMatch(const MatchCliOptions& o, const std::string& matcher, const std::vector<cv::Mat>& left,
                               const std::vector<cv::Mat>& right, DisparityResult* result) {
  bool given_here = false;
  if (o.model) {
    const DisparityNoiseModel& model = *o.model;
    model.CheckApplicable(matcher, result->disparity_px.cols, o.noise_model);
    if (model.form == NoiseForm::kLearned) {
      result->sigma_disparity_px = LearnedDisparitySigma(model, matcher, left, right, result->disparity_px,
                                                         o.noise_model, &result->edge_sigma_disparity_px);
      given_here = true;
    } else if (model.form == NoiseForm::kConstant && result->sigma_disparity_px.empty()) {
      const cv::Mat valid = result->disparity_px == result->disparity_px;
      result->sigma_disparity_px =
          cv::Mat(result->disparity_px.size(), CV_32F, cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
      result->sigma_disparity_px.setTo(model.sigma_px, valid);
      given_here = true;
    }
  }
  if (o.max_sigma_px > 0 && given_here) DropAboveSigma(o.max_sigma_px, result);
}

void WritePicture(const cv::Mat& image, const fs::path& path, bool reverse) {
  ColorMapOptions c;
  c.reverse = reverse;
  WritePng(ColorMap(image, c), path.string());
}

// Writes the data files, the pictures and (with a rig) depth and the mesh. Prints one summary line.
void WriteOutputs(const DisparityResult& result, const std::optional<Rectifier>& rectifier, std::int64_t frame_id,
                  std::int64_t timestamp_ns, const fs::path& out, const MatchCliOptions& o) {
  CreateFolder(out.string());
  WritePfm(result.disparity_px, (out / "disparity.pfm").string());
  WritePicture(result.disparity_px, out / "disparity.png", false);
  if (!result.sigma_disparity_px.empty()) {
    WritePfm(result.sigma_disparity_px, (out / "sigma_disparity.pfm").string());
    WritePicture(result.sigma_disparity_px, out / "sigma_disparity.png", false);
  }
  std::printf("%s\n", result.BriefReport().c_str());
  const int searched = result.num_disparities_searched > 0 ? result.num_disparities_searched : o.num_disparities;
  if (searched != o.num_disparities) {
    Notice(o.quiet, StrCat("searched ", searched, " disparities (", o.min_disparity_px, " to ",
                           o.min_disparity_px + searched - 1, " px), not ", o.num_disparities,
                           ": SGBM searches multiples of 16"));
  }
  if (result.range_end_fraction >= kRangeEndWarning) {
    char share[32];
    std::snprintf(share, sizeof(share), "%.1f%%", 100.0 * result.range_end_fraction);
    Notice(o.quiet, StrCat("warning: ", share, " of the pixels matched best at an end of the disparities searched (",
                           o.min_disparity_px, " to ", o.min_disparity_px + searched - 1, " px): ", RangeEndAdvice()));
  }
  if (!rectifier) {
    Notice(o.quiet, "no rig given: wrote disparity only (no depth, no mesh)");
    return;
  }
  DepthFrame frame =
      DepthFromDisparity(result, rectifier->intrinsics(), rectifier->baseline_m(), rectifier->doffs_px());
  frame.frame_id = frame_id;
  frame.timestamp_ns = timestamp_ns;
  WritePfm(frame.depth_m, (out / "depth.pfm").string());
  WritePfm(frame.sigma_depth_m, (out / "sigma_depth.pfm").string());
  WritePicture(frame.depth_m, out / "depth.png", true);
  WritePicture(frame.sigma_depth_m, out / "sigma_depth.png", false);
  if (o.no_mesh) return;
  TriangulateOptions t;
  t.downsample = o.downsample;
  t.max_jump_sigma = o.max_jump_sigma;
  if (o.model) ApplyDisparityNoiseModel(*o.model, &t);
  TriangulateSummary ts;
  const NoisyMesh mesh = TriangulateDepth(frame, t, &ts);
  WriteNoisyMesh(mesh, (out / "mesh.ply").string());
  std::printf("%s\n", ts.BriefReport().c_str());
}

// The pair as stored; an alpha channel is dropped.
cv::Mat ReadStereoImage(const std::string& path) {
  cv::Mat image = ReadImage(path, cv::IMREAD_UNCHANGED);
  if (image.channels() == 4) cv::cvtColor(image, image, cv::COLOR_BGRA2BGR);
  return image;
}

void AddStereo(CLI::App& app) {
  struct Opts {
    std::string left, right, rig, out, matcher = "sgbm";
    MatchCliOptions m;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = app.add_subcommand("stereo", "Match one stereo pair: disparity, depth, sigma, pictures and mesh");
  sub->add_option("LEFT", o->left, "Left image")->required();
  sub->add_option("RIGHT", o->right, "Right image")->required();
  sub->add_option("--rig", o->rig, "Rig YAML (rangebayes calibrate); without it only the disparity is written");
  sub->add_option("--out,-o", o->out, "Output folder")->required();
  sub->add_option("--matcher", o->matcher, "sgbm (OpenCV SGBM 3-way) or block (our block matcher with sigma)")
      ->check(CLI::IsMember({"sgbm", "block"}));
  AddMatchOptions(sub, &o->m, false);
  sub->add_option("--cost", o->m.cost, "Block matcher cost: auto (ssd for one frame), ssd, zncc (over time) or zncc-space (local normalisation)");
  sub->callback([o, sub] {
    if (o->matcher == "sgbm") {
      if (o->m.max_sigma_px > 0 && o->m.noise_model.empty()) {
        UsageError("--max-sigma needs a sigma_d: SGBM has none; give --noise-model or use --matcher block");
      }
      // Options of our block matcher: OpenCV's SGBM has no such setting (they were read and ignored).
      for (const char* block_only : {"--cost", "--image-noise", "--sigma-floor", "--sigma-scale",
                                     "--subpixel-iterations", "--edge-reject", "--doubtful-jump"}) {
        if (sub->count(block_only) > 0) UsageError(std::string(block_only) + " applies to --matcher block, not sgbm");
      }
      CheckSgbmWindow(o->m.window_px);
    }
    ReadNoiseModelOption(&o->m);
    cv::Mat left = ReadStereoImage(o->left), right = ReadStereoImage(o->right);
    RB_CHECK(left.size() == right.size(), o->left, " is ", left.cols, "x", left.rows, " but ", o->right, " is ",
             right.cols, "x", right.rows);
    RB_CHECK(left.type() == right.type(), o->left, " and ", o->right, " differ in type (channels or bit depth)");
    std::optional<Rectifier> rectifier;
    if (!o->rig.empty()) {
      const StereoRig rig = ReadStereoRig(o->rig);
      rectifier.emplace(rig);
      cv::Mat l, r;
      rectifier->Rectify(left, right, &l, &r);
      left = l;
      right = r;
    }
    std::unique_ptr<StereoMatcher> matcher;
    if (o->matcher == "sgbm") {
      SgbmMatcherOptions s;
      s.min_disparity_px = o->m.min_disparity_px;
      s.num_disparities = o->m.num_disparities;
      if (o->m.window_px > 0) s.block_size_px = o->m.window_px;
      matcher = std::make_unique<SgbmMatcher>(s);
    } else {
      matcher = std::make_unique<SpaceTimeMatcher>(BlockOptions(o->m, SpaceTimeMatcherOptions{}));
    }
    DisparityResult result = matcher->Match({left}, {right});
    ApplyNoiseModelAfterMatch(o->m, o->matcher, {left}, {right}, &result);
    WriteOutputs(result, rectifier, 0, 0, o->out, o->m);
  });
}

void AddSpaceTime(CLI::App& app) {
  struct Opts {
    std::string recording, out;
    int frames = 0;
    int first = 0;
    MatchCliOptions m;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = app.add_subcommand(
      "spacetime", "Space-time stereo of a recording of a static scene: disparity, depth, sigma, pictures and mesh");
  sub->add_option("RECORDING", o->recording, "Recording folder (frames.csv, rig.yaml, left/, right/)")->required();
  sub->add_option("--out,-o", o->out, "Output folder")->required();
  sub->add_option("--frames", o->frames, "Temporal window T (frames; 0: all from --first)")
      ->check(NonNegativeInteger());
  sub->add_option("--first", o->first, "First frame of the window (index into frames.csv)")
      ->check(NonNegativeInteger());
  AddMatchOptions(sub, &o->m, true);
  sub->add_option("--cost", o->m.cost, "Matching cost: auto (zncc over time for T >= 3, else ssd), ssd, zncc or zncc-space");
  sub->callback([o] {
    ReadNoiseModelOption(&o->m);
    RecordingReadSummary rs;
    const Recording rec = OpenRecording(o->recording, &rs);
    RB_CHECK(rec.rig.has_value(), o->recording, ": recording has no rig.yaml (needed for rectification and depth)");
    RB_CHECK(rec.num_frames() > o->first, o->recording, ": --first ", o->first, " but the recording has ",
             rec.num_frames(), " frames");
    const int T = o->frames > 0 ? o->frames : rec.num_frames() - o->first;
    // Without the sum first + T, which passes INT_MAX for --frames 2147483647.
    RB_CHECK(T <= rec.num_frames() - o->first, o->recording, ": frames ", o->first, "..",
             static_cast<std::int64_t>(o->first) + T - 1, " requested but the recording has ", rec.num_frames());
    std::optional<Rectifier> rectifier;
    rectifier.emplace(*rec.rig);
    std::vector<cv::Mat> left, right;
    std::int64_t timestamp = 0, id = 0;
    for (int i = o->first; i < o->first + T; ++i) {
      const StereoFrame f = LoadRecordingFrame(rec, i);
      cv::Mat l, r;
      rectifier->Rectify(f.left, f.right, &l, &r);
      left.push_back(l);
      right.push_back(r);
      timestamp = f.timestamp_ns();
      id = f.index;
    }
    SpaceTimeMatcher matcher(BlockOptions(o->m, SpaceTimeStaticSceneOptions(T)));
    DisparityResult result = matcher.Match(left, right);
    ApplyNoiseModelAfterMatch(o->m, "spacetime", left, right, &result);
    WriteOutputs(result, rectifier, id, timestamp, o->out, o->m);
  });
}

void AddSynth(CLI::App& app) {
  struct Opts {
    std::string scene = "planes", pattern = "random", out;
    SynthOptions s;
    bool overwrite = false;
    bool quiet = false;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = app.add_subcommand(
      "synth", "Render a synthetic rectified stereo recording of a known scene under projected patterns");
  sub->add_option("--scene", o->scene, "plane, planes, box, sphere, cylinder or stairs")
      ->check(CLI::IsMember({"plane", "planes", "box", "sphere", "cylinder", "stairs"}));
  sub->add_option("--pattern", o->pattern, "random or graycode")->check(CLI::IsMember({"random", "graycode"}));
  sub->add_option("--frames", o->s.frames, "Number of stereo pairs T (1-256)")->check(CLI::Range(1, 256));
  sub->add_option("--noise", o->s.image_noise_gray, "Image noise sigma (8-bit grey levels)")
      ->check(RealRange(0.0, 100.0));
  sub->add_option("--seed", o->s.seed, "Random seed (patterns and noise)");
  sub->add_option("--width", o->s.width, "Image width (px)")->check(CLI::Range(16, 4096));
  sub->add_option("--height", o->s.height, "Image height (px)")->check(CLI::Range(16, 4096));
  sub->add_option("--focal", o->s.focal_px, "Focal length (px; 0: the image width)")->check(NonNegativeReal());
  sub->add_option("--baseline", o->s.baseline_m, "Baseline (m, > 0)")->check(PositiveReal());
  sub->add_option("--cell", o->s.pattern_cell_px, "Projector pixel size at the image centre (camera px, 0.5-64)")
      ->check(RealRange(0.5, 64.0));
  sub->add_option("--supersample", o->s.supersample, "Samples per pixel side (1-8)")->check(CLI::Range(1, 8));
  sub->add_option("--pixel-jitter", o->s.pixel_jitter_px,
                  "Pixel localisation error sigma (px, 0-2; 0: off): each left pixel's ray is offset by a smooth "
                  "N(0, sigma^2) field common to both cameras; ground_truth/points_left_m.pfm holds the true points")
      ->check(RealRange(0.0, 2.0));
  sub->add_option("--pixel-jitter-cell", o->s.pixel_jitter_cell_px,
                  "Correlation length of the pixel jitter field (px, 1-256)")
      ->check(RealRange(1.0, 256.0));
  sub->add_option("--out,-o", o->out, "Output recording folder")->required();
  sub->add_flag("--overwrite", o->overwrite, "Replace a recording already in the folder");
  AddQuietFlag(sub, &o->quiet);
  sub->callback([o] {
    o->s.scene = ParseSynthScene(o->scene);
    o->s.pattern = ParseSynthPattern(o->pattern);
    InstallStopSignalHandlers();
    ProgressPrinter progress(o->quiet);
    SynthWriteOptions w;
    w.overwrite = o->overwrite;
    w.progress = progress.callback();
    w.stop = &StopFlag();
    const SynthRecording rec = WriteSynthetic(o->s, o->out, w);
    progress.Finish();
    const int written = static_cast<int>(rec.pattern_ids.size());
    RB_CHECK(written > 0, "stopped by request before the first frame (", o->out,
             " holds the ground truth and no frame)");
    if (written < o->s.frames) {
      Notice(false, StrCat("synth: stopped by request after ", written, " of ", o->s.frames, " frames: ", o->out,
                           " holds those frames and the ground truth"));
    }
    std::printf("synth: %s, written to %s\n", rec.BriefReport(o->s).c_str(), o->out.c_str());
  });
}

void AddEvalDepth(CLI::App& app) {
  struct Opts {
    std::string estimate, ground_truth, scene, mask;
    double scale = 1.0, gt_scale = 0.0, estimate_scale = 1.0;
    int mask_value = 255;
    bool json = false;
  };
  auto o = std::make_shared<Opts>();
  CLI::App* sub = app.add_subcommand(
      "eval-depth", "Score a disparity map against ground truth: bad-0.5/1/2/4 and RMS, holes counted both ways");
  sub->add_option("DISPARITY", o->estimate, "Estimated disparity (PFM, or PNG/PGM with --scale)")->required();
  sub->add_option("GROUND_TRUTH", o->ground_truth,
                  "Ground-truth disparity (PFM, or PNG/PGM with --gt-scale), or a Middlebury scene folder");
  sub->add_option("--scene", o->scene, "Middlebury scene folder: ground truth, scale and non-occluded mask from it");
  sub->add_option("--scale", o->scale, "Estimate PNG/PGM: disparity = value / scale (a PFM holds disparities)");
  sub->add_option("--gt-scale", o->gt_scale, "Ground-truth PNG: disparity = value / scale (0: 1 for PFM)")
      ->check(RealRange(0.0, 1e6));
  sub->add_option("--estimate-scale", o->estimate_scale,
                  "Multiply the estimate's disparities by this before scoring (e.g. 0.25 for a map resized to the "
                  "quarter-size ground truth but still in full-size pixels; the sizes must match)")
      ->check(PositiveReal());
  sub->add_option("--mask", o->mask, "Mask image: only pixels equal to --mask-value are scored");
  sub->add_option("--mask-value", o->mask_value, "Mask value of the pixels to score (0-65535)")
      ->check(CLI::Range(0, 65535));
  sub->add_flag("--json", o->json, "Print JSON instead of text");
  sub->callback([o] {
    std::string scene_folder = o->scene;
    if (scene_folder.empty() && !o->ground_truth.empty() && fs::is_directory(o->ground_truth)) {
      scene_folder = o->ground_truth;
    }
    RB_CHECK(!scene_folder.empty() || !o->ground_truth.empty(), "give GROUND_TRUTH or --scene");
    if (!o->scene.empty() && !o->ground_truth.empty()) {
      UsageError("give GROUND_TRUTH or --scene, not both (the scene's ground truth would replace the file)");
    }
    const cv::Mat estimate = ReadDisparityMap(o->estimate, o->scale);
    cv::Mat gt, mask;
    if (!scene_folder.empty()) {
      const MiddleburyScene scene = ReadMiddleburyScene(scene_folder);
      RB_CHECK(!scene.gt_disparity_px.empty(), scene_folder, ": scene has no ground truth");
      gt = scene.gt_disparity_px;
      mask = scene.mask_nonocc;
    } else {
      gt = ReadDisparityMap(o->ground_truth, o->gt_scale > 0 ? o->gt_scale : 1.0);
    }
    if (!o->mask.empty()) mask = ReadMask(o->mask, o->mask_value);
    RB_CHECK(estimate.size() == gt.size(), o->estimate, " is ", estimate.cols, "x", estimate.rows,
             " but the ground truth is ", gt.cols, "x", gt.rows);
    DisparityEvaluationOptions eo;
    eo.estimate_scale = o->estimate_scale;
    const DisparityEvaluation ev = EvaluateDisparity(estimate, gt, mask, eo);
    if (o->json) {
      nlohmann::json j;
      j["evaluated_pixels"] = ev.evaluated_pixels;
      j["coverage"] = ev.coverage;
      j["rms_px"] = ev.rms_px;
      j["mean_abs_px"] = ev.mean_abs_px;
      for (size_t i = 0; i < ev.thresholds_px.size(); ++i) {
        char key[32];
        std::snprintf(key, sizeof key, "bad_%g", ev.thresholds_px[i]);
        j[key] = {{"holes_as_errors", ev.bad_with_holes[i]}, {"holes_excluded", ev.bad_valid_only[i]}};
      }
      std::printf("%s\n", j.dump(2).c_str());
      return;
    }
    std::fputs(ev.BriefReport().c_str(), stdout);
  });
}

}  // namespace

RB_REGISTER_COMMANDS(30, AddStereo);
RB_REGISTER_COMMANDS(31, AddSpaceTime);
RB_REGISTER_COMMANDS(32, AddSynth);
RB_REGISTER_COMMANDS(33, AddEvalDepth);

}  // namespace rangebayes::apps
