// bayes/: smoothing (what `rangebayes smooth` runs), the generic noise model, decimation, learned priors, and the
// evaluation of a result against ground truth (what `rangebayes eval` prints).
#include <pybind11/eigen.h>
#include <pybind11/stl.h>

#include <cmath>
#include <memory>
#include <optional>

#include "pipeline/mesh_metrics.h"
#include "python/src/bindings.h"
#include "python/src/convert.h"
#include "python/src/option_tables.h"

namespace rangebayes::python {
namespace {

// None: not given (an empty optional: the library estimates it); a NaN given is an error, not a silent None.
std::optional<double> OptionalNumber(py::handle value, const char* name) {
  if (value.is_none()) return std::nullopt;
  const double number = FieldFromPython<double>(value, name);
  if (std::isnan(number)) throw py::value_error(std::string(name) + ": nan is not a value (None: estimate it)");
  return number;
}

}  // namespace

void ApplySmoothingPrior(py::handle prior, bool beta_given, SmoothOptions* options,
                         std::unique_ptr<SplinePotential>* learned, const std::string& what) {
  std::optional<LearnedPrior> read;
  const LearnedPrior* p = nullptr;
  if (py::isinstance<LearnedPrior>(prior)) {
    p = &prior.cast<const LearnedPrior&>();
  } else if (IsPathLike(prior)) {
    read = ReadLearnedPrior(prior.cast<PathArg>().string());
    p = &*read;
  } else if (py::isinstance<py::str>(prior)) {
    const std::string name = prior.cast<std::string>();
    if (IsLearnedPriorFile(name)) {
      read = ReadLearnedPrior(name);
      p = &*read;
    } else {
      options->prior = ParsePriorKind(name);
      options->potential = nullptr;
      return;
    }
  } else {
    throw py::type_error(
        what + ": prior must be 'sqrt', 'quadratic', 'cauchy', a .yaml path (str or os.PathLike) or a LearnedPrior");
  }
  *learned = std::make_unique<SplinePotential>(p->spline, p->theta);
  options->potential = learned->get();
  options->prior_weight =
      ResolvePriorWeight(beta_given ? std::optional<double>(options->prior_weight) : std::nullopt, p);
}

namespace {

// The keywords smooth() takes besides the SmoothOptions table.
constexpr const char* kSmoothExtraKeywords = "across_ratio, ignore_covariance, initial_positions, progress";

py::tuple SmoothPy(py::handle mesh, py::handle noise, py::handle sigma, py::handle prior, py::kwargs kwargs) {
  py::dict kw = py::dict(kwargs);
  GenericNoiseOptions noise_options;
  noise_options.noise_edge_multiple = OptionalNumber(noise, "noise");
  noise_options.sigma = OptionalNumber(sigma, "sigma");
  if (noise_options.noise_edge_multiple && noise_options.sigma) {
    throw py::value_error("smooth(): give noise or sigma, not both");
  }
  py::object across = PopKeyword(kw, "across_ratio");
  if (!across.is_none()) noise_options.across_ratio = FieldFromPython<double>(across, "across_ratio");
  py::object ignore = PopKeyword(kw, "ignore_covariance");
  const bool ignore_covariance = !ignore.is_none() && FieldFromPython<bool>(ignore, "ignore_covariance");
  py::object initial = PopKeyword(kw, "initial_positions");
  py::object progress = PopKeyword(kw, "progress");

  SmoothOptions options;
  const bool beta_given = kw.contains("prior_weight");
  ApplyKeywords(SmoothOptionFields(), kw, &options, "smooth", kSmoothExtraKeywords);
  std::unique_ptr<SplinePotential> learned;
  ApplySmoothingPrior(prior, beta_given, &options, &learned, "smooth()");
  Vertices start;
  if (!initial.is_none()) {
    start = VerticesFromArray(initial, "initial_positions");
    options.initial_positions = &start;
  }
  options.progress = PythonProgress(progress);
  options.Check();

  const NoisyMesh input = ToNoisyMesh(mesh, "smooth");
  NoiseModelChoice choice;
  SmoothSummary summary;
  Mesh result;
  {
    py::gil_scoped_release nogil;
    const NoisyMesh noisy = ChooseNoiseModel(
        input, noise_options, ignore_covariance ? CovarianceSource::kGeneric : CovarianceSource::kAuto, &choice);
    result = Smooth(noisy, options, &summary);
  }
  py::object s = py::cast(std::move(summary));
  s.attr("noise_model") = py::cast(choice);
  return py::make_tuple(std::move(result), s);
}

}  // namespace

void BindBayes(py::module_& m) {
  py::class_<AdaptiveEpsilonSummary> adaptive(m, "AdaptiveEpsilonSummary", "What the adaptive-ε default did.");
  PickledFields(adaptive)
      .ReadOnly("per_face", &AdaptiveEpsilonSummary::per_face)
      .ReadOnly("gate_median_epsilon_squared", &AdaptiveEpsilonSummary::gate_median_epsilon_squared)
      .ReadOnly("median_epsilon_squared", &AdaptiveEpsilonSummary::median_epsilon_squared)
      .ReadOnly("p10_epsilon_squared", &AdaptiveEpsilonSummary::p10_epsilon_squared)
      .ReadOnly("p90_epsilon_squared", &AdaptiveEpsilonSummary::p90_epsilon_squared)
      .ReadOnly("faces_at_minimum", &AdaptiveEpsilonSummary::faces_at_minimum)
      .ReadOnly("prepass_iterations", &AdaptiveEpsilonSummary::prepass_iterations)
      .ReadOnly("prepass_evaluations", &AdaptiveEpsilonSummary::prepass_evaluations)
      .ReadOnly("prepass_time_s", &AdaptiveEpsilonSummary::prepass_time_s)
      .ReadOnly("time_s", &AdaptiveEpsilonSummary::time_s)
      .Pickle();

  py::class_<SmoothSummary> smooth_summary(m, "SmoothSummary", py::dynamic_attr(),
                                           "What smooth() did; brief_report() is what `rangebayes smooth` prints. "
                                           "noise_model: the NoiseModelChoice (file covariances or the generic "
                                           "model).");
  smooth_summary
      .def_property_readonly("termination", [](const SmoothSummary& s) { return SmoothTerminationName(s.termination); })
      .def("brief_report", &SmoothSummary::BriefReport);
  PickledFields(smooth_summary)
      .ReadOnly("iterations", &SmoothSummary::iterations)
      .ReadOnly("evaluations", &SmoothSummary::evaluations)
      .ReadOnly("energy", &SmoothSummary::energy, "energy at the start, then after each iteration")
      .ReadOnly("data_energy", &SmoothSummary::data_energy)
      .ReadOnly("prior_energy", &SmoothSummary::prior_energy)
      .ReadOnly("prior_weight", &SmoothSummary::prior_weight, "β the energy used (after prior_weight_per_stride)")
      .ReadOnly("pixel_stride", &SmoothSummary::pixel_stride,
                "organized meshes: the pixel grid's step that β was divided by; 0: none")
      .ReadOnly("notices", &SmoothSummary::notices,
                "what the call repaired or could not use, one line each (e.g. pixel positions that are not "
                "one grid)")
      .ReadOnly("initial_gradient_norm", &SmoothSummary::initial_gradient_norm)
      .ReadOnly("final_gradient_norm", &SmoothSummary::final_gradient_norm)
      .ReadOnly("remaining_decrease", &SmoothSummary::remaining_decrease,
                "E − E* at the end, estimated from the rate of decrease (inf: fewer than 4 iterations)")
      .State(
          "termination", [](const SmoothSummary& s) { return py::cast(static_cast<int>(s.termination)); },
          [](SmoothSummary& s, py::handle value) { s.termination = static_cast<SmoothTermination>(value.cast<int>()); })
      .ReadOnly("time_s", &SmoothSummary::time_s, "seconds, the whole call")
      .ReadOnly("setup_time_s", &SmoothSummary::setup_time_s, "seconds for topology and buffers")
      .ReadOnly("restarts", &SmoothSummary::restarts)
      .ReadOnly("flipped_faces", &SmoothSummary::flipped_faces)
      .ReadOnly("input_flipped_faces", &SmoothSummary::input_flipped_faces)
      .ReadOnly("inactive_faces", &SmoothSummary::inactive_faces, "degenerate faces left out of the prior")
      .ReadOnly("num_threads", &SmoothSummary::num_threads)
      .ReadOnly("potential_name", &SmoothSummary::potential_name)
      .ReadOnly("memory_bytes", &SmoothSummary::memory_bytes)
      .ReadOnly("levels", &SmoothSummary::levels, "grid levels solved coarse to fine, in any stage (1: single level)")
      .ReadOnly("continuation_stages", &SmoothSummary::continuation_stages,
                "ε-continuation stages solved before the final solve")
      .ReadOnly("coarse_work", &SmoothSummary::coarse_work,
                "evaluations before the final solve (coarse levels, continuation stages) in units of one "
                "evaluation of the input; iterations and evaluations are the final solve's")
      .ReadOnly("adaptive_epsilon_used", &SmoothSummary::adaptive_epsilon_used)
      .ReadOnly("adaptive", &SmoothSummary::adaptive)
      .Pickle();

  py::class_<NoiseEstimateDetails> estimate_details(m, "NoiseEstimateDetails",
                                                    "What the noise estimate read from the mesh.");
  PickledFields(estimate_details)
      .ReadOnly("one_ring", &NoiseEstimateDetails::one_ring, "one-ring residual scale / l_e")
      .ReadOnly("growth", &NoiseEstimateDetails::growth, "two-ring residual over the one-ring's")
      .ReadOnly("tail", &NoiseEstimateDetails::tail, "99th percentile over the median of the one-ring residuals")
      .ReadOnly("raised_to_floor", &NoiseEstimateDetails::raised_to_floor,
                "heavy-tailed residuals: the real-sensor floor set the estimate")
      .Pickle();
  py::class_<GenericNoiseSummary> generic_noise(m, "GenericNoiseSummary");
  PickledFields(generic_noise)
      .ReadOnly("mean_edge_length", &GenericNoiseSummary::mean_edge_length, "l_e, model units")
      .ReadOnly("noise_edge_multiple", &GenericNoiseSummary::noise_edge_multiple, "k used")
      .ReadOnly("sigma", &GenericNoiseSummary::sigma, "σ along the normal, model units")
      .ReadOnly("estimated", &GenericNoiseSummary::estimated)
      .ReadOnly("estimate", &GenericNoiseSummary::estimate, "what the estimate read (when estimated)")
      .ReadOnly("across_ratio", &GenericNoiseSummary::across_ratio, "σ across the normal is σ / across_ratio")
      .Pickle();
  py::class_<NoiseModelChoice> noise_choice(m, "NoiseModelChoice",
                                            "brief_report() is the noise line that `rangebayes smooth` prints.");
  noise_choice.def("brief_report", &NoiseModelChoice::BriefReport);
  PickledFields(noise_choice)
      .ReadOnly("from_file", &NoiseModelChoice::from_file)
      .ReadOnly("replaced_file", &NoiseModelChoice::replaced_file)
      .ReadOnly("generic", &NoiseModelChoice::generic)
      .Pickle();

  m.def("smooth", &SmoothPy, py::arg("mesh"), py::arg("noise") = py::none(), py::arg("sigma") = py::none(),
        py::arg("prior") = "sqrt",
        R"(Bayesian smoothing, the same defaults and result as `rangebayes smooth`: returns (Mesh, SmoothSummary).

mesh: a Mesh or NoisyMesh (copied in). The noise model is ChooseNoiseModel's: the NoisyMesh's covariances
when it has them and neither noise nor sigma is given, else the generic model with noise = k (σ as a multiple
of the mean edge length, (0, 10]) or sigma (σ in model units), k estimated from the mesh when neither is given.
prior: 'sqrt' (default), 'quadratic', 'cauchy', a learned prior .yaml path or a LearnedPrior (its β is used
unless prior_weight is given). Keywords: every SmoothOptions field (rangebayes.SMOOTH_OPTIONS holds their
defaults; enums as strings, e.g. tolerance='fast'), across_ratio (generic model), ignore_covariance=True (the
generic model even when covariances are given), initial_positions ((n, 3) start), progress (a function
(fraction, stage), called with the GIL). The GIL is released while smoothing. An unknown keyword is a
TypeError naming the valid ones; an out-of-range value a rangebayes.Error.)");
  m.attr("SMOOTH_OPTIONS") = FieldsToDict(SmoothOptionFields(), SmoothOptions{});

  m.def(
      "estimate_noise_level",
      [](py::handle mesh) {
        const Mesh plain = ToMesh(mesh, "estimate_noise_level");
        py::gil_scoped_release nogil;
        return EstimateNoiseLevel(plain);
      },
      py::arg("mesh"), "k = σ / l_e estimated from a noisy mesh (0 when nothing is measurable). GIL released.");
  m.def(
      "evaluate",
      [](py::handle ground_truth, py::handle result, bool surface_only) {
        const Mesh gt = ToMesh(ground_truth, "evaluate"), r = ToMesh(result, "evaluate");
        if (!surface_only && !SameConnectivity(r, gt)) {
          throw py::value_error(
              "evaluate: ground_truth and result do not share connectivity (needed for mae_deg); pass "
              "surface_only=True for surface distances alone");
        }
        MeshEvaluation e;
        {
          py::gil_scoped_release nogil;
          e = EvaluateMesh(r, gt, !surface_only, "evaluate: result", "evaluate: ground_truth");
        }
        py::dict out;
        for (const EvaluationField& f : EvaluationFields(e)) {
          out[py::str(f.name)] = f.count ? py::object(py::int_(static_cast<long long>(f.value))) : py::float_(f.value);
        }
        return out;
      },
      py::arg("ground_truth"), py::arg("result"), py::arg("surface_only") = false,
      R"(What `rangebayes eval GT RESULT` prints, as a dict with the same keys: mae_deg (mean angle between corresponding face
normals, degrees; needs the same faces in both meshes, else ValueError) and mae_skipped_faces, unless
surface_only; ev, hausdorff, mean_distance (model units; distances of the result's vertices to the ground-truth
surface, and the other way for hausdorff), their *_rel_bbox, bbox_diagonal, faces, vertices. A mesh without faces
or with a vertex that is not finite is refused. GIL released.)");
  m.def(
      "make_generic_noisy_mesh",
      [](py::handle mesh, py::handle noise, py::handle sigma, double across_ratio) {
        GenericNoiseOptions options;
        options.noise_edge_multiple = OptionalNumber(noise, "noise");
        options.sigma = OptionalNumber(sigma, "sigma");
        options.across_ratio = across_ratio;
        const Mesh plain = ToMesh(mesh, "make_generic_noisy_mesh");
        GenericNoiseSummary summary;
        py::gil_scoped_release nogil;
        NoisyMesh noisy = MakeGenericNoisyMesh(plain, options, &summary);
        return std::make_pair(std::move(noisy), summary);
      },
      py::arg("mesh"), py::arg("noise") = py::none(), py::arg("sigma") = py::none(),
      py::arg("across_ratio") = GenericNoiseOptions{}.across_ratio,
      "The generic noise model (noise = k or sigma in model units; estimated when neither): (NoisyMesh, "
      "GenericNoiseSummary).");

  // Decimation.
  py::class_<DecimatedMesh> decimated(m, "DecimatedMesh", "One decimated pose; arrays are copies.");
  PickledFields(decimated)
      .ReadOnly("mesh", &DecimatedMesh::mesh)
      .ReadOnly("corner_normals", &DecimatedMesh::corner_normals)
      .ReadOnly("face_patch", &DecimatedMesh::face_patch, "per output face, its patch")
      .ReadOnly("vertex_source", &DecimatedMesh::vertex_source, "per output vertex, its input index")
      .ReadOnly("dense_face_patch", &DecimatedMesh::dense_face_patch, "per input face, its patch (-1: dropped)")
      .ReadOnly("polygons", &DecimatedMesh::polygons, "one polygon (vertex indices) per patch")
      .ReadOnly("num_patches", &DecimatedMesh::num_patches)
      .Pickle();
  py::class_<DecimateSummary> decimate_summary(m, "DecimateSummary",
                                               "What decimate() did; brief_report() is what `rangebayes decimate` "
                                               "prints.");
  decimate_summary.def("brief_report", &DecimateSummary::BriefReport);
  PickledFields(decimate_summary)
      .ReadOnly("lambda_", &DecimateSummary::lambda, "the λ used")
      .ReadOnly("target_faces", &DecimateSummary::target_faces, "the faces asked for (0: λ given)")
      .ReadOnly("refitted", &DecimateSummary::refitted, "vertices were refitted (refit_vertices)")
      .ReadOnly("poses", &DecimateSummary::poses, "meshes decimated with one patch map")
      .ReadOnly("input_faces", &DecimateSummary::input_faces)
      .ReadOnly("num_patches", &DecimateSummary::num_patches)
      .ReadOnly("output_faces", &DecimateSummary::output_faces)
      .ReadOnly("output_vertices", &DecimateSummary::output_vertices)
      .ReadOnly("energy", &DecimateSummary::energy, "λ·#patches + data term, summed over poses")
      .ReadOnly("data_energy", &DecimateSummary::data_energy)
      .ReadOnly("fuses", &DecimateSummary::fuses)
      .ReadOnly("splits", &DecimateSummary::splits)
      .ReadOnly("swaps", &DecimateSummary::swaps)
      .ReadOnly("rejected_disconnecting", &DecimateSummary::rejected_disconnecting,
                "split/swap moves refused because they would cut a patch")
      .ReadOnly("rounds", &DecimateSummary::rounds)
      .ReadOnly("converged", &DecimateSummary::converged)
      .ReadOnly("bisection_steps", &DecimateSummary::bisection_steps, "full decimations the λ search ran")
      .ReadOnly("budget_faces", &DecimateSummary::budget_faces)
      .ReadOnly("lambda_too_many", &DecimateSummary::lambda_too_many,
                "the λ search's bracket: at lambda_too_many the patches need faces_too_many > budget_faces")
      .ReadOnly("lambda_fits", &DecimateSummary::lambda_fits)
      .ReadOnly("faces_too_many", &DecimateSummary::faces_too_many)
      .ReadOnly("faces_fits", &DecimateSummary::faces_fits)
      .ReadOnly("max_chain_error_rel", &DecimateSummary::max_chain_error_rel)
      .ReadOnly("kept_corner_vertices", &DecimateSummary::kept_corner_vertices)
      .ReadOnly("blocked_vertices", &DecimateSummary::blocked_vertices)
      .ReadOnly("fell_back_to_dense", &DecimateSummary::fell_back_to_dense)
      .ReadOnly("seconds_partition", &DecimateSummary::seconds_partition)
      .ReadOnly("seconds_geometry", &DecimateSummary::seconds_geometry)
      .ReadOnly("seconds_refit_and_shading", &DecimateSummary::seconds_refit_and_shading)
      .ReadOnly("seconds_search_partition", &DecimateSummary::seconds_search_partition)
      .ReadOnly("seconds_search_geometry", &DecimateSummary::seconds_search_geometry)
      .ReadOnly("refit_moved", &DecimateSummary::refit_moved)
      .ReadOnly("refit_blocked", &DecimateSummary::refit_blocked)
      .ReadOnly("refit_flips", &DecimateSummary::refit_flips)
      .ReadOnly("refit_quadric_before", &DecimateSummary::refit_quadric_before)
      .ReadOnly("refit_quadric_after", &DecimateSummary::refit_quadric_after)
      .ReadOnly("refit_rms_before", &DecimateSummary::refit_rms_before)
      .ReadOnly("refit_rms_after", &DecimateSummary::refit_rms_after)
      .ReadOnly("seconds_total", &DecimateSummary::seconds_total)
      .ReadOnly("notices", &DecimateSummary::notices)
      .Pickle();
  m.def(
      "decimate",
      [](py::handle mesh, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        DecimateOptions options;
        options.progress = PythonProgress(PopKeyword(kw, "progress"));
        // As the CLI: a λ given with a face budget would be replaced by the budget's search without a word.
        if (kw.contains("lambda") && kw.contains("target_faces")) {
          throw py::value_error("decimate: give lambda or target_faces, not both (target_faces searches lambda)");
        }
        ApplyKeywords(DecimateOptionFields(), kw, &options, "decimate", "progress");
        options.Check();
        const Mesh input = ToMesh(mesh, "decimate");
        DecimateSummary summary;
        py::gil_scoped_release nogil;
        DecimatedMesh out = Decimate(input, options, &summary);
        return std::make_pair(std::move(out), std::move(summary));
      },
      py::arg("mesh"),
      "Bayesian decimation into planar patches: (DecimatedMesh, DecimateSummary). Keywords: the DecimateOptions "
      "fields (rangebayes.DECIMATE_OPTIONS, with their defaults), progress; lambda (the energy of one patch, unitless: "
      "squared normal difference x faces) or target_faces (faces wanted; lambda is then searched), not both. GIL "
      "released.");
  m.def(
      "decimate_animated",
      [](const py::sequence& poses, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        DecimateOptions options;
        options.progress = PythonProgress(PopKeyword(kw, "progress"));
        ApplyKeywords(DecimateOptionFields(), kw, &options, "decimate_animated", "progress");
        options.Check();
        std::vector<Mesh> input;
        for (py::handle pose : poses) input.push_back(ToMesh(pose, "decimate_animated"));
        DecimateSummary summary;
        py::gil_scoped_release nogil;
        std::vector<DecimatedMesh> out = DecimateAnimated(input, options, &summary);
        return std::make_pair(std::move(out), std::move(summary));
      },
      py::arg("poses"),
      "Decimates poses of one connectivity with one shared patch map: (list of DecimatedMesh, DecimateSummary).");
  m.attr("DECIMATE_OPTIONS") = FieldsToDict(DecimateOptionFields(), DecimateOptions{});

  // Learned priors.
  py::class_<LearnedPrior> learned_prior(m, "LearnedPrior", "A learned spline potential (prior.yaml).");
  learned_prior.def(py::init<>());
  PickledFields(learned_prior)
      .EigenCopy("theta", &LearnedPrior::theta, "N knot values φ(t_j), t_j = 2j/(N−1)")
      .Property(
          "num_knots", [](const LearnedPrior& p) { return p.spline.num_knots; },
          [](LearnedPrior& p, int n) { p.spline.num_knots = n; })
      .Property(
          "epsilon_squared", [](const LearnedPrior& p) { return p.spline.epsilon_squared; },
          [](LearnedPrior& p, double e) { p.spline.epsilon_squared = e; })
      .ReadWrite("prior_weight", &LearnedPrior::prior_weight, "β it was trained with")
      .ReadWrite("noise_kind", &LearnedPrior::noise_kind)
      .ReadWrite("noise_k", &LearnedPrior::noise_k)
      .ReadWrite("noise_k_max", &LearnedPrior::noise_k_max,
                 "a mixture of levels: the training noise spans [noise_k, noise_k_max]; NaN: a single level")
      .ReadWrite("training_set", &LearnedPrior::training_set)
      .ReadWrite("training_pairs", &LearnedPrior::training_pairs)
      .ReadWrite("method", &LearnedPrior::method)
      .ReadWrite("regularizer_weight", &LearnedPrior::regularizer_weight)
      .ReadWrite("training_mse_le2", &LearnedPrior::training_mse_le2,
                 "the data loss per vertex at the end of training, in units of the mean edge length squared")
      .ReadWrite("date", &LearnedPrior::date)
      .Pickle();
  m.def(
      "read_learned_prior", [](const PathArg& path) { return ReadLearnedPrior(path.string()); }, py::arg("path"),
      "A LearnedPrior from the YAML file `rangebayes learn-prior` writes (for smooth(potential=...)); "
      "rangebayes.Error names the file and field when it is malformed.");
  m.def(
      "write_learned_prior", [](const PathArg& path, const LearnedPrior& p) { WriteLearnedPrior(p, path.string()); },
      py::arg("path"), py::arg("prior"),
      "Writes a LearnedPrior as the YAML file `rangebayes smooth --prior` reads (replaced whole, never left half "
      "written).");
  m.def(
      "learn_prior",
      [](const py::sequence& pairs, py::handle initial_theta, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        LearnPriorOptions options;
        options.progress = PythonProgress(PopKeyword(kw, "progress"));
        ApplyKeywords(LearnPriorOptionFields(), kw, &options, "learn_prior", "progress");
        options.Check();
        std::vector<TrainingPair> training;
        for (py::handle pair : pairs) {
          if (!py::isinstance<py::sequence>(pair) || py::isinstance<py::str>(pair) || py::len(pair) != 2) {
            throw py::value_error("learn_prior: each pair is (noisy NoisyMesh, truth Mesh)");
          }
          auto t = pair.cast<py::tuple>();
          TrainingPair p;
          p.name = "pair " + std::to_string(training.size());
          p.noisy = ToNoisyMesh(t[0], "learn_prior");
          p.truth = ToMesh(t[1], "learn_prior");
          training.push_back(std::move(p));
        }
        Eigen::VectorXd start;
        if (!initial_theta.is_none()) start = initial_theta.cast<Eigen::VectorXd>();
        LearnPriorSummary summary;
        Eigen::VectorXd theta;
        {
          py::gil_scoped_release nogil;
          theta = LearnPrior(training, options, start, &summary);
        }
        // The record `learn-prior` writes (it recorded the method's bare name and no training error).
        TrainingSet set;
        set.pairs = std::move(training);
        const LearnedPrior prior = MakeLearnedPrior(set, options, theta, summary);
        py::dict s;
        s["loss"] = summary.loss;
        s["iterations"] = summary.iterations;
        s["initial_data_loss"] = summary.initial_data_loss;
        s["final_data_loss"] = summary.final_data_loss;
        s["num_vertices"] = summary.num_vertices;
        s["total_time_s"] = summary.total_time_s;
        s["termination"] = summary.termination;
        return py::make_tuple(prior, s);
      },
      py::arg("pairs"), py::arg("initial_theta") = py::none(),
      R"(Learns a spline prior from [(noisy NoisyMesh with covariances, truth Mesh), ...]: (LearnedPrior, summary
dict). Keywords: rangebayes.LEARN_PRIOR_OPTIONS, progress. GIL released.)");
  m.attr("LEARN_PRIOR_OPTIONS") = FieldsToDict(LearnPriorOptionFields(), LearnPriorOptions{});
}

}  // namespace rangebayes::python
