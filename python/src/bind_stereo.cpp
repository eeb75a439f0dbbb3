// calibration/, stereo/, reconstruction/: rigs and noise models, rectification, matching, depth, triangulation.
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <initializer_list>

#include "python/src/bindings.h"
#include "python/src/convert.h"
#include "python/src/option_tables.h"

namespace rangebayes::python {
namespace {

// A sequence of images: one array (a single frame) or a list of arrays.
std::vector<ImageIn> ImageSequence(py::handle images, const std::string& what) {
  std::vector<ImageIn> out;
  if (py::isinstance<py::list>(images) || py::isinstance<py::tuple>(images)) {
    for (py::handle image : images) out.push_back(ImageFromArray(image, what));
  } else {
    out.push_back(ImageFromArray(images, what));
  }
  return out;
}

// numpy's default float64 maps are taken as float32, the library's type (disparities need no more; NaN stays NaN).
void Float64AsFloat32(std::initializer_list<cv::Mat*> maps) {
  for (cv::Mat* m : maps) {
    if (m->type() == CV_64F) m->convertTo(*m, CV_32F);
  }
}

std::vector<cv::Mat> Mats(const std::vector<ImageIn>& images) {
  std::vector<cv::Mat> out;
  for (const ImageIn& i : images) out.push_back(i.mat);
  return out;
}

// Runs the matcher named `matcher` ("sgbm", "spacetime", or "block": the CLI's and a noise model's name of the
// space-time matcher on one frame) with keyword options on rectified images.
DisparityResult MatchImages(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right,
                            const std::string& matcher, py::dict& kw, const std::string& what,
                            const std::string& extra) {
  if (matcher == "sgbm") {
    SgbmMatcherOptions options;
    ApplyKeywords(SgbmOptionFields(), kw, &options, what, extra);
    options.Check();
    py::gil_scoped_release nogil;
    SgbmMatcher m(options);
    return m.Match(left, right);
  }
  if (matcher == "spacetime" || matcher == "block") {
    SpaceTimeMatcherOptions options;
    ApplyKeywords(SpaceTimeOptionFields(), kw, &options, what, extra);
    options.Check();
    py::gil_scoped_release nogil;
    SpaceTimeMatcher m(options);
    return m.Match(left, right);
  }
  throw py::value_error(what + ": matcher must be 'sgbm', 'spacetime' or 'block' (spacetime on one image pair), got '" +
                        matcher + "'");
}

py::dict DisparityDict(const DisparityResult& r) {
  py::dict d;
  d["disparity_px"] = ArrayFromMat(r.disparity_px);
  d["sigma_disparity_px"] = ArrayFromMat(r.sigma_disparity_px);
  d["match_ms"] = r.match_ms;
  d["frames_used"] = r.frames_used;
  d["valid_fraction"] = r.valid_fraction;
  d["range_end_fraction"] = r.range_end_fraction;
  d["num_disparities_searched"] = r.num_disparities_searched;
  return d;
}

cv::Mat MatOrEmpty(py::handle array, const std::string& what, std::vector<ImageIn>* keep) {
  if (array.is_none()) return {};
  keep->push_back(ImageFromArray(array, what));
  return keep->back().mat;
}

}  // namespace

void BindStereo(py::module_& m) {
  py::class_<CameraIntrinsics> intrinsics(m, "CameraIntrinsics", "Pinhole intrinsics in pixels; image width × height.");
  intrinsics.def(py::init<>());
  PickledFields(intrinsics)
      .ReadWrite("fx_px", &CameraIntrinsics::fx_px)
      .ReadWrite("fy_px", &CameraIntrinsics::fy_px)
      .ReadWrite("cx_px", &CameraIntrinsics::cx_px)
      .ReadWrite("cy_px", &CameraIntrinsics::cy_px)
      .ReadWrite("width", &CameraIntrinsics::width)
      .ReadWrite("height", &CameraIntrinsics::height)
      .Pickle();

  py::class_<StereoRig> rig(m, "StereoRig", R"(A calibrated stereo rig (calibration/stereo_rig.h). Matrices are
numpy arrays (copies on read; assign a whole array to change one). Translations in metres.)");
  rig.def(py::init<>())
      .def("rectified_left", &StereoRig::RectifiedLeft, "the rectified left camera")
      .def("baseline_m", &StereoRig::baseline_m);
  PickledFields(rig)
      .ReadWrite("width", &StereoRig::width)
      .ReadWrite("height", &StereoRig::height)
      .ReadWrite("is_rectified", &StereoRig::is_rectified)
      .ReadWrite("doffs_px", &StereoRig::doffs_px)
      .EigenCopy("K_left", &StereoRig::K_left)
      .EigenCopy("K_right", &StereoRig::K_right)
      .EigenCopy("distortion_left", &StereoRig::distortion_left)
      .EigenCopy("distortion_right", &StereoRig::distortion_right)
      .EigenCopy("R_right_from_left", &StereoRig::R_right_from_left)
      .EigenCopy("t_right_from_left_m", &StereoRig::t_right_from_left_m)
      .EigenCopy("R1", &StereoRig::R1)
      .EigenCopy("R2", &StereoRig::R2)
      .EigenCopy("P1", &StereoRig::P1)
      .EigenCopy("P2", &StereoRig::P2)
      .EigenCopy("Q", &StereoRig::Q)
      .ReadWrite("rms_left_px", &StereoRig::rms_left_px, "calibration RMS reprojection error, px (-1: unknown)")
      .ReadWrite("rms_right_px", &StereoRig::rms_right_px)
      .ReadWrite("rms_stereo_px", &StereoRig::rms_stereo_px)
      .ReadWrite("epipolar_error_px", &StereoRig::epipolar_error_px,
                 "mean |y_left − y_right| of rectified board corners, px (-1: unknown)")
      .ReadWrite("view_names", &StereoRig::view_names, "the views that entered the calibration (left file names)")
      .ReadWrite("view_rms_stereo_px", &StereoRig::view_rms_stereo_px, "their per-view stereo RMS, same order")
      .Pickle();
  m.def(
      "read_rig", [](const PathArg& path) { return ReadStereoRig(path.string()); }, py::arg("path"),
      "Reads a rig YAML (OpenCV FileStorage, as calibrate writes).");
  m.def(
      "write_rig", [](const PathArg& path, const StereoRig& rig) { WriteStereoRig(rig, path.string()); },
      py::arg("path"), py::arg("rig"),
      "Writes a StereoRig as the rig.yaml (OpenCV FileStorage) that `rangebayes calibrate rig` writes and --rig "
      "reads.");

  py::class_<DisparityNoiseModel> noise_model(m, "DisparityNoiseModel",
                                              "σ_d model fitted by `rangebayes calibrate noise`.");
  noise_model.def(py::init<>());
  PickledFields(noise_model)
      .Property(
          "form", [](const DisparityNoiseModel& d) { return std::string(NoiseFormName(d.form)); },
          [](DisparityNoiseModel& d, const std::string& s) { d.form = ParseNoiseForm(s); },
          "'constant', 'floor-plus-scale' or 'learned'")
      .ReadWrite("sigma_px", &DisparityNoiseModel::sigma_px)
      .ReadWrite("floor_px", &DisparityNoiseModel::floor_px)
      .ReadWrite("scale", &DisparityNoiseModel::scale)
      .ReadWrite("matcher", &DisparityNoiseModel::matcher)
      .ReadWrite("samples", &DisparityNoiseModel::samples)
      .ReadWrite("outlier_fraction", &DisparityNoiseModel::outlier_fraction)
      .ReadWrite("depth_slope_px_per_m", &DisparityNoiseModel::depth_slope_px_per_m)
      .ReadWrite("image_noise_gray", &DisparityNoiseModel::image_noise_gray)
      .ReadWrite("jump_scale", &DisparityNoiseModel::jump_scale)
      .ReadWrite("width_min_px", &DisparityNoiseModel::width_min_px)
      .ReadWrite("width_max_px", &DisparityNoiseModel::width_max_px)
      .ReadWrite("window_px", &DisparityNoiseModel::window_px)
      .Pickle();
  noise_model.def(
      "apply",
      [](const DisparityNoiseModel& model, double sigma_pred_px, double jump_px) {
        model.Check();  // fields set from Python: a NaN sigma_px gave NaN here without a word
        return model.Apply(sigma_pred_px, jump_px);
      },
      py::arg("sigma_pred_px"), py::arg("jump_px") = 0.0,
      "σ_d (px) for a predicted σ (px) and (learned form) the largest neighbour jump (px); raises Error for a "
      "model with fields out of range");
  m.def(
      "read_noise_model", [](const PathArg& path) { return ReadDisparityNoiseModel(path.string()); }, py::arg("path"),
      "A DisparityNoiseModel from the noise.yaml `rangebayes calibrate noise` writes (σ_d in px; for "
      "stereo/replay noise_model=...); rangebayes.Error names the file and field when it is malformed.");
  m.def(
      "write_noise_model",
      [](const PathArg& path, const DisparityNoiseModel& model) { WriteDisparityNoiseModel(model, path.string()); },
      py::arg("path"), py::arg("model"),
      "Writes a DisparityNoiseModel as the noise.yaml the CLI's --noise-model reads.");

  py::class_<DepthFrame> depth_frame(m, "DepthFrame", R"(A depth image in the rectified left view. depth_m (metres),
sigma_depth_m, disparity_px, sigma_disparity_px: float32 (h, w) numpy views of the C++ images (no copy), NaN where
invalid. edge_sigma_depth_m: None, or (a learned noise model) the σ_Z the mesh's discontinuity test reads, σ without
the model's neighbour-jump term.)");
  depth_frame.def_property_readonly("width", &DepthFrame::width).def_property_readonly("height", &DepthFrame::height);
  // The images pickle as float32 copies and come back as the arrays they were (a map of another type or shape
  // from a hand-made state is refused).
  const auto image = [](cv::Mat DepthFrame::*member, const char* name) {
    return std::make_pair(
        std::function<py::object(const DepthFrame&)>([member](const DepthFrame& f) { return ArrayFromMat(f.*member); }),
        std::function<void(DepthFrame&, py::handle)>([member, name](DepthFrame& f, py::handle value) {
          if (value.is_none()) return;
          const ImageIn in = ImageFromArray(value, std::string("DepthFrame.") + name);
          if (in.mat.type() != CV_32F) throw py::value_error(std::string("DepthFrame.") + name + ": expected float32");
          f.*member = in.mat.clone();
        }));
  };
  PickledFields<DepthFrame> depth_fields(depth_frame);
  for (const auto& [name, member] : {std::pair{"depth_m", &DepthFrame::depth_m},
                                     {"sigma_depth_m", &DepthFrame::sigma_depth_m},
                                     {"disparity_px", &DepthFrame::disparity_px},
                                     {"sigma_disparity_px", &DepthFrame::sigma_disparity_px},
                                     {"edge_sigma_depth_m", &DepthFrame::edge_sigma_depth_m}}) {
    depth_frame.def_property_readonly(name, [member = member](const DepthFrame& f) { return ArrayFromMat(f.*member); });
    const auto [get, set] = image(member, name);
    depth_fields.State(name, get, set);
  }
  depth_fields.ReadWrite("frame_id", &DepthFrame::frame_id)
      .ReadWrite("timestamp_ns", &DepthFrame::timestamp_ns)
      .ReadWrite("intrinsics", &DepthFrame::intrinsics)
      .ReadWrite("baseline_m", &DepthFrame::baseline_m)
      .ReadWrite("doffs_px", &DepthFrame::doffs_px)
      .ReadWrite("sigma_pixel_px", &DepthFrame::sigma_pixel_px)
      .Pickle();

  m.def(
      "rectify",
      [](const StereoRig& rig, py::handle left, py::handle right, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        RectifierOptions options;
        ApplyKeywords(RectifierOptionFields(), kw, &options, "rectify");
        const ImageIn l = ImageFromArray(left, "left");
        const ImageIn r = ImageFromArray(right, "right");
        cv::Mat lr, rr;
        {
          py::gil_scoped_release nogil;
          Rectifier rectifier(rig, options);
          rectifier.Rectify(l.mat, r.mat, &lr, &rr);
        }
        return py::make_tuple(ArrayFromMat(lr), ArrayFromMat(rr));
      },
      py::arg("rig"), py::arg("left"), py::arg("right"),
      "Rectifies one pair with the rig: (left, right) new arrays. Keywords: alpha, interpolation.");
  m.def(
      "match",
      [](py::handle left, py::handle right, const std::string& matcher, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        const auto l = ImageSequence(left, "left");
        const auto r = ImageSequence(right, "right");
        return DisparityDict(MatchImages(Mats(l), Mats(r), matcher, kw, "match", ""));
      },
      py::arg("left"), py::arg("right"), py::arg("matcher") = "sgbm",
      R"(Stereo matching on rectified images (an array, or a list of arrays for a space-time sequence; read in
place when C-contiguous, uint8 or uint16, 1 or 3 channels). matcher 'sgbm' (OpenCV SGBM) or 'spacetime'
(ours, with σ_d; 'block' is the same on one pair, as the CLI and noise models name it); keywords: rangebayes.SGBM_OPTIONS / SPACETIME_OPTIONS. Returns a dict: disparity_px,
sigma_disparity_px (float32 (h, w), NaN invalid; σ None for sgbm), match_ms, frames_used, valid_fraction,
range_end_fraction (share of pixels matched best at an end of the search range: the range may be too short),
num_disparities_searched (when other than asked: SGBM searches a multiple of 16; else 0). GIL released.)");
  m.attr("SGBM_OPTIONS") = FieldsToDict(SgbmOptionFields(), SgbmMatcherOptions{});
  m.attr("SPACETIME_OPTIONS") = FieldsToDict(SpaceTimeOptionFields(), SpaceTimeMatcherOptions{});

  m.def(
      "stereo",
      [](const StereoRig& rig, py::handle left, py::handle right, const std::string& matcher, py::dict depth,
         py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        DepthFromDisparityOptions depth_options;
        ApplyKeywords(DepthOptionFields(), depth, &depth_options, "stereo(depth=...)");
        depth_options.Check();
        const auto l = ImageSequence(left, "left");
        const auto r = ImageSequence(right, "right");
        RB_CHECK(l.size() == r.size() && !l.empty(), "stereo: left and right need the same number (>= 1) of images");
        std::vector<cv::Mat> lr(l.size()), rr(r.size());
        std::optional<Rectifier> rectifier;
        {
          py::gil_scoped_release nogil;
          rectifier.emplace(rig);
          for (size_t i = 0; i < l.size(); ++i) rectifier->Rectify(l[i].mat, r[i].mat, &lr[i], &rr[i]);
        }
        const DisparityResult result = MatchImages(lr, rr, matcher, kw, "stereo", "depth");
        py::gil_scoped_release nogil;
        return DepthFromDisparity(result, rectifier->intrinsics(), rectifier->baseline_m(), rectifier->doffs_px(),
                                  depth_options);
      },
      py::arg("rig"), py::arg("left"), py::arg("right"), py::arg("matcher") = "sgbm", py::arg("depth") = py::dict(),
      R"(Rectify with the rig, match (matcher 'sgbm' or 'spacetime', keywords as for match()), and convert to
depth: a DepthFrame. left/right: one image or a list (space-time sequence). depth: dict of
DepthFromDisparityOptions (min_depth_m, max_depth_m, sigma_pixel_px). GIL released.)");

  m.def(
      "depth_from_disparity",
      [](py::handle disparity, py::handle sigma, const CameraIntrinsics& intrinsics, double baseline_m,
         double doffs_px, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        DepthFromDisparityOptions options;
        ApplyKeywords(DepthOptionFields(), kw, &options, "depth_from_disparity");
        std::vector<ImageIn> keep;
        cv::Mat d = MatOrEmpty(disparity, "disparity", &keep);
        cv::Mat s = MatOrEmpty(sigma, "sigma", &keep);
        Float64AsFloat32({&d, &s});
        RB_CHECK(d.type() == CV_32F && (s.empty() || s.type() == CV_32F),
                 "depth_from_disparity: disparity and sigma must be float32 or float64 (h, w) images");
        py::gil_scoped_release nogil;
        DepthFrame f = DepthFromDisparity(d, s, intrinsics, baseline_m, doffs_px, options);
        f.depth_m = f.depth_m.clone();  // the result must not point into the caller's arrays
        f.sigma_depth_m = f.sigma_depth_m.clone();
        f.disparity_px = f.disparity_px.clone();
        f.sigma_disparity_px = f.sigma_disparity_px.clone();
        return f;
      },
      py::arg("disparity"), py::arg("sigma"), py::arg("intrinsics"), py::arg("baseline_m"), py::arg("doffs_px") = 0.0,
      "A DepthFrame from a float32 disparity (px, NaN invalid) and its σ (or None). Copies.");

  m.def(
      "triangulate",
      [](const DepthFrame& frame, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        TriangulateOptions options;
        ApplyKeywords(TriangulateOptionFields(), kw, &options, "triangulate");
        options.Check();
        py::gil_scoped_release nogil;
        return TriangulateDepth(frame, options);
      },
      py::arg("frame"),
      R"(Organized triangulation of a DepthFrame into a NoisyMesh (metres, rectified left camera frame) with the
ray-aligned covariance per vertex. Keywords: rangebayes.TRIANGULATE_OPTIONS. GIL released.)");
  m.attr("TRIANGULATE_OPTIONS") = FieldsToDict(TriangulateOptionFields(), TriangulateOptions{});

  py::class_<MiddleburyScene>(
      m, "MiddleburyScene",
      R"(One Middlebury scene folder (2014, v2, 2005/2006, 2001 or 2003 layout): the two views as
stored (BGR uint8), the ground-truth disparity (float32, NaN unknown; None when the folder has none), the
non-occluded mask (uint8, 255 = evaluate; None when absent), the search range and (2014) the rectified rig.)")
      .def_readonly("folder", &MiddleburyScene::folder)
      .def_readonly("layout", &MiddleburyScene::layout)
      .def_property_readonly("left", [](const MiddleburyScene& s) { return ArrayFromMat(s.left); })
      .def_property_readonly("right", [](const MiddleburyScene& s) { return ArrayFromMat(s.right); })
      .def_property_readonly("gt_disparity_px",
                             [](const MiddleburyScene& s) { return ArrayFromMat(s.gt_disparity_px); })
      .def_property_readonly("mask_nonocc", [](const MiddleburyScene& s) { return ArrayFromMat(s.mask_nonocc); })
      .def_readonly("num_disparities", &MiddleburyScene::num_disparities)
      .def_property_readonly(
          "rig", [](const MiddleburyScene& s) { return s.rig ? py::cast(*s.rig) : py::object(py::none()); });
  m.def(
      "read_middlebury_scene",
      [](const PathArg& folder) {
        py::gil_scoped_release nogil;
        return ReadMiddleburyScene(folder.string());
      },
      py::arg("folder"), "Reads a Middlebury scene folder (the layouts `rangebayes eval-depth --scene` reads).");

  py::class_<DisparityEvaluation> evaluation(m, "DisparityEvaluation",
                                             "A disparity map scored against ground truth; brief_report() is what "
                                             "`rangebayes eval-depth` prints.");
  evaluation.def("brief_report", &DisparityEvaluation::BriefReport);
  PickledFields(evaluation)
      .ReadOnly("evaluated_pixels", &DisparityEvaluation::evaluated_pixels)
      .ReadOnly("estimated_pixels", &DisparityEvaluation::estimated_pixels)
      .ReadOnly("coverage", &DisparityEvaluation::coverage)
      .ReadOnly("thresholds_px", &DisparityEvaluation::thresholds_px)
      .ReadOnly("bad_with_holes", &DisparityEvaluation::bad_with_holes,
                "per threshold: share of evaluated pixels missing or off by more (Middlebury's bad-N)")
      .ReadOnly("bad_valid_only", &DisparityEvaluation::bad_valid_only, "the same among estimated pixels")
      .ReadOnly("rms_px", &DisparityEvaluation::rms_px)
      .ReadOnly("mean_abs_px", &DisparityEvaluation::mean_abs_px)
      .Pickle();
  m.def(
      "evaluate_disparity",
      [](py::handle estimate, py::handle ground_truth, py::handle mask, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        DisparityEvaluationOptions options;
        ApplyKeywords(DisparityEvaluationOptionFields(), kw, &options, "evaluate_disparity");
        options.Check();
        std::vector<ImageIn> keep;
        cv::Mat e = MatOrEmpty(estimate, "estimate", &keep);
        cv::Mat gt, m_in;
        if (py::isinstance<MiddleburyScene>(ground_truth)) {
          const MiddleburyScene& scene = ground_truth.cast<const MiddleburyScene&>();
          if (scene.gt_disparity_px.empty())
            throw py::value_error("evaluate_disparity: " + scene.folder + " has no ground truth");
          gt = scene.gt_disparity_px;
          m_in = scene.mask_nonocc;
        } else {
          gt = MatOrEmpty(ground_truth, "ground_truth", &keep);
        }
        py::object mask_in = py::reinterpret_borrow<py::object>(mask);
        // A boolean mask (numpy's own comparison result) is scored as uint8.
        if (py::isinstance<py::array>(mask) && py::array::ensure(mask).dtype().kind() == 'b') {
          mask_in = mask_in.attr("astype")("uint8");
        }
        if (!mask.is_none()) m_in = MatOrEmpty(mask_in, "mask", &keep);
        Float64AsFloat32({&e, &gt});
        if (e.empty() || e.type() != CV_32F || gt.type() != CV_32F) {
          throw py::type_error(
              "evaluate_disparity: estimate and ground_truth must be float32 or float64 (h, w) "
              "disparities");
        }
        if (!m_in.empty() && m_in.type() != CV_8U)
          throw py::type_error("evaluate_disparity: mask must be uint8 or bool (h, w)");
        if (e.size() != gt.size() || (!m_in.empty() && m_in.size() != gt.size())) {
          throw py::value_error("evaluate_disparity: estimate, ground truth and mask differ in size");
        }
        py::gil_scoped_release nogil;
        return EvaluateDisparity(e, gt, m_in, options);
      },
      py::arg("estimate"), py::arg("ground_truth"), py::arg("mask") = py::none(),
      R"(Scores a disparity map (float32 or float64 (h, w), NaN missing) as `rangebayes eval-depth` does: a DisparityEvaluation.
ground_truth: a MiddleburyScene (its ground truth and non-occluded mask) or a float32 array; mask (uint8, non-zero =
score; or bool) replaces the scene's. Keywords: bad_thresholds_px, estimate_scale. GIL released.)");
  m.def(
      "read_disparity",
      [](const PathArg& path, double scale) {
        cv::Mat d;
        {
          py::gil_scoped_release nogil;
          d = ReadDisparityMap(path.string(), scale);
        }
        return ArrayFromMat(d);
      },
      py::arg("path"), py::arg("scale") = 1.0,
      "A disparity map file (PFM as `stereo` writes disparity.pfm, or PNG/PGM: disparity = value / scale, as "
      "`eval-depth --scale`) as float32 (h, w), NaN unknown.");
  m.attr("DISPARITY_EVALUATION_OPTIONS") =
      FieldsToDict(DisparityEvaluationOptionFields(), DisparityEvaluationOptions{});

  py::class_<SynthRecording>(
      m, "SynthRecording",
      R"(A synthetic rectified stereo recording with exact ground truth (`rangebayes synth`): left,
right (lists of uint8 (h, w) frames), depth_m and disparity_px of the left view (float32, NaN none), the rig and
the intrinsics.)")
      .def_property_readonly("left",
                             [](const SynthRecording& r) {
                               py::list out;
                               for (const cv::Mat& f : r.left) out.append(ArrayFromMat(f));
                               return out;
                             })
      .def_property_readonly("right",
                             [](const SynthRecording& r) {
                               py::list out;
                               for (const cv::Mat& f : r.right) out.append(ArrayFromMat(f));
                               return out;
                             })
      .def_property_readonly("depth_m", [](const SynthRecording& r) { return ArrayFromMat(r.depth_m); })
      .def_property_readonly("disparity_px", [](const SynthRecording& r) { return ArrayFromMat(r.disparity_px); })
      .def_readonly("rig", &SynthRecording::rig)
      .def_readonly("intrinsics", &SynthRecording::intrinsics);
  m.def(
      "synth",
      [](py::object out, bool overwrite, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        SynthOptions options;
        ApplyKeywords(SynthOptionFields(), kw, &options, "synth");
        options.Check();
        std::string folder;
        if (!out.is_none()) {
          if (!py::isinstance<py::str>(out) && !IsPathLike(out))
            throw py::type_error("synth: out must be a folder path");
          folder = out.cast<PathArg>().string();
        }
        py::gil_scoped_release nogil;
        SynthRecording recording = RenderSynthetic(options);
        if (!folder.empty()) {
          SynthWriteOptions write;
          write.overwrite = overwrite;
          write.overwrite_flag = "overwrite=True";
          WriteSyntheticRecording(recording, options, folder, write);
        }
        return recording;
      },
      py::kw_only(), py::arg("out") = py::none(), py::arg("overwrite") = false,
      R"(Renders a synthetic recording of a known scene under projected patterns, as `rangebayes synth` does: a
SynthRecording. out: also write it there as a recording folder (open_recording / replay read it; the same files as
`synth --out`), overwrite: replace a recording already there. Keywords: rangebayes.SYNTH_OPTIONS (scene 'plane',
'planes', 'box', 'sphere', 'cylinder' or 'stairs'; pattern 'random' or 'graycode'; frames, width, height, seed,
...). GIL released.)");
  m.attr("SYNTH_OPTIONS") = FieldsToDict(SynthOptionFields(), SynthOptions{});
}

}  // namespace rangebayes::python
