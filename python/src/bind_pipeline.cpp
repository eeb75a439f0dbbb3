// capture/ recordings and pipeline/ replay.
#include <pybind11/stl.h>

#include <mutex>

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

template <typename Options>
void ApplyNested(py::dict& kw, const char* name, const FieldTable<Options>& table, Options* options) {
  py::object value = PopKeyword(kw, name);
  if (value.is_none()) return;
  if (!py::isinstance<py::dict>(value)) throw py::type_error(std::string("replay: ") + name + " must be a dict");
  ApplyKeywords(table, value.cast<py::dict>(), options, std::string("replay(") + name + "=...)");
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

  py::class_<Recording>(m, "Recording", R"(A recorded session (recordings/README.md): rig (StereoRig or None), meta (dict),
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
        return py::module_::import("builtins").attr("map")(self.attr("__getitem__"),
                                                            py::module_::import("builtins").attr("range")(py::len(self)));
      });
  m.def("open_recording", [](const std::string& folder) { return OpenRecording(folder); }, py::arg("folder"),
        "Opens a recording folder (frames.csv, meta.yaml, rig.yaml, left/, right/).");

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
      .def_readonly("error", &PipelineResult::error);

  py::class_<StageTiming>(m, "StageTiming")
      .def_readonly("name", &StageTiming::name)
      .def_readonly("items", &StageTiming::items)
      .def_readonly("errors", &StageTiming::errors)
      .def_readonly("total_ms", &StageTiming::total_ms)
      .def_property_readonly("mean_ms", &StageTiming::mean_ms);
  py::class_<PipelineSummary>(m, "PipelineSummary")
      .def_readonly("source", &PipelineSummary::source)
      .def_readonly("frames_captured", &PipelineSummary::frames_captured)
      .def_readonly("results", &PipelineSummary::results)
      .def_readonly("failed", &PipelineSummary::failed)
      .def_readonly("errors", &PipelineSummary::errors)
      .def_readonly("stages", &PipelineSummary::stages)
      .def_readonly("notices", &PipelineSummary::notices)
      .def_readonly("wall_s", &PipelineSummary::wall_s)
      .def_readonly("frames_per_s", &PipelineSummary::frames_per_s);

  m.def(
      "replay",
      [](py::handle recording, py::handle rig, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        Recording rec = py::isinstance<py::str>(recording) ? OpenRecording(recording.cast<std::string>())
                                                           : recording.cast<Recording>();
        if (!rig.is_none()) rec.rig = rig.cast<StereoRig>();
        RB_CHECK(rec.rig.has_value(), rec.folder, ": has no rig.yaml (uncalibrated); give one with rig=");
        RB_CHECK(rec.num_frames() > 0, rec.folder, ": frames.csv lists no frame");
        PipelineOptions options;
        options.progress = PythonProgress(PopKeyword(kw, "progress"));
        ApplyNested(kw, "sgbm", SgbmOptionFields(), &options.sgbm);
        ApplyNested(kw, "spacetime", SpaceTimeOptionFields(), &options.spacetime);
        ApplyNested(kw, "depth", DepthOptionFields(), &options.depth);
        ApplyNested(kw, "triangulate", TriangulateOptionFields(), &options.triangulate);
        ApplyNested(kw, "smoothing", SmoothOptionFields(), &options.smoothing);
        ApplyNested(kw, "decimation", DecimateOptionFields(), &options.decimation);
        PlaybackOptions playback;
        ApplyNested(kw, "playback", PlaybackOptionFields(), &playback);
        ApplyKeywords(PipelineOptionFields(), kw, &options, "replay",
                      "progress, sgbm, spacetime, depth, triangulate, smoothing, decimation, playback");
        options.Check();
        playback.Check();
        const StereoRig r = *rec.rig;
        CollectingSink sink;
        PipelineSummary summary;
        {
          py::gil_scoped_release nogil;
          PlaybackSource source(std::move(rec), playback);
          summary = RunPipeline(source, r, options, {&sink});
        }
        return std::make_pair(sink.Take(), std::move(summary));
      },
      py::arg("recording"), py::arg("rig") = py::none(),
      R"(Replays a recording (a Recording or a folder) through the pipeline (rectify, stereo, triangulate, smooth,
decimate) as `rangebayes replay` does, without dropping frames: (list of PipelineResult, PipelineSummary).
Keywords: rangebayes.PIPELINE_OPTIONS fields (matcher 'sgbm'/'spacetime', window_frames, smooth, decimate,
...), nested dicts sgbm, spacetime, depth, triangulate, smoothing, decimation, playback (first_position,
count, repeats), progress. GIL released while the pipeline runs.)");
  m.attr("PIPELINE_OPTIONS") = FieldsToDict(PipelineOptionFields(), PipelineOptions{});
}

}  // namespace rangebayes::python
