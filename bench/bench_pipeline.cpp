// Pipeline stages one by one on a 640×480 synthetic frame (stereo/synth.h, scene "planes", disparities
// ~39–68 px), and the live preview path end to end. See BENCHMARKS.md "Capture and pipeline".
//
//   bench_pipeline [google benchmark flags]      e.g. --benchmark_filter=Live
//
// Every stage runs with the settings the `rangebayes replay` command uses for it: SGBM with 96 disparities at
// full resolution, 48 at half resolution (the live path's --stereo-downsample 2), space-time T = 8 over
// disparities 16–79, triangulation of every pixel (full) or every 2nd pixel of the half-resolution depth
// (live: every 4th full-resolution pixel), fast smoothing tolerance, decimation with the default λ.
// Times are wall clock (UseRealTime) because OpenCV and TBB use both cores; the CPU column is the process's.
#include <benchmark/benchmark.h>

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "bayes/decimation/decimate.h"
#include "bayes/smooth.h"
#include "capture/playback_source.h"
#include "capture/recording.h"
#include "pipeline/file_sink.h"
#include "pipeline/pipeline.h"
#include "reconstruction/triangulate.h"
#include "stereo/depth_frame.h"
#include "stereo/rectify.h"
#include "stereo/sgbm_matcher.h"
#include "stereo/spacetime_matcher.h"
#include "stereo/synth.h"

namespace rb = rangebayes;
namespace fs = std::filesystem;

namespace {

constexpr int kFrames = 16;  // recording length for the end-to-end runs (≥ 8 for the T = 8 window)

// The scene, its recording on disk and the intermediate results, computed once.
struct Fixture {
  rb::SynthRecording scene;
  std::string folder;  // a recording of the scene (PNG, compression 1, as `rangebayes synth` writes it)
  rb::DepthFrame depth_full, depth_half;
  rb::NoisyMesh mesh_full, mesh_live;
  rb::Mesh smoothed_live;
  rb::PipelineResult live_result;

  Fixture() {
    rb::SynthOptions o;
    o.scene = rb::SynthScene::kPlanes;
    o.width = 640;
    o.height = 480;
    o.frames = kFrames;
    o.supersample = 1;
    o.seed = 2;
    scene = rb::RenderSynthetic(o);
    folder = (fs::temp_directory_path() / ("rb_bench_pipeline_" + std::to_string(::getpid()))).string();
    fs::remove_all(folder);
    rb::WriteSyntheticRecording(scene, o, folder);

    rb::SgbmMatcher full(SgbmFull());
    const rb::DisparityResult d = full.Match({scene.left[0]}, {scene.right[0]});
    depth_full = rb::DepthFromDisparity(d.disparity_px, d.sigma_disparity_px, scene.intrinsics,
                                        scene.rig.baseline_m(), 0.0);
    mesh_full = rb::TriangulateDepth(depth_full);
    cv::Mat l, r;
    cv::pyrDown(scene.left[0], l);
    cv::pyrDown(scene.right[0], r);
    rb::SgbmMatcher half(SgbmHalf());
    const rb::DisparityResult dh = half.Match({l}, {r});
    depth_half = rb::DepthFromDisparity(dh.disparity_px, dh.sigma_disparity_px,
                                        rb::DownsampledIntrinsics(scene.intrinsics, 2), scene.rig.baseline_m(), 0.0);
    mesh_live = rb::TriangulateDepth(depth_half, LiveTriangulate());
    smoothed_live = rb::Smooth(mesh_live, FastSmooth());
    live_result.depth = depth_half;
    live_result.raw_mesh = mesh_live;
    live_result.smoothed = smoothed_live;
    live_result.left_rectified = scene.left[0];
  }
  ~Fixture() {
    std::error_code ec;
    fs::remove_all(folder, ec);
  }

  static rb::SgbmMatcherOptions SgbmFull() {
    rb::SgbmMatcherOptions s;
    s.num_disparities = 96;
    return s;
  }
  static rb::SgbmMatcherOptions SgbmHalf() {
    rb::SgbmMatcherOptions s;
    s.num_disparities = 48;
    return s;
  }
  static rb::TriangulateOptions LiveTriangulate() {
    rb::TriangulateOptions t;
    t.downsample = 2;
    return t;
  }
  static rb::SmoothOptions FastSmooth() {
    rb::SmoothOptions s;
    s.adaptive_epsilon = false;  // the plain solve (global ε²)
    s.tolerance = rb::SmoothTolerance::kFast;
    return s;
  }
};

Fixture& F() {
  static Fixture fixture;
  return fixture;
}

void Counters(benchmark::State& state, double vertices = 0) {
  state.SetItemsProcessed(state.iterations());
  if (vertices > 0) state.counters["vertices"] = vertices;
}

// One stereo pair from the recording on disk (LoadRecordingFrame: two PNG reads, as the capture stage does).
void BM_CaptureDecode(benchmark::State& state) {
  const rb::Recording rec = rb::OpenRecording(F().folder);
  int i = 0;
  for (auto _ : state) {
    rb::StereoFrame frame = rb::LoadRecordingFrame(rec, i++ % rec.num_frames());
    benchmark::DoNotOptimize(frame.left.data);
  }
  Counters(state);
}
BENCHMARK(BM_CaptureDecode)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

// The two halves of BM_CaptureDecode: reading one image file's bytes, and decoding them (cv::imdecode).
void BM_CaptureReadFile(benchmark::State& state) {
  const std::string path = F().folder + "/left/000000.png";
  std::vector<char> bytes;
  for (auto _ : state) {
    std::ifstream in(path, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
    benchmark::DoNotOptimize(bytes.data());
  }
  Counters(state);
  state.counters["bytes"] = static_cast<double>(bytes.size());
}
BENCHMARK(BM_CaptureReadFile)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

void BM_PngDecode(benchmark::State& state) {
  std::ifstream in(F().folder + "/left/000000.png", std::ios::binary);
  const std::vector<uchar> bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (auto _ : state) benchmark::DoNotOptimize(cv::imdecode(bytes, cv::IMREAD_UNCHANGED).data);
  Counters(state);
}
BENCHMARK(BM_PngDecode)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

void BM_Rectify(benchmark::State& state) {
  // The synthetic rig is rectified already (a passthrough); un-mark it so that real remap maps are built.
  rb::StereoRig rig = F().scene.rig;
  rig.is_rectified = false;
  rig.P1.setZero();
  rig.P2.setZero();
  const rb::Rectifier rectifier(rig);
  cv::Mat l, r;
  for (auto _ : state) rectifier.Rectify(F().scene.left[0], F().scene.right[0], &l, &r);
  Counters(state);
}
BENCHMARK(BM_Rectify)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

void BM_PyrDownPair(benchmark::State& state) {
  cv::Mat l, r;
  for (auto _ : state) {
    cv::pyrDown(F().scene.left[0], l);
    cv::pyrDown(F().scene.right[0], r);
  }
  Counters(state);
}
BENCHMARK(BM_PyrDownPair)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

void BM_SgbmFull640(benchmark::State& state) {
  rb::SgbmMatcher m(Fixture::SgbmFull());
  for (auto _ : state) benchmark::DoNotOptimize(m.Match({F().scene.left[0]}, {F().scene.right[0]}));
  Counters(state);
}
BENCHMARK(BM_SgbmFull640)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

void BM_SgbmHalf320(benchmark::State& state) {
  cv::Mat l, r;
  cv::pyrDown(F().scene.left[0], l);
  cv::pyrDown(F().scene.right[0], r);
  rb::SgbmMatcher m(Fixture::SgbmHalf());
  for (auto _ : state) benchmark::DoNotOptimize(m.Match({l}, {r}));
  Counters(state);
}
BENCHMARK(BM_SgbmHalf320)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

void BM_SpaceTimeT8(benchmark::State& state) {
  rb::SpaceTimeMatcherOptions o;
  o.min_disparity_px = 16;
  o.num_disparities = 64;
  rb::SpaceTimeMatcher m(o);
  const std::vector<cv::Mat> left(F().scene.left.begin(), F().scene.left.begin() + 8);
  const std::vector<cv::Mat> right(F().scene.right.begin(), F().scene.right.begin() + 8);
  for (auto _ : state) benchmark::DoNotOptimize(m.Match(left, right));
  Counters(state);
}
BENCHMARK(BM_SpaceTimeT8)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

void BM_TriangulateFull(benchmark::State& state) {
  rb::NoisyMesh mesh;
  for (auto _ : state) mesh = rb::TriangulateDepth(F().depth_full);
  Counters(state, mesh.mesh.num_vertices());
}
BENCHMARK(BM_TriangulateFull)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

void BM_TriangulateLive(benchmark::State& state) {
  rb::NoisyMesh mesh;
  for (auto _ : state) mesh = rb::TriangulateDepth(F().depth_half, Fixture::LiveTriangulate());
  Counters(state, mesh.mesh.num_vertices());
}
BENCHMARK(BM_TriangulateLive)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

// Fast tolerance to convergence on the live mesh (160×120 grid); the iteration count is reported.
void BM_SmoothFastLive(benchmark::State& state) {
  rb::SmoothSummary s;
  for (auto _ : state) benchmark::DoNotOptimize(rb::Smooth(F().mesh_live, Fixture::FastSmooth(), &s));
  Counters(state, F().mesh_live.mesh.num_vertices());
  state.counters["iterations"] = s.iterations;
}
BENCHMARK(BM_SmoothFastLive)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

// A fixed number of iterations on the full-resolution mesh (~250k vertices): the cost of one iteration there.
// Converging at the fast tolerance takes hundreds of iterations (BENCHMARKS.md), too long to repeat here.
void BM_SmoothFull10Iterations(benchmark::State& state) {
  rb::SmoothOptions o = Fixture::FastSmooth();
  o.max_iterations = 10;
  rb::SmoothSummary s;
  for (auto _ : state) benchmark::DoNotOptimize(rb::Smooth(F().mesh_full, o, &s));
  Counters(state, F().mesh_full.mesh.num_vertices());
  state.counters["ms_per_iteration"] = 1000.0 * (s.time_s - s.setup_time_s) / std::max(1, s.iterations);
}
BENCHMARK(BM_SmoothFull10Iterations)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime()->Iterations(2);

void BM_DecimateLive(benchmark::State& state) {
  rb::DecimateSummary s;
  for (auto _ : state) benchmark::DoNotOptimize(rb::Decimate(F().smoothed_live, rb::DecimateOptions{}, &s));
  Counters(state, F().smoothed_live.num_vertices());
  state.counters["output_faces"] = s.output_faces;
}
BENCHMARK(BM_DecimateLive)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

// The file sink on a live result: range(0) = 1 with depth and shaded previews, 0 meshes only.
void BM_SinksLive(benchmark::State& state) {
  const std::string out = F().folder + "_sink";
  rb::FileSinkOptions o;
  o.depth_png = o.shaded_png = state.range(0) != 0;
  {
    rb::FileSink sink(out, o);
    for (auto _ : state) sink.Consume(F().live_result);
    sink.Finish();
  }
  Counters(state, F().mesh_live.mesh.num_vertices());
  std::error_code ec;
  fs::remove_all(out, ec);
}
BENCHMARK(BM_SinksLive)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime();

// The live preview path end to end (as `rangebayes replay REC --live-path`, 96 disparities), over the
// 16-frame recording. range(0) = 1: the recording plays as fast as it can be read, the oldest frame dropped
// where a stage is busy; 0: paced at the recorded 30 frames/s, like a camera. Counters: results per second
// of wall time (the preview rate) and frames dropped.
void BM_LivePath(benchmark::State& state) {
  const rb::Recording rec = rb::OpenRecording(F().folder);
  rb::PipelineOptions p;
  p.queue_policy = rb::QueueFullPolicy::kDropOldest;
  p.queue_capacity = 1;
  p.stereo_downsample = 2;
  p.sgbm.num_disparities = 96;
  p.triangulate.downsample = 4;
  p.smoothing.tolerance = rb::SmoothTolerance::kFast;
  p.smooth_budget_ms = 40.0;
  p.decimate = false;
  const std::string out = F().folder + "_live";
  double results = 0, dropped = 0, wall = 0, iterations = 0;
  for (auto _ : state) {
    rb::PlaybackOptions playback;
    playback.speed = state.range(0) != 0 ? rb::PlaybackSpeed::kFastest : rb::PlaybackSpeed::kRecorded;
    rb::PlaybackSource source(rec, playback);
    rb::FileSinkOptions so;
    so.depth_png = so.shaded_png = true;
    rb::FileSink sink(out, so);
    const rb::PipelineSummary s = rb::RunPipeline(source, *rec.rig, p, {&sink});
    results += static_cast<double>(s.results);
    dropped += static_cast<double>(s.dropped);
    wall += s.wall_s;
    iterations += s.smooth_iterations_mean;
  }
  state.counters["results_per_s"] = wall > 0 ? results / wall : 0.0;
  state.counters["dropped"] = dropped / static_cast<double>(state.iterations());
  state.counters["smooth_iterations"] = iterations / static_cast<double>(state.iterations());
  std::error_code ec;
  fs::remove_all(out, ec);
}
BENCHMARK(BM_LivePath)->Arg(1)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime()->MeasureProcessCPUTime()->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
