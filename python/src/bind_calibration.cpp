// calibration/: the stereo rig from board images and the disparity noise model, as `rangebayes calibrate` fits them.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "python/src/bindings.h"
#include "python/src/option_tables.h"

namespace rangebayes::python {
namespace {

// File names or glob patterns: one str / PathLike, or a sequence of them.
std::vector<std::string> PathList(py::handle value, const char* what) {
  std::vector<std::string> out;
  if (py::isinstance<py::str>(value) || IsPathLike(value)) {
    out.push_back(value.cast<PathArg>().string());
    return out;
  }
  if (!py::isinstance<py::sequence>(value)) {
    throw py::type_error(std::string(what) + ": expected a path, a glob pattern or a list of them");
  }
  for (py::handle item : value.cast<py::sequence>()) {
    if (!py::isinstance<py::str>(item) && !IsPathLike(item)) {
      throw py::type_error(std::string(what) + ": expected paths, got " +
                           py::str(py::type::of(item)).cast<std::string>());
    }
    out.push_back(item.cast<PathArg>().string());
  }
  return out;
}

// The residual samples as an (n, 4) array: residual_px, sigma_pred_px, depth_m, jump_px.
py::array SamplesToArray(const std::vector<NoiseSample>& samples) {
  py::array_t<double> out({static_cast<py::ssize_t>(samples.size()), py::ssize_t{4}});
  auto view = out.mutable_unchecked<2>();
  for (size_t i = 0; i < samples.size(); ++i) {
    const auto k = static_cast<py::ssize_t>(i);
    view(k, 0) = samples[i].residual_px;
    view(k, 1) = samples[i].sigma_pred_px;
    view(k, 2) = samples[i].depth_m;
    view(k, 3) = samples[i].jump_px;
  }
  return out;
}

// What a noise calibration reports to Python: its text, the fit and (plane target) the samples it fitted.
struct NoiseCalibrationReport {
  std::string brief;
  NoiseFitSummary fit;
  std::vector<NoiseSample> samples;
  int scenes = 0;  // ground truth only
};

}  // namespace

void BindCalibration(py::module_& m) {
  py::class_<StereoCalibrationSummary>(m, "StereoCalibrationSummary",
                                       "What calibrate_rig() found; brief_report() is what `rangebayes calibrate rig` "
                                       "prints.")
      .def_readonly("pairs_given", &StereoCalibrationSummary::pairs_given)
      .def_readonly("pairs_found", &StereoCalibrationSummary::pairs_found)
      .def_readonly("pairs_used", &StereoCalibrationSummary::pairs_used)
      .def_readonly("rms_left_px", &StereoCalibrationSummary::rms_left_px)
      .def_readonly("rms_right_px", &StereoCalibrationSummary::rms_right_px)
      .def_readonly("rms_stereo_px", &StereoCalibrationSummary::rms_stereo_px)
      .def_readonly("epipolar_error_mean_px", &StereoCalibrationSummary::epipolar_error_mean_px)
      .def_readonly("epipolar_error_max_px", &StereoCalibrationSummary::epipolar_error_max_px)
      .def_readonly("right_camera_on_the_left", &StereoCalibrationSummary::right_camera_on_the_left,
                    "the images were most likely given swapped (left for right)")
      .def_property_readonly(
          "views",
          [](const StereoCalibrationSummary& s) {
            py::list out;
            for (const CalibrationView& v : s.views) {
              py::dict d;
              d["left"] = v.left;
              d["right"] = v.right;
              d["used"] = v.used;
              d["dropped"] = v.dropped;
              d["flagged"] = v.flagged;
              d["skip_reason"] = v.skip_reason;
              d["rms_stereo_px"] = v.rms_stereo_px;
              out.append(d);
            }
            return out;
          },
          "per image pair: left, right, used, dropped, flagged, skip_reason, rms_stereo_px")
      .def("brief_report", &StereoCalibrationSummary::BriefReport);
  m.def(
      "calibrate_rig",
      [](py::handle left, py::handle right, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        StereoCalibrationOptions options;
        const ProgressCallback progress = PythonProgress(PopKeyword(kw, "progress"));
        ApplyNestedKeywords(kw, "board", BoardOptionFields(), &options.board, "calibrate_rig");
        ApplyKeywords(StereoCalibrationOptionFields(), kw, &options, "calibrate_rig", "board, progress");
        options.Check();
        const std::vector<std::string> left_patterns = PathList(left, "calibrate_rig: left");
        const std::vector<std::string> right_patterns = PathList(right, "calibrate_rig: right");
        StereoCalibrationSummary summary;
        StereoRig rig;
        std::vector<std::string> unpaired;
        std::vector<CalibrationImagePair> pairs;
        {
          py::gil_scoped_release nogil;
          pairs = PairCalibrationImages(left_patterns, right_patterns, &unpaired);
        }
        // What the CLI prints as notices: images without a partner are left out.
        std::vector<std::string> notices;
        for (const std::string& u : unpaired) notices.push_back("no partner image for " + u + " (skipped)");
        WarnNotices(notices, "calibrate_rig");
        {
          py::gil_scoped_release nogil;
          rig = CalibrateStereoRig(pairs, options, &summary, progress);
        }
        const std::string problem = CalibrationProblem(summary, options);
        RB_CHECK(problem.empty(), "calibrate_rig: ", problem, " (max_rms_px=float('inf') returns it anyway)");
        return std::make_pair(std::move(rig), std::move(summary));
      },
      py::arg("left"), py::arg("right"),
      R"(Calibrates a stereo rig from board image pairs as `rangebayes calibrate rig` does: (StereoRig, StereoCalibrationSummary).
left, right: image files or glob patterns (a str, a Path, or a list), paired by the last number in the file names.
board: a dict of the board (rangebayes.BOARD_OPTIONS: type 'chessboard' or 'charuco', cols, rows, square_m, ...);
the other keywords are the StereoCalibrationOptions fields (rangebayes.RIG_CALIBRATION_OPTIONS) and progress.
GIL released.)");
  m.attr("BOARD_OPTIONS") = FieldsToDict(BoardOptionFields(), BoardSpec{});
  m.attr("RIG_CALIBRATION_OPTIONS") = FieldsToDict(StereoCalibrationOptionFields(), StereoCalibrationOptions{});

  py::class_<NoiseCalibrationReport>(m, "NoiseCalibrationReport",
                                     "What calibrate_noise() measured; brief_report() is what `rangebayes calibrate "
                                     "noise` prints.")
      .def("brief_report", [](const NoiseCalibrationReport& r) { return r.brief; })
      .def_property_readonly("outlier_fraction", [](const NoiseCalibrationReport& r) { return r.fit.outlier_fraction; })
      .def_property_readonly("constant_sigma_px",
                             [](const NoiseCalibrationReport& r) { return r.fit.constant_sigma_px; })
      .def_property_readonly("log_likelihood", [](const NoiseCalibrationReport& r) { return r.fit.log_likelihood; })
      .def_readonly("scenes", &NoiseCalibrationReport::scenes, "ground-truth target: scenes used")
      .def_property_readonly(
          "samples", [](const NoiseCalibrationReport& r) { return SamplesToArray(r.samples); },
          "plane target: the residuals fitted, (n, 4): residual_px, sigma_pred_px, depth_m, jump_px");
  m.def(
      "calibrate_noise",
      [](py::handle inputs, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        py::object target_arg = PopKeyword(kw, "target");
        const std::string target =
            target_arg.is_none() ? "plane" : FieldFromPython<std::string>(target_arg, "calibrate_noise: target");
        NoiseCalibrationReport report;
        DisparityNoiseModel model;
        std::vector<std::string> notices;  // raised once the GIL is held again
        if (target == "ground-truth") {
          GroundTruthNoiseOptions options;
          options.progress = PythonProgress(PopKeyword(kw, "progress"));
          ApplyKeywords(GroundTruthNoiseOptionFields(), kw, &options, "calibrate_noise(target='ground-truth')",
                        "target, progress");
          options.Check();
          const std::vector<std::string> scenes = PathList(inputs, "calibrate_noise: scenes");
          GroundTruthNoiseSummary summary;
          py::gil_scoped_release nogil;
          model = CalibrateDisparityNoiseFromGroundTruth(scenes, options, &summary);
          report.brief = summary.BriefReport(model);
          report.fit = summary.fit;
          report.scenes = summary.scenes;
        } else if (target == "plane") {
          py::object rig_arg = PopKeyword(kw, "rig");
          py::object form_arg = PopKeyword(kw, "form");
          py::object roi_arg = PopKeyword(kw, "roi");
          NoiseCalibrationOptions options;
          ApplyKeywords(PlaneNoiseOptionFields(), kw, &options, "calibrate_noise(target='plane')",
                        "target, rig, form, roi");
          if (!form_arg.is_none()) {
            options.form = ParseNoiseForm(FieldFromPython<std::string>(form_arg, "calibrate_noise: form"));
          }
          if (!roi_arg.is_none()) {
            const auto roi = FieldFromPython<std::vector<int>>(roi_arg, "calibrate_noise: roi");
            if (roi.size() != 4) throw py::value_error("calibrate_noise: roi takes four numbers: x, y, width, height");
            options.roi = cv::Rect(roi[0], roi[1], roi[2], roi[3]);
          }
          options.Check();
          if (!py::isinstance<py::str>(inputs) && !IsPathLike(inputs)) {
            throw py::type_error("calibrate_noise: target 'plane' takes one recording folder");
          }
          const std::string folder = inputs.cast<PathArg>().string();
          std::optional<StereoRig> rig;
          if (!rig_arg.is_none()) {
            if (py::isinstance<StereoRig>(rig_arg)) {
              rig = rig_arg.cast<StereoRig>();
            } else if (py::isinstance<py::str>(rig_arg) || IsPathLike(rig_arg)) {
              rig = ReadStereoRig(rig_arg.cast<PathArg>().string());
            } else {
              throw py::type_error("calibrate_noise: rig must be a StereoRig or a rig file");
            }
          }
          NoiseCalibrationSummary summary;
          RecordingReadSummary read;
          const Recording recording = OpenRecording(folder, &read);
          WarnNotices(read.notices, "");  // they name the folder
          py::gil_scoped_release nogil;
          RB_CHECK(rig || recording.rig.has_value(), folder, ": recording has no rig.yaml; give rig=");
          model = CalibrateDisparityNoise(recording, rig ? *rig : *recording.rig, options, &summary);
          report.brief = summary.BriefReport(model);
          report.fit = summary.fit;
          report.samples = std::move(summary.samples);
          notices = summary.notices;
        } else {
          throw py::value_error("calibrate_noise: target '" + target + "' is not one of 'plane', 'ground-truth'");
        }
        WarnNotices(notices, "calibrate_noise");
        return std::make_pair(std::move(model), std::move(report));
      },
      py::arg("inputs"),
      R"(Fits the disparity noise model as `rangebayes calibrate noise` does: (DisparityNoiseModel, NoiseCalibrationReport).
target='plane' (default): inputs is a recording folder of one plane; rig= a StereoRig or rig file (default: the
recording's rig.yaml); form= 'constant' or 'floor-plus-scale' (default: by the matcher); roi= (x, y, width,
height) of the target in the rectified left image; keywords: rangebayes.PLANE_NOISE_OPTIONS. target='ground-truth': inputs is a list of
Middlebury scene folders (the learned form); keywords: rangebayes.GROUND_TRUTH_NOISE_OPTIONS and progress. GIL
released.)");
  m.attr("PLANE_NOISE_OPTIONS") = FieldsToDict(PlaneNoiseOptionFields(), NoiseCalibrationOptions{});
  m.attr("GROUND_TRUTH_NOISE_OPTIONS") = FieldsToDict(GroundTruthNoiseOptionFields(), GroundTruthNoiseOptions{});

  py::class_<NoiseModelCheck>(m, "NoiseModelCheck",
                              "The calibration test of a noise model: observed against predicted shares of |z| ≤ 1, "
                              "2, 3 and the RMS of z within 3.")
      .def_readonly("samples", &NoiseModelCheck::samples)
      .def_property_readonly(
          "observed_within",
          [](const NoiseModelCheck& c) { return std::vector<double>(c.observed_within, c.observed_within + 3); })
      .def_property_readonly(
          "predicted_within",
          [](const NoiseModelCheck& c) { return std::vector<double>(c.predicted_within, c.predicted_within + 3); })
      .def_readonly("rms_within3", &NoiseModelCheck::rms_within3)
      .def_readonly("predicted_rms_within3", &NoiseModelCheck::predicted_rms_within3)
      .def_readonly("outlier_share", &NoiseModelCheck::outlier_share)
      .def("passes", &NoiseModelCheck::Passes, py::arg("max_share_error") = 0.03, py::arg("max_rms_error") = 0.1)
      .def("brief_report", &NoiseModelCheck::BriefReport);
  m.def(
      "check_noise_model",
      [](const DisparityNoiseModel& model, py::handle scenes_arg, int stride_px, py::object progress_arg) {
        const std::vector<std::string> scenes = PathList(scenes_arg, "check_noise_model: scenes");
        const ProgressCallback progress = PythonProgress(progress_arg);
        py::gil_scoped_release nogil;
        return CheckDisparityNoiseOnGroundTruth(model, scenes, stride_px, progress);
      },
      py::arg("model"), py::arg("scenes"), py::arg("stride_px") = 2, py::kw_only(), py::arg("progress") = py::none(),
      "The calibration test of a learned model on held-out scenes with ground truth (`rangebayes calibrate "
      "check-noise`): a NoiseModelCheck. GIL released.");
  m.def(
      "ground_truth_noise_samples",
      [](const PathArg& folder, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        GroundTruthNoiseOptions options;
        ApplyKeywords(GroundTruthNoiseOptionFields(), kw, &options, "ground_truth_noise_samples");
        options.Check();
        std::vector<NoiseSample> samples;
        {
          py::gil_scoped_release nogil;
          samples = GroundTruthNoiseSamples(ReadMiddleburyScene(folder.string()), options);
        }
        return SamplesToArray(samples);
      },
      py::arg("folder"),
      "The residual samples one Middlebury scene gives calibrate_noise(target='ground-truth') and check_noise_model "
      "(the matcher run as `rangebayes stereo` runs it, d − d_gt on the non-occluded pixels): (n, 4) float64 "
      "residual_px, sigma_pred_px, depth_m (NaN), jump_px. Keywords: rangebayes.GROUND_TRUTH_NOISE_OPTIONS. GIL "
      "released.");
}

}  // namespace rangebayes::python
