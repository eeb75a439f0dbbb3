// capture/ recordings and pipeline/ replay.
#include <pybind11/stl.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <memory>
#include <mutex>
#include <string_view>
#include <thread>

#include "python/src/bindings.h"
#include "python/src/convert.h"
#include "python/src/option_tables.h"

namespace rangebayes::python {
namespace {

// Keeps every result (the sink thread runs without the GIL; results become Python objects afterwards).
class CollectingSink : public PipelineSink {
 public:
  void Consume(const PipelineResult& result) override {
    std::lock_guard<std::mutex> lock(mutex_);
    results_.push_back(result);
  }
  std::vector<PipelineResult> Take() {
    std::lock_guard<std::mutex> lock(mutex_);
    return std::move(results_);
  }

 private:
  std::mutex mutex_;
  std::vector<PipelineResult> results_;
};

// RunPipeline on a worker thread while this (Python) thread waits without the GIL: every 50 ms it takes the
// GIL to let Python run its signal handlers, so Ctrl-C (KeyboardInterrupt) stops the run. An exception from
// the progress function (called on the pipeline's sink thread) also stops the run; either is raised here once
// the pipeline has ended. The pipeline's own threads never see a Python exception.
PipelineSummary RunReplay(Recording recording, const StereoRig& rig, const PlaybackOptions& playback,
                          PipelineOptions options, PipelineSink* sink) {
  std::atomic<bool> stop{false};
  std::mutex mutex;
  std::condition_variable finished_cv;
  bool finished = false;
  std::exception_ptr python_error;  // from the progress function or a signal handler
  std::exception_ptr run_error;     // from RunPipeline (invalid options, a rig that does not fit)
  auto fail = [&](std::exception_ptr e) {
    std::lock_guard<std::mutex> lock(mutex);
    if (!python_error) python_error = std::move(e);
    stop = true;
  };
  options.stop = &stop;
  if (options.progress) {
    options.progress = [user = std::move(options.progress), &fail](double fraction, std::string_view stage) {
      try {
        user(fraction, stage);
      } catch (...) {
        fail(std::current_exception());
      }
    };
  }
  PipelineSummary summary;
  {
    py::gil_scoped_release nogil;
    std::thread runner([&] {
      try {
        PlaybackOptions stoppable = playback;
        stoppable.stop = &stop;  // Ctrl-C also ends a long wait at the recorded speed
        PlaybackSource source(std::move(recording), stoppable);
        summary = RunPipeline(source, rig, options, {sink});
      } catch (...) {
        run_error = std::current_exception();
      }
      std::lock_guard<std::mutex> lock(mutex);
      finished = true;
      finished_cv.notify_all();
    });
    std::unique_lock<std::mutex> lock(mutex);
    while (!finished_cv.wait_for(lock, std::chrono::milliseconds(50), [&] { return finished; })) {
      lock.unlock();
      {
        py::gil_scoped_acquire gil;
        if (PyErr_CheckSignals() != 0) {
          try {
            throw py::error_already_set();
          } catch (...) {
            fail(std::current_exception());
          }
        }
      }
      lock.lock();
    }
    lock.unlock();
    runner.join();
  }
  if (python_error) std::rethrow_exception(python_error);
  if (run_error) std::rethrow_exception(run_error);
  return summary;
}

}  // namespace

void BindPipeline(py::module_& m) {
  py::class_<StereoFrame>(m, "StereoFrame", "One stereo pair; left/right are numpy views of the decoded images.")
      .def_property_readonly("left", [](const StereoFrame& f) { return ArrayFromMat(f.left); })
      .def_property_readonly("right", [](const StereoFrame& f) { return ArrayFromMat(f.right); })
      .def_readonly("index", &StereoFrame::index)
      .def_readonly("timestamp_left_ns", &StereoFrame::timestamp_left_ns)
      .def_readonly("timestamp_right_ns", &StereoFrame::timestamp_right_ns)
      .def_readonly("pattern_id", &StereoFrame::pattern_id);

  py::class_<Recording>(m, "Recording",
                        R"(A recorded session (recordings/README.md): rig (StereoRig or None), meta (dict),
len(recording) frames; recording[i] / iteration load frames as StereoFrame (images decoded from disk).)")
      .def_readonly("folder", &Recording::folder)
      .def_readwrite("rig", &Recording::rig)
      .def_readonly("meta", &Recording::meta)
      .def("__len__", &Recording::num_frames)
      .def("__getitem__",
           [](const Recording& r, int i) {
             if (i < 0) i += r.num_frames();
             if (i < 0 || i >= r.num_frames()) throw py::index_error("frame " + std::to_string(i) + " out of range");
             py::gil_scoped_release nogil;
             return LoadRecordingFrame(r, i);
           })
      .def("__iter__", [](py::object self) {
        return py::module_::import("builtins")
            .attr("map")(self.attr("__getitem__"), py::module_::import("builtins").attr("range")(py::len(self)));
      });
  m.def(
      "open_recording",
      [](const PathArg& folder) {
        RecordingReadSummary summary;
        Recording recording = OpenRecording(folder.string(), &summary);
        WarnNotices(summary.notices, "");  // they name the folder
        return recording;
      },
      py::arg("folder"),
      "Opens a recording folder (frames.csv, meta.yaml, rig.yaml, left/, right/). What the CLI prints as notices (a "
      "cut last line, missing frames) are UserWarnings.");

  py::class_<PipelineResult>(m, "PipelineResult", R"(One pipeline result: index, last_index, timestamp_ns, frames,
left_rectified (numpy), depth (DepthFrame), raw_mesh (NoisyMesh), smoothed (Mesh or None), decimated
(DecimatedMesh or None), error ('' when fine).)")
      .def_readonly("index", &PipelineResult::index)
      .def_readonly("last_index", &PipelineResult::last_index)
      .def_readonly("timestamp_ns", &PipelineResult::timestamp_ns)
      .def_readonly("frames", &PipelineResult::frames)
      .def_property_readonly("left_rectified", [](const PipelineResult& r) { return ArrayFromMat(r.left_rectified); })
      .def_readonly("depth", &PipelineResult::depth)
      .def_readonly("raw_mesh", &PipelineResult::raw_mesh)
      .def_readonly("smoothed", &PipelineResult::smoothed)
      .def_readonly("decimated", &PipelineResult::decimated)
      .def_readonly("error", &PipelineResult::error)
      .def_readonly("error_stage", &PipelineResult::error_stage)
      .def_readonly("stereo_downsample", &PipelineResult::stereo_downsample)
      .def_readonly("smooth_iterations", &PipelineResult::smooth_iterations, "iterations of the final solve")
      .def_readonly("smooth_time_limited", &PipelineResult::smooth_time_limited, "the smoothing budget stopped it")
      .def_readonly("smooth_distance", &PipelineResult::smooth_distance,
                    "estimated distance to the optimum, relative to E (inf: unknown)")
      .def_readonly("smooth_warm_vertices", &PipelineResult::smooth_warm_vertices,
                    "vertices that started from the previous result (0: solved from the measurements)");

  py::class_<StageTiming>(m, "StageTiming")
      .def_readonly("name", &StageTiming::name)
      .def_readonly("items", &StageTiming::items)
      .def_readonly("errors", &StageTiming::errors)
      .def_readonly("total_ms", &StageTiming::total_ms)
      .def_property_readonly("mean_ms", &StageTiming::mean_ms);
  py::class_<PipelineSummary>(m, "PipelineSummary")
      .def_readonly("source", &PipelineSummary::source)
      .def_readonly("frames_captured", &PipelineSummary::frames_captured)
      .def_readonly("frames_skipped", &PipelineSummary::frames_skipped, "frames the source could not deliver")
      .def_readonly("results", &PipelineSummary::results)
      .def_readonly("failed", &PipelineSummary::failed)
      .def_readonly("dropped", &PipelineSummary::dropped)
      .def_readonly("stopped", &PipelineSummary::stopped)
      .def_readonly("fatal_error", &PipelineSummary::fatal_error)
      .def_readonly("errors", &PipelineSummary::errors, "one line per failed or skipped frame (first 100)")
      .def_readonly("stages", &PipelineSummary::stages)
      .def_readonly("notices", &PipelineSummary::notices)
      .def_readonly("wall_s", &PipelineSummary::wall_s, "seconds")
      .def_readonly("frames_per_s", &PipelineSummary::frames_per_s)
      .def_readonly("latency_mean_ms", &PipelineSummary::latency_mean_ms, "capture-to-result time per result, ms")
      .def_readonly("smooth_iterations_mean", &PipelineSummary::smooth_iterations_mean)
      .def_readonly("smooth_time_limited", &PipelineSummary::smooth_time_limited, "results the budget stopped")
      .def_readonly("smooth_warm_started", &PipelineSummary::smooth_warm_started,
                    "results whose solve started from the previous result")
      .def_readonly("smooth_distance_mean", &PipelineSummary::smooth_distance_mean,
                    "mean estimated distance to the optimum, relative to E (NaN: unknown)");

  m.def(
      "replay",
      [](py::handle recording, py::handle rig, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        // A folder (str or os.PathLike) or a Recording; anything else is a TypeError that says so (pybind11's cast
        // said "Unable to cast Python instance to C++ type").
        const bool is_path = py::isinstance<py::str>(recording) || IsPathLike(recording);
        if (!is_path && !py::isinstance<Recording>(recording)) {
          throw py::type_error("replay: recording must be a folder (str or os.PathLike) or a Recording, not " +
                               py::str(py::type::of(recording).attr("__name__")).cast<std::string>());
        }
        if (!rig.is_none() && !py::isinstance<StereoRig>(rig)) {
          throw py::type_error("replay: rig must be a StereoRig or None, not " +
                               py::str(py::type::of(rig).attr("__name__")).cast<std::string>());
        }
        Recording rec;
        if (is_path) {
          RecordingReadSummary read;
          rec = OpenRecording(recording.cast<PathArg>().string(), &read);
          WarnNotices(read.notices, "");
        } else {
          rec = recording.cast<Recording>();
        }
        if (!rig.is_none()) rec.rig = rig.cast<StereoRig>();
        RB_CHECK(rec.rig.has_value(), rec.folder, ": has no rig.yaml (uncalibrated); give one with rig=");
        RB_CHECK(rec.num_frames() > 0, rec.folder, ": frames.csv lists no frame");
        PipelineOptions options;
        // live_path=True: the live-path preset first (`replay --live-path`), so that the keywords given win.
        py::object live_path = PopKeyword(kw, "live_path");
        if (!live_path.is_none() && FieldFromPython<bool>(live_path, "live_path")) ApplyLivePathPreset(&options);
        options.progress = PythonProgress(PopKeyword(kw, "progress"), false);
        ApplyNestedKeywords(kw, "sgbm", SgbmOptionFields(), &options.sgbm, "replay");
        ApplyNestedKeywords(kw, "spacetime", SpaceTimeOptionFields(), &options.spacetime, "replay");
        ApplyNestedKeywords(kw, "depth", DepthOptionFields(), &options.depth, "replay");
        ApplyNestedKeywords(kw, "triangulate", TriangulateOptionFields(), &options.triangulate, "replay");
        std::unique_ptr<SplinePotential> learned;  // the learned prior options.smoothing.potential points to
        py::object smoothing = PopKeyword(kw, "smoothing");
        if (!smoothing.is_none()) {
          if (!py::isinstance<py::dict>(smoothing)) throw py::type_error("replay: smoothing must be a dict");
          py::dict sd = smoothing.attr("copy")();
          py::object prior = PopKeyword(sd, "prior");
          const bool beta_given = sd.contains("prior_weight");
          ApplyKeywords(SmoothOptionFields(), sd, &options.smoothing, "replay(smoothing=...)", "prior");
          if (!prior.is_none()) {
            ApplySmoothingPrior(prior, beta_given, &options.smoothing, &learned, "replay(smoothing=...)");
          }
        }
        ApplyNestedKeywords(kw, "decimation", DecimateOptionFields(), &options.decimation, "replay");
        PlaybackOptions playback;
        ApplyNestedKeywords(kw, "playback", PlaybackOptionFields(), &playback, "replay");
        ApplyKeywords(PipelineOptionFields(), kw, &options, "replay",
                      "live_path, progress, sgbm, spacetime, depth, triangulate, smoothing, decimation, playback");
        options.Check();
        playback.Check();
        const StereoRig r = *rec.rig;
        CollectingSink sink;
        PipelineSummary summary = RunReplay(std::move(rec), r, playback, options, &sink);
        return std::make_pair(sink.Take(), std::move(summary));
      },
      py::arg("recording"), py::arg("rig") = py::none(),
      R"(Replays a recording (a Recording, or a folder as str or os.PathLike) through the pipeline (rectify, stereo,
triangulate, smooth, decimate) as `rangebayes replay` does, without dropping frames: (list of PipelineResult,
PipelineSummary). The defaults are the library's (PipelineOptions{}), which are the CLI's: replay(rec, **kw) gives the meshes
`rangebayes replay REC --out DIR` writes for the same options (python/tests compare the bytes).
Keywords: rangebayes.PIPELINE_OPTIONS fields (matcher 'sgbm'/'spacetime', window_frames, stereo_downsample,
smooth, decimate, ...), nested dicts sgbm, spacetime, depth, triangulate, smoothing, decimation, playback
(first_position, count, repeats), progress (a function (fraction, stage), called with the GIL), live_path
(True: the live-path preset of `replay --live-path` first, ApplyLivePathPreset: drop-oldest queues of one item,
stereo every 2nd pixel, triangulation every 4th, fast smoothing within an 80 ms budget, no decimation; the
other keywords given win over it; frames may then be dropped, counted in summary.dropped).
smoothing takes the SmoothOptions fields and prior as smooth() does ('sqrt', 'quadratic', 'cauchy', a learned
prior .yaml path or a LearnedPrior, whose β is used unless prior_weight is given: `replay --prior FILE`).
CLI flags map as --num-disparities N: sgbm={"num_disparities": N} (or spacetime=...), --window B:
sgbm={"block_size_px": B} / spacetime={"window_px": B}, --downsample N: triangulate={"downsample": N},
--tolerance T / --max-iterations I / --prior-weight W: smoothing={...}, --lambda L: decimation={"lambda": L},
--first/--count/--repeat: playback={...}. The GIL is released while the pipeline runs; frames that fail are
PipelineResult.error and summary.errors, as in the CLI. Ctrl-C (KeyboardInterrupt) or an exception raised by
progress stops the run and is raised once the pipeline has ended.)");
  m.attr("PIPELINE_OPTIONS") = FieldsToDict(PipelineOptionFields(), PipelineOptions{});
}

}  // namespace rangebayes::python
