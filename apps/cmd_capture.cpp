// Subcommands cameras, record, live and replay: from cameras or recordings through the stereo-to-mesh pipeline.
#include <poll.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "apps/command.h"
#include "apps/flags.h"
#include "apps/progress.h"
#include "bayes/learn_prior_io.h"
#include "calibration/disparity_noise_model.h"
#include "capture/device_list.h"
#include "capture/libcamera_source.h"
#include "capture/playback_source.h"
#include "capture/recorder.h"
#include "capture/recording.h"
#include "capture/stop_signal.h"
#include "capture/tee_source.h"
#include "capture/v4l2_source.h"
#include "console/console.h"
#include "console/protocol.h"
#include "core/error.h"
#include "pipeline/file_sink.h"
#include "pipeline/pipeline.h"
#include "pipeline/pipeline_control.h"

namespace rangebayes::apps {
namespace {

namespace fs = std::filesystem;

// Pipeline settings shared by replay and live.
struct PipelineCli {
  std::string matcher = "sgbm";
  int window_frames = 1;
  int window_step_frames = 0;
  int num_disparities = 64;
  int min_disparity_px = 0;
  int window_px = 5;
  int downsample = 1;
  int stereo_downsample = 0;  // 0: 1, or 2 with --live-path
  bool no_smooth = false;
  double smooth_budget_ms = -1.0;  // < 0: none, or kLiveSmoothBudgetMs with --live-path
  bool no_warm_start = false;
  std::string tolerance = "default";
  std::optional<double> prior_weight;  // empty: ResolvePriorWeight's rule
  std::string prior = PriorKindName(SmoothOptions{}.prior);      // as `smooth --prior` takes it
  mutable std::shared_ptr<const SplinePotential> learned_prior;  // kept alive for the run's SmoothOptions
  int max_iterations = 0;
  bool no_decimate = false;
  bool decimate = false;
  double lambda = DecimateOptions{}.lambda;
  int queue_capacity = 0;  // 0: the preset's (PipelineOptions' 4, or 1 with --live-path)
  bool live_path = false;
  std::string noise_model;  // noise.yaml from `rangebayes calibrate noise`
  int preview_width_px = 0;
  bool no_previews = false;
  bool overwrite = false;
  bool quiet = false;
  std::string ui;            // [ADDR:]PORT of the operator's console; empty: none
  std::string ui_record_dir; // recordings started from the console; empty: OUT/recordings
};

void AddPipelineOptions(CLI::App* sub, PipelineCli* o) {
  sub->add_option("--noise-model", o->noise_model,
                  "noise.yaml from 'rangebayes calibrate noise' (a learned model gives every pixel its sigma_d); "
                  "--matcher spacetime takes models of 'calibrate noise --matcher block' (its configuration over the "
                  "window's frames); a model of another matcher or (learned) resolution fails every frame with an "
                  "error");
  sub->add_option("--matcher", o->matcher,
                  "Stereo matcher: sgbm (OpenCV semi-global) or spacetime (ours, with sigma: the block matcher "
                  "over --window-frames frames, not the static-scene preset of 'rangebayes spacetime')")
      ->check(CLI::IsMember({"sgbm", "spacetime"}));
  sub->add_option("--window-frames", o->window_frames,
                  "Frames per space-time window (1: single-frame stereo; >1 needs --matcher spacetime)")
      ->check(CLI::Range(1, 256));
  sub->add_option("--window-step", o->window_step_frames, "Frames between window starts (0: = window, no overlap)")
      ->check(CLI::Range(0, 256));
  sub->add_option("--num-disparities", o->num_disparities, "Disparities searched (px)")->check(CLI::Range(3, 1024));
  sub->add_option("--min-disparity", o->min_disparity_px, "Smallest disparity searched (px)");
  AddWindowOption(sub, &o->window_px, "default 5; sgbm 1-11", 1);
  sub->add_option("--downsample", o->downsample, "Triangulate every n-th pixel (1-64, full-resolution pixels)")
      ->check(CLI::Range(1, 64));
  sub->add_option("--stereo-downsample", o->stereo_downsample,
                  "Match on the rectified pair shrunk by 1, 2, 4 or 8 (pyrDown; rig and disparity range scaled "
                  "to match; 0: 1, or 2 with --live-path)")
      ->check(CLI::IsMember({0, 1, 2, 4, 8}));
  sub->add_flag("--no-smooth", o->no_smooth, "Skip Bayesian smoothing");
  AddToleranceOption(sub, &o->tolerance);
  AddPriorWeightOption(sub, &o->prior_weight);
  AddPriorOption(sub, &o->prior);
  sub->add_option("--max-iterations", o->max_iterations, "Smoothing iteration cap (0: the tolerance preset's)")
      ->check(NonNegativeInteger());
  sub->add_option("--smooth-budget", o->smooth_budget_ms,
                  "Smoothing time per frame (ms): a deadline; the summary says how far from converged it stopped "
                  "(-1: no budget, or 80 with --live-path)")
      ->check(RealRange(-1.0, 1e3 * kMaxSmoothTimeLimitS));
  sub->add_flag("--no-warm-start", o->no_warm_start,
                "Under a smoothing budget, solve every frame from its measurements instead of starting where the "
                "previous result agrees with them");
  sub->add_flag("--no-decimate", o->no_decimate, "Skip Bayesian decimation");
  sub->add_flag("--decimate", o->decimate,
                "With --live-path: run decimation too (off there by default: over the 2-core frame budget)");
  sub->add_option("--lambda", o->lambda, "Decimation: energy cost of one patch (unitless, > 0)")->check(PositiveReal());
  sub->add_option("--queue", o->queue_capacity, "Items waiting between two stages (1-64; 0: 4, or 1 with --live-path)")
      ->check(CLI::Range(0, 64));
  sub->add_flag("--live-path", o->live_path,
                "Live preview settings: drop the oldest frame when a stage is busy (queues of 1 unless --queue), "
                "match at half resolution, triangulate every 4th pixel, fast smoothing tolerance within an 80 ms "
                "budget, no decimation (overrides --downsample and --tolerance)");
  CLI::Option* preview_width = sub->add_option(
      "--preview-width", o->preview_width_px,
      "Width of each rendered preview panel (px; 0: frame width, or the matched width with --live-path)");
  sub->add_flag("--no-previews", o->no_previews, "Write meshes only (no depth or shaded PNG)")->excludes(preview_width);
  sub->add_flag("--overwrite", o->overwrite,
                "OUT may hold an earlier run's results: they are removed first (without it such a folder is refused)");
  AddQuietFlag(sub, &o->quiet);
  CLI::Option* ui =
      sub->add_option("--ui", o->ui,
                      "Serve the operator's console (a live web page with controls) on [ADDR:]PORT (ADDR default "
                      "127.0.0.1; 0.0.0.0 exposes it to the network); the control token is printed at start; the "
                      "page stays up after the run until Ctrl-C");
  sub->add_option("--ui-record-dir", o->ui_record_dir,
                  "Folder for recordings started from the console (default: OUT/recordings)")
      ->needs(ui);
}

PipelineOptions MakePipelineOptions(const PipelineCli& o) {
  PipelineOptions p;
  p.matcher = o.matcher == "spacetime" ? PipelineMatcher::kSpaceTime : PipelineMatcher::kSgbm;
  if (o.window_frames > 1 && p.matcher != PipelineMatcher::kSpaceTime) {
    UsageError("--window-frames > 1 needs --matcher spacetime");
  }
  if (o.window_step_frames > o.window_frames) UsageError("--window-step must not exceed --window-frames");
  p.window_frames = o.window_frames;
  p.window_step_frames = o.window_step_frames;
  p.sgbm.num_disparities = o.num_disparities;
  p.sgbm.min_disparity_px = o.min_disparity_px;
  if (p.matcher == PipelineMatcher::kSgbm) CheckSgbmWindow(o.window_px);
  p.sgbm.block_size_px = o.window_px;
  p.spacetime.num_disparities = o.num_disparities;
  p.spacetime.min_disparity_px = o.min_disparity_px;
  p.spacetime.window_px = o.window_px;
  p.triangulate.downsample = o.downsample;
  p.stereo_downsample = o.stereo_downsample > 0 ? o.stereo_downsample : 1;
  p.smooth_budget_ms = std::max(0.0, o.smooth_budget_ms);
  p.smooth_warm_start = !o.no_warm_start;
  p.smooth = !o.no_smooth;
  p.smoothing.tolerance = ParseSmoothTolerance(o.tolerance);
  o.learned_prior = ApplySmoothingPrior(o.prior, o.prior_weight, &p.smoothing).potential;
  p.smoothing.max_iterations = o.max_iterations;
  p.decimate = !o.no_decimate;
  p.decimation.lambda = o.lambda;
  if (!o.noise_model.empty()) ApplyDisparityNoiseModel(ReadDisparityNoiseModel(o.noise_model), o.noise_model, &p);
  if (o.live_path) {
    ApplyLivePathPreset(&p);
    // The flags the preset documents as winning over it.
    if (o.stereo_downsample > 0) p.stereo_downsample = o.stereo_downsample;
    if (o.smooth_budget_ms >= 0.0) p.smooth_budget_ms = o.smooth_budget_ms;
    p.decimate = o.decimate && !o.no_decimate;
  }
  if (o.queue_capacity > 0) p.queue_capacity = o.queue_capacity;
  return p;
}

void PrintSummary(const PipelineSummary& s, const std::string& out_dir, bool quiet) {
  if (quiet) return;
  std::fputs(s.BriefReport().c_str(), stderr);
  if (!out_dir.empty()) {
    // What this run wrote: a folder exists once its first file is written (an output that is off has none).
    std::string parts;
    // The shaded pictures' panels: the raw mesh, and the smoothed and decimated ones where those were made (it
    // named three panels on two-panel pictures).
    const auto made = [&](const char* folder) {
      std::error_code ec;
      return std::filesystem::is_directory(std::filesystem::path(out_dir) / folder, ec);
    };
    const std::string shaded = StrCat("shaded/ (raw", made("smoothed") ? " | smoothed" : "",
                                      made("decimated") ? " | decimated" : "", " renderings)");
    for (const auto& [folder, what] : {std::pair<const char*, const char*>{"shaded", shaded.c_str()},
                                       {"depth", "depth/"},
                                       {"raw", "raw/ (PLY)"},
                                       {"smoothed", "smoothed/ (PLY)"},
                                       {"decimated", "decimated/ (OBJ)"}}) {
      std::error_code ec;
      if (std::filesystem::is_directory(std::filesystem::path(out_dir) / folder, ec)) parts += StrCat(what, ", ");
    }
    std::fprintf(stderr, "results in %s: %sresults.csv, summary.json\n", out_dir.c_str(), parts.c_str());
  }
}

// Set when q or the end of stdin ended a step replay.
std::atomic<bool>& StepQuit() {
  static std::atomic<bool> quit{false};
  return quit;
}

// Runs the pipeline with a file sink into out_dir (and the console with --ui), prints the summary, writes
// summary.json, sets the exit code.
void RunToFolder(FrameSource& source, const StereoRig& rig, PipelineOptions options, const PipelineCli& cli,
                 const std::string& out_dir) {
  options.Check();  // before the console or the output folder is made
  std::unique_ptr<PipelineControl> control;
  std::unique_ptr<Console> console;
  if (!cli.ui.empty()) {
    const UiAddress address = ParseUiAddress(cli.ui);
    ConsoleOptions co;
    co.server.address = address.address;
    co.server.port = address.port;
    co.record_root = cli.ui_record_dir.empty() ? (fs::path(out_dir) / "recordings").string() : cli.ui_record_dir;
    co.capture_dir = (fs::path(out_dir) / "captures").string();
    control = std::make_unique<PipelineControl>();
    console = std::make_unique<Console>(co, control.get(), rig, source.Meta());
    options.control = control.get();
    options.on_frame = [c = console.get()](const StereoFrame& frame) { c->OnFrame(frame); };
    // Printed even with --quiet: the operator needs the token to control the run.
    std::fprintf(stderr, "rangebayes: console at %s (control token %s; or open %s#token=%s)\n",
                 console->url().c_str(), console->token().c_str(), console->url().c_str(), console->token().c_str());
    if (!IsLoopbackAddress(address.address)) {
      std::fprintf(stderr,
                   "rangebayes: warning: the console is open to the network on %s: whoever reaches this machine sees "
                   "the camera images and meshes (the controls need the token)\n",
                   address.address.c_str());
    }
    std::fflush(stderr);
  }
  FileSinkOptions sink_options;
  sink_options.preview_width_px = cli.preview_width_px;
  // Live previews are drawn at the matched resolution: a 640-px panel costs 4x the rendering time of a 320-px one.
  if (cli.live_path && cli.preview_width_px == 0) {
    sink_options.preview_width_px = std::max(16, rig.width / options.stereo_downsample);
  }
  if (cli.no_previews) sink_options.depth_png = sink_options.shaded_png = false;
  sink_options.overwrite = cli.overwrite;
  FileSink sink(out_dir, sink_options);
  ProgressPrinter progress(cli.quiet || console != nullptr);
  options.progress = progress.callback();
  InstallStopSignalHandlers();
  options.stop = &StopFlag();
  std::vector<PipelineSink*> sinks = {&sink};
  if (console) sinks.push_back(console.get());
  PipelineSummary summary = RunPipeline(source, rig, options, sinks);
  progress.Finish();
  if (StepQuit().load()) summary.stopped = true;
  if (cli.live_path && !options.decimate && !cli.no_decimate) {
    summary.notices.push_back(
        "live path: decimation is off by default (about 70 ms of CPU per frame on a 640x480 live mesh, which "
        "with the other stages is more than 2 cores give in 100 ms; --decimate turns it on)");
  }
  WritePipelineSummaryJson(summary, (fs::path(out_dir) / "summary.json").string());
  PrintSummary(summary, out_dir, cli.quiet);
  if (console && !StopFlag().load()) {  // (a run stopped by a signal ends here, console and all)
    Notice(cli.quiet, StrCat("run finished; the console stays up at ", console->url(), " until Ctrl-C"));
    while (!StopFlag().load()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  if (!summary.fatal_error.empty()) RB_FAIL(summary.fatal_error);
  RB_CHECK(summary.results > 0 || !summary.stopped, "stopped by request before the first result");
  if (summary.results == 0 && summary.frames_captured + summary.frames_skipped > 0) {
    // The first reason in the error line itself, the rest above: with --quiet nothing is above (the line pointed at
    // notes that were never printed); without errors, the note that says why (a space-time window longer than the
    // recording).
    const std::vector<std::string>& reasons = !summary.errors.empty() ? summary.errors : summary.notices;
    RB_FAIL("no frame went through the pipeline",
            reasons.empty()
                ? std::string()
                : StrCat(": ", reasons.front(),
                         cli.quiet || reasons.size() == 1 ? std::string()
                                                          : StrCat(" (and ", reasons.size() - 1, " more above)")));
  }
  if (summary.failed > 0 || summary.frames_skipped > 0) SetExitCode(3);
}

// Camera options shared by record and live.
struct CameraCli {
  std::string left = "/dev/video0";
  std::string right = "/dev/video2";
  bool side_by_side = false;
  bool libcamera = false;
  int width = 640;
  int height = 480;
  std::optional<double> fps;          // V4L2 only; empty: V4l2CameraOptions' rate
  std::optional<std::string> format;  // V4L2 only; empty: auto
  double tolerance_ms = 10.0;
  int timeout_ms = 2000;
  std::string rig;
};

void AddCameraOptions(CLI::App* sub, CameraCli* o) {
  sub->add_option("--left", o->left, "Left camera: V4L2 device (/dev/videoN) or, with --libcamera, a camera id");
  sub->add_option("--right", o->right, "Right camera: V4L2 device or libcamera id (ignored with --side-by-side)");
  sub->add_flag("--side-by-side", o->side_by_side,
                "One V4L2 device (--left) delivering both views side by side (not with --libcamera)");
  sub->add_flag("--libcamera", o->libcamera, "Use libcamera cameras instead of V4L2 devices");
  sub->add_option("--width", o->width, "Requested image width (px; the closest offered is used)");
  sub->add_option("--height", o->height, "Requested image height (px)");
  sub->add_option("--fps", o->fps, "Requested frame rate (frames/s, default 30; V4L2 only, not with --libcamera)")
      ->check(RealRange(0.1, 1000.0));
  sub->add_option("--format", o->format,
                  "V4L2 pixel format: auto (GREY, YUYV, MJPEG in that order), grey, yuyv, mjpeg (not with --libcamera)")
      ->check(CLI::IsMember({"auto", "grey", "yuyv", "mjpeg"}));
  sub->add_option("--pair-tolerance", o->tolerance_ms, "Largest left/right timestamp difference of a pair (ms)")
      ->check(RealRange(0.001, 1000.0));
  sub->add_option("--timeout", o->timeout_ms, "Camera timeout (ms) before a frame counts as late")
      ->check(CLI::Range(1, 60000));
  sub->add_option("--rig", o->rig, "Calibrated rig (rig.yaml, see rangebayes calibrate)");
}

std::unique_ptr<FrameSource> OpenCameras(const CameraCli& o) {
  FramePairerOptions pairing;
  pairing.tolerance_ns = static_cast<std::int64_t>(o.tolerance_ms * 1e6);
  if (o.libcamera) {
    // LibcameraStereoSource has no frame rate, pixel format or side-by-side mode: the flags would do nothing.
    if (o.side_by_side) UsageError("--side-by-side is for one V4L2 device; --libcamera uses two cameras");
    if (o.fps.has_value()) UsageError("--fps is not supported with --libcamera (the cameras run at their own rate)");
    if (o.format.has_value()) UsageError("--format is a V4L2 pixel format; --libcamera uses the cameras' YUV or R8");
    LibcameraStereoOptions l;
    l.left_camera = o.left.rfind("/dev/", 0) == 0 ? "" : o.left;
    l.right_camera = o.right.rfind("/dev/", 0) == 0 ? "" : o.right;
    l.width = o.width;
    l.height = o.height;
    l.pairing = pairing;
    l.timeout_ms = o.timeout_ms;
    return std::make_unique<LibcameraStereoSource>(l);
  }
  V4l2StereoOptions v;
  v.left_device = o.left;
  v.right_device = o.right;
  v.side_by_side = o.side_by_side;
  v.camera.width = o.width;
  v.camera.height = o.height;
  if (o.fps.has_value()) v.camera.fps = *o.fps;
  const std::string format = o.format.value_or("auto");
  if (format == "grey") v.camera.formats = {FourccGrey()};
  if (format == "yuyv") v.camera.formats = {FourccYuyv()};
  if (format == "mjpeg") v.camera.formats = {FourccMjpeg()};
  v.pairing = pairing;
  v.timeout_ms = o.timeout_ms;
  return std::make_unique<V4l2StereoSource>(RealV4l2SysCalls(), v);
}

void AddCameras(CLI::App& app) {
  auto* sub = app.add_subcommand("cameras", "List V4L2 video devices and libcamera cameras");
  sub->callback([] {
    auto sys = RealV4l2SysCalls();
    const std::vector<V4l2DeviceInfo> devices = ListV4l2Devices(*sys);
    if (devices.empty()) {
      std::printf("V4L2: no video devices (/dev/video*) on this machine\n");
    } else {
      std::printf("V4L2 devices:\n");
      for (const V4l2DeviceInfo& d : devices) {
        if (!d.error.empty()) {
          std::printf("  %s: cannot open (%s)\n", d.path.c_str(), d.error.c_str());
          continue;
        }
        std::string formats;
        for (const std::string& f : d.formats) formats += (formats.empty() ? "" : " ") + f;
        std::printf("  %s: %s (%s, %s)%s%s\n", d.path.c_str(), d.card.c_str(), d.driver.c_str(), d.bus.c_str(),
                    d.can_capture ? " formats: " : " (not a capture device)", formats.c_str());
      }
    }
    const LibcameraList cams = ListLibcameraCameras();
    if (!cams.manager_started) {
      std::printf("libcamera: %s\n", cams.error.c_str());
    } else if (cams.cameras.empty()) {
      std::printf("libcamera: no cameras\n");
    } else {
      std::printf("libcamera cameras:\n");
      for (const LibcameraCameraInfo& c : cams.cameras) {
        std::printf("  %s%s%s\n", c.id.c_str(), c.model.empty() ? "" : ": ", c.model.c_str());
      }
    }
    const bool none = std::none_of(devices.begin(), devices.end(), [](const V4l2DeviceInfo& d) { return d.can_capture; }) &&
                      cams.cameras.empty();
    if (none) std::printf("No cameras found: record and live need cameras; replay works on recordings.\n");
  });
}

// One line from stdin for the step gate: true for a line that does not start with q; false for one that does, the
// end of stdin, or a stop request. stdin is polled (not read blocking) so that Ctrl-C or SIGTERM ends the wait
// within 100 ms, whether or not anything is typed.
bool WaitForEnterLine() {
  std::fprintf(stderr, "rangebayes: Enter for the next frame, q then Enter to stop\n");
  std::string line;
  while (!StopRequested()) {
    pollfd in{STDIN_FILENO, POLLIN, 0};
    const int ready = ::poll(&in, 1, 100);
    if (ready < 0 && errno != EINTR) return false;
    if (ready <= 0) continue;
    char c = 0;
    const ssize_t n = ::read(STDIN_FILENO, &c, 1);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return !line.empty() && line.front() != 'q';  // end of input (or stdin unreadable)
    if (c == '\n') return line.empty() || line.front() != 'q';
    line += c;
  }
  return false;
}

// The step gate of `replay --speed step`, on the capture thread. q and the end of stdin end the recording there
// (the frames in flight go through) and the run counts as stopped by request: they ended it as if the recording
// had ended (exit 0, "stopped": false, also after 0 of 8 frames).
bool WaitForEnter() {
  const bool next = WaitForEnterLine();
  if (!next && !StopRequested()) StepQuit().store(true);
  return next;
}

std::optional<StereoRig> ReadOptionalRig(const std::string& path) {
  if (path.empty()) return std::nullopt;
  return ReadStereoRig(path);
}

void AddRecord(CLI::App& app) {
  struct Options {
    CameraCli camera;
    std::string out;
    std::int64_t max_frames = 0;
    double duration_s = 0.0;
    bool quiet = false;
  };
  auto o = std::make_shared<Options>();
  auto* sub = app.add_subcommand("record", "Record stereo frames from two cameras into a recording folder (Ctrl-C stops)");
  AddCameraOptions(sub, &o->camera);
  sub->add_option("--out,-o", o->out, "Recording folder to create")->required();
  sub->add_option("--frames", o->max_frames, "Stop after this many frames (0: until Ctrl-C)")
      ->check(NonNegativeInteger());
  sub->add_option("--duration", o->duration_s, "Stop after this many seconds (0: until Ctrl-C)")->check(NonNegativeReal());
  AddQuietFlag(sub, &o->quiet);
  sub->callback([o] {
    const std::optional<StereoRig> rig = ReadOptionalRig(o->camera.rig);
    InstallStopSignalHandlers();
    std::unique_ptr<FrameSource> source = OpenCameras(o->camera);
    Notice(o->quiet, source->Describe());
    RecordingWriter writer(o->out, rig, source->Meta());
    RecorderOptions options;
    options.max_frames = o->max_frames;
    options.max_duration_s = o->duration_s;
    options.stop = &StopFlag();
    ProgressPrinter progress(o->quiet);
    const RecorderSummary s = Record(*source, writer, options, progress.callback());
    progress.Finish();
    Notice(o->quiet, StrCat("recorded into ", o->out, ": ", s.BriefReport()));
    if (!s.error.empty()) {
      RB_FAIL(s.error, " (the recording is kept up to frame ", s.frames_written, ")");
    }
  });
}

void AddLive(CLI::App& app) {
  struct Options {
    CameraCli camera;
    std::string out;
    std::string record;
    PipelineCli pipeline;
  };
  auto o = std::make_shared<Options>();
  auto* sub = app.add_subcommand(
      "live", "Live from two cameras through the pipeline with live settings (drops frames when behind)");
  AddCameraOptions(sub, &o->camera);
  sub->add_option("--out,-o", o->out, "Output folder for the results")->required();
  sub->add_option("--record", o->record, "Also record the raw frames into this recording folder");
  AddPipelineOptions(sub, &o->pipeline);
  sub->callback([o] {
    RB_CHECK(!o->camera.rig.empty(), "live needs a calibrated rig: give --rig rig.yaml (see rangebayes calibrate)");
    const StereoRig rig = ReadStereoRig(o->camera.rig);
    std::unique_ptr<FrameSource> camera = OpenCameras(o->camera);
    PipelineCli cli = o->pipeline;
    cli.live_path = true;
    std::unique_ptr<RecordingWriter> writer;
    if (!o->record.empty()) writer = std::make_unique<RecordingWriter>(o->record, rig, camera->Meta());
    TeeSource tee(*camera, writer.get());
    RunToFolder(tee, rig, MakePipelineOptions(cli), cli, o->out);
    if (writer) writer->Finish();
  });
}

void AddReplay(CLI::App& app) {
  struct Options {
    std::string recording;
    std::string out;
    std::string rig;
    std::string speed = "fastest";
    double speed_factor = 1.0;
    int first = 0;
    int count = -1;
    int repeats = 1;
    PipelineCli pipeline;
  };
  auto o = std::make_shared<Options>();
  auto* sub = app.add_subcommand(
      "replay", "Run a recording through rectify, stereo, triangulation, smoothing and decimation into a folder");
  sub->add_option("RECORDING", o->recording, "Recording folder (rig.yaml, frames.csv, left/, right/)")->required();
  sub->add_option("--out,-o", o->out, "Output folder (created)")->required();
  sub->add_option("--rig", o->rig, "Rig file to use instead of the recording's rig.yaml");
  sub->add_option("--speed", o->speed, "fastest, recorded (at the recorded frame times) or step (Enter per frame)")
      ->check(CLI::IsMember({"fastest", "recorded", "step"}));
  sub->add_option("--speed-factor", o->speed_factor, "With --speed recorded: play this many times faster")
      ->check(RealRange(0.001, 1000.0));
  sub->add_option("--first", o->first, "First frames.csv entry to play (0-based position)")
      ->check(NonNegativeInteger());
  sub->add_option("--count", o->count, "Entries to play (-1: all)")->check(CountOrAll());
  sub->add_option("--repeat", o->repeats,
                  "Play the entries this many times (frame indices keep increasing; for live-path timing)")
      ->check(CLI::Range(1, 1000000));
  AddPipelineOptions(sub, &o->pipeline);
  sub->callback([o, sub] {
    if (sub->count("--speed-factor") > 0 && o->speed != "recorded") {
      UsageError("--speed-factor applies to --speed recorded (it was ignored)");
    }
    RecordingReadSummary read_summary;
    Recording recording = OpenRecording(o->recording, &read_summary);
    for (const std::string& n : read_summary.notices) Notice(o->pipeline.quiet, n);
    if (!o->rig.empty()) recording.rig = ReadStereoRig(o->rig);
    RB_CHECK(recording.rig.has_value(), o->recording,
             ": has no rig.yaml (uncalibrated); give one with --rig (see rangebayes calibrate)");
    RB_CHECK(recording.num_frames() > 0, o->recording, ": frames.csv lists no frame");
    if (o->count >= 0 && static_cast<std::int64_t>(o->first) + o->count > recording.num_frames() &&
        o->first < recording.num_frames()) {
      Notice(o->pipeline.quiet,
             StrCat("--count ", o->count, " from --first ", o->first, ": the recording has ", recording.num_frames(),
                    " entries, so ", recording.num_frames() - o->first, " are played"));
    }
    const StereoRig rig = *recording.rig;
    PlaybackOptions playback;
    playback.speed = o->speed == "recorded" ? PlaybackSpeed::kRecorded
                     : o->speed == "step"   ? PlaybackSpeed::kStep
                                            : PlaybackSpeed::kFastest;
    playback.speed_factor = o->speed_factor;
    playback.first_position = o->first;
    playback.count = o->count;
    playback.repeats = o->repeats;
    playback.stop = &StopFlag();
    if (playback.speed == PlaybackSpeed::kStep) playback.step_gate = WaitForEnter;
    PlaybackSource source(std::move(recording), playback);
    RunToFolder(source, rig, MakePipelineOptions(o->pipeline), o->pipeline, o->out);
  });
}

}  // namespace

RB_REGISTER_COMMANDS(50, AddCameras);
RB_REGISTER_COMMANDS(51, AddRecord);
RB_REGISTER_COMMANDS(52, AddLive);
RB_REGISTER_COMMANDS(53, AddReplay);

}  // namespace rangebayes::apps
