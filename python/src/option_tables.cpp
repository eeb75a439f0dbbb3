// One row per Options field exposed to Python: adding or removing a field of a library Options struct is a
// one-line edit here (an enum field's value names sit beside its table).
#include "python/src/option_tables.h"

namespace rangebayes::python {

RB_PY_ENUM_NAMES(SmoothTolerance, {{"fast", SmoothTolerance::kFast},
                                   {"default", SmoothTolerance::kDefault},
                                   {"tight", SmoothTolerance::kTight}});

const FieldTable<SmoothOptions>& SmoothOptionFields() {
  static const FieldTable<SmoothOptions> table = {
      RB_PY_FIELD(SmoothOptions, sqrt_epsilon_squared),
      RB_PY_FIELD(SmoothOptions, face_epsilon_squared),
      RB_PY_FIELD(SmoothOptions, cauchy_scale),
      RB_PY_FIELD(SmoothOptions, prior_weight),
      RB_PY_FIELD(SmoothOptions, prior_weight_per_stride),
      RB_PY_FIELD(SmoothOptions, tolerance),
      RB_PY_FIELD(SmoothOptions, energy_tolerance),
      RB_PY_FIELD(SmoothOptions, gap_tolerance),
      RB_PY_FIELD(SmoothOptions, line_search_c2),
      RB_PY_FIELD(SmoothOptions, max_iterations),
      RB_PY_FIELD(SmoothOptions, num_threads),
      RB_PY_FIELD(SmoothOptions, adaptive_epsilon),
      RB_PY_FIELD(SmoothOptions, multilevel),
      RB_PY_FIELD(SmoothOptions, precondition_rays),
      RB_PY_FIELD(SmoothOptions, epsilon_continuation_stages),
      RB_PY_FIELD(SmoothOptions, time_limit_s),
      RB_PY_FIELD(SmoothOptions, robust_data_nu),
  };
  return table;
}

const FieldTable<GenericNoiseOptions>& GenericNoiseOptionFields() {
  static const FieldTable<GenericNoiseOptions> table = {
      RB_PY_FIELD(GenericNoiseOptions, across_ratio),
  };
  return table;
}

RB_PY_ENUM_NAMES(DecimateWeighting, {{"area", DecimateWeighting::kArea}, {"uniform", DecimateWeighting::kUniform}});

const FieldTable<DecimateOptions>& DecimateOptionFields() {
  static const FieldTable<DecimateOptions> table = {
      RB_PY_FIELD(DecimateOptions, lambda),
      RB_PY_FIELD(DecimateOptions, target_faces),
      RB_PY_FIELD(DecimateOptions, chain_reserve_share),
      RB_PY_FIELD(DecimateOptions, lambda_resolution),
      RB_PY_FIELD(DecimateOptions, max_bisection_steps),
      RB_PY_FIELD(DecimateOptions, weighting),
      RB_PY_FIELD(DecimateOptions, max_rounds),
      RB_PY_FIELD(DecimateOptions, min_cos_to_patch_normal),
      RB_PY_FIELD(DecimateOptions, chain_tolerance_rel),
      RB_PY_FIELD(DecimateOptions, shading_regularisation),
      RB_PY_FIELD(DecimateOptions, corner_normal_ridge),
  };
  return table;
}

const FieldTable<SgbmMatcherOptions>& SgbmOptionFields() {
  static const FieldTable<SgbmMatcherOptions> table = {
      RB_PY_FIELD(SgbmMatcherOptions, min_disparity_px),
      RB_PY_FIELD(SgbmMatcherOptions, num_disparities),
      RB_PY_FIELD(SgbmMatcherOptions, block_size_px),
      RB_PY_FIELD(SgbmMatcherOptions, p1),
      RB_PY_FIELD(SgbmMatcherOptions, p2),
      RB_PY_FIELD(SgbmMatcherOptions, uniqueness_ratio_pct),
      RB_PY_FIELD(SgbmMatcherOptions, speckle_window_px),
      RB_PY_FIELD(SgbmMatcherOptions, speckle_range_px),
      RB_PY_FIELD(SgbmMatcherOptions, left_right_max_diff_px),
      RB_PY_FIELD(SgbmMatcherOptions, pre_filter_cap),
      RB_PY_FIELD(SgbmMatcherOptions, three_way),
  };
  return table;
}

RB_PY_ENUM_NAMES(SpaceTimeCost, {{"auto", SpaceTimeCost::kAuto},
                                 {"ssd", SpaceTimeCost::kSsd},
                                 {"zncc-space", SpaceTimeCost::kZnccSpace},
                                 {"zncc", SpaceTimeCost::kZnccTime}});

const FieldTable<SpaceTimeMatcherOptions>& SpaceTimeOptionFields() {
  static const FieldTable<SpaceTimeMatcherOptions> table = {
      RB_PY_FIELD(SpaceTimeMatcherOptions, min_disparity_px),
      RB_PY_FIELD(SpaceTimeMatcherOptions, num_disparities),
      RB_PY_FIELD(SpaceTimeMatcherOptions, window_px),
      RB_PY_FIELD(SpaceTimeMatcherOptions, cost),
      RB_PY_FIELD(SpaceTimeMatcherOptions, uniqueness_ratio),
      RB_PY_FIELD(SpaceTimeMatcherOptions, left_right_max_diff_px),
      RB_PY_FIELD(SpaceTimeMatcherOptions, image_noise_gray),
      RB_PY_FIELD(SpaceTimeMatcherOptions, sigma_floor_px),
      RB_PY_FIELD(SpaceTimeMatcherOptions, sigma_scale),
      RB_PY_FIELD(SpaceTimeMatcherOptions, residual_noise),
      RB_PY_FIELD(SpaceTimeMatcherOptions, ambiguity_weight),
      RB_PY_FIELD(SpaceTimeMatcherOptions, neighbour_jump_px),
      RB_PY_FIELD(SpaceTimeMatcherOptions, max_sigma_disparity_px),
      RB_PY_FIELD(SpaceTimeMatcherOptions, edge_reject_jump_px),
      RB_PY_FIELD(SpaceTimeMatcherOptions, subpixel_iterations),
      RB_PY_FIELD(SpaceTimeMatcherOptions, rows_per_task),
  };
  return table;
}

const FieldTable<DepthFromDisparityOptions>& DepthOptionFields() {
  static const FieldTable<DepthFromDisparityOptions> table = {
      RB_PY_FIELD(DepthFromDisparityOptions, min_depth_m),
      RB_PY_FIELD(DepthFromDisparityOptions, max_depth_m),
      RB_PY_FIELD(DepthFromDisparityOptions, sigma_pixel_px),
  };
  return table;
}

const FieldTable<TriangulateOptions>& TriangulateOptionFields() {
  static const FieldTable<TriangulateOptions> table = {
      RB_PY_FIELD(TriangulateOptions, downsample),
      RB_PY_FIELD(TriangulateOptions, max_jump_sigma),
      RB_PY_FIELD(TriangulateOptions, max_slope_deg),
      RB_PY_FIELD(TriangulateOptions, default_sigma_disparity_px),
      RB_PY_FIELD(TriangulateOptions, sigma_pixel_px),
  };
  return table;
}

const FieldTable<RectifierOptions>& RectifierOptionFields() {
  static const FieldTable<RectifierOptions> table = {
      RB_PY_FIELD(RectifierOptions, alpha),
      RB_PY_FIELD(RectifierOptions, interpolation),
  };
  return table;
}

RB_PY_ENUM_NAMES(LearnMethod,
                 {{"interleaved", LearnMethod::kInterleaved}, {"none", LearnMethod::kNone}});

// The top-level knobs of LearnPrior only (its internals are being simplified).
const FieldTable<LearnPriorOptions>& LearnPriorOptionFields() {
  static const FieldTable<LearnPriorOptions> table = {
      RB_PY_FIELD(LearnPriorOptions, method),
      RB_PY_FIELD(LearnPriorOptions, regularizer_weight),
      RB_PY_FIELD(LearnPriorOptions, prior_weight),
      RB_PY_FIELD(LearnPriorOptions, tolerance),
      RB_PY_FIELD(LearnPriorOptions, max_iterations),
      RB_PY_FIELD(LearnPriorOptions, time_limit_s),
      RB_PY_FIELD(LearnPriorOptions, bump_search_sweeps),
      RB_PY_FIELD(LearnPriorOptions, num_threads),
  };
  return table;
}

RB_PY_ENUM_NAMES(PipelineMatcher, {{"sgbm", PipelineMatcher::kSgbm}, {"spacetime", PipelineMatcher::kSpaceTime}});

// Nested options (sgbm, spacetime, smoothing, ...) are separate dict arguments of replay().
const FieldTable<PipelineOptions>& PipelineOptionFields() {
  static const FieldTable<PipelineOptions> table = {
      RB_PY_FIELD(PipelineOptions, queue_capacity),
      RB_PY_FIELD(PipelineOptions, matcher),
      RB_PY_FIELD(PipelineOptions, window_frames),
      RB_PY_FIELD(PipelineOptions, window_step_frames),
      RB_PY_FIELD(PipelineOptions, stereo_downsample),
      RB_PY_FIELD(PipelineOptions, smooth),
      RB_PY_FIELD(PipelineOptions, smooth_budget_ms),
      RB_PY_FIELD(PipelineOptions, smooth_warm_start),
      RB_PY_FIELD(PipelineOptions, decimate),
  };
  return table;
}

const FieldTable<PlaybackOptions>& PlaybackOptionFields() {
  static const FieldTable<PlaybackOptions> table = {
      RB_PY_FIELD(PlaybackOptions, first_position),
      RB_PY_FIELD(PlaybackOptions, count),
      RB_PY_FIELD(PlaybackOptions, repeats),
  };
  return table;
}

const FieldTable<RangeGridScanOptions>& ScanOptionFields() {
  static const FieldTable<RangeGridScanOptions> table = {
      RB_PY_FIELD(RangeGridScanOptions, sigma_range),       RB_PY_FIELD(RangeGridScanOptions, sigma_lateral),
      RB_PY_FIELD(RangeGridScanOptions, min_cos_incidence), RB_PY_FIELD(RangeGridScanOptions, max_jump_sigma),
      RB_PY_FIELD(RangeGridScanOptions, max_slope_deg),
  };
  return table;
}

const FieldTable<RegisterOptions>& RegisterOptionFields() {
  static const FieldTable<RegisterOptions> table = {
      RB_PY_FIELD(RegisterOptions, max_distance_edges),
      RB_PY_FIELD(RegisterOptions, iterations_per_level),
      RB_PY_FIELD(RegisterOptions, samples_per_scan),
      RB_PY_FIELD(RegisterOptions, final_samples_per_scan),
      RB_PY_FIELD(RegisterOptions, max_normal_angle_deg),
      RB_PY_FIELD(RegisterOptions, slide_sigma_edges),
      RB_PY_FIELD(RegisterOptions, robust_scale_sigma),
      RB_PY_FIELD(RegisterOptions, boundary_rings),
      RB_PY_FIELD(RegisterOptions, min_overlap),
      RB_PY_FIELD(RegisterOptions, converged_step),
      RB_PY_FIELD(RegisterOptions, seed),
      RB_PY_FIELD(RegisterOptions, num_threads),
  };
  return table;
}

// The nested options (registration, smoothing, fusion, decimation) and progress are separate arguments of fuse().
const FieldTable<ModelOptions>& ModelOptionFields() {
  static const FieldTable<ModelOptions> table = {
      RB_PY_FIELD(ModelOptions, align),
      RB_PY_FIELD(ModelOptions, smooth),
      RB_PY_FIELD(ModelOptions, decimate),
  };
  return table;
}

const FieldTable<FuseOptions>& FuseOptionFields() {
  static const FieldTable<FuseOptions> table = {
      RB_PY_FIELD(FuseOptions, voxel_edges),       RB_PY_FIELD(FuseOptions, voxel_size),
      RB_PY_FIELD(FuseOptions, truncation_voxels), RB_PY_FIELD(FuseOptions, kernel_radius_edges),
      RB_PY_FIELD(FuseOptions, min_cos_ray),       RB_PY_FIELD(FuseOptions, min_weight_share),
      RB_PY_FIELD(FuseOptions, max_voxels),
  };
  return table;
}

RB_PY_ENUM_NAMES(BoardType, {{"chessboard", BoardType::kChessboard}, {"charuco", BoardType::kCharuco}});
RB_PY_ENUM_NAMES(ChessboardDetector, {{"best", ChessboardDetector::kBest},
                                      {"sb", ChessboardDetector::kSectorBased},
                                      {"classic", ChessboardDetector::kClassic}});

const FieldTable<BoardSpec>& BoardOptionFields() {
  static const FieldTable<BoardSpec> table = {
      RB_PY_FIELD(BoardSpec, type),     RB_PY_FIELD(BoardSpec, cols),
      RB_PY_FIELD(BoardSpec, rows),     RB_PY_FIELD(BoardSpec, square_m),
      RB_PY_FIELD(BoardSpec, marker_m), RB_PY_FIELD(BoardSpec, dictionary),
      RB_PY_FIELD(BoardSpec, detector), RB_PY_FIELD(BoardSpec, accurate_corners),
  };
  return table;
}

// board is a separate dict argument of calibrate_rig().
const FieldTable<StereoCalibrationOptions>& StereoCalibrationOptionFields() {
  static const FieldTable<StereoCalibrationOptions> table = {
      RB_PY_FIELD(StereoCalibrationOptions, min_pairs),
      RB_PY_FIELD(StereoCalibrationOptions, outlier_mad_factor),
      RB_PY_FIELD(StereoCalibrationOptions, outlier_min_ratio),
      RB_PY_FIELD(StereoCalibrationOptions, drop_outliers),
      RB_PY_FIELD(StereoCalibrationOptions, rational_model),
      RB_PY_FIELD(StereoCalibrationOptions, coverage_grid),
      RB_PY_FIELD(StereoCalibrationOptions, max_rms_px),
  };
  return table;
}

RB_PY_ENUM_NAMES(NoiseCalibrationMatcher, {{"block", NoiseCalibrationMatcher::kBlock},
                                           {"spacetime", NoiseCalibrationMatcher::kSpaceTime},
                                           {"sgbm", NoiseCalibrationMatcher::kSgbm}});

// form (None or a form's name) and roi (x, y, width, height) are handled by calibrate_noise() itself.
const FieldTable<NoiseCalibrationOptions>& PlaneNoiseOptionFields() {
  static const FieldTable<NoiseCalibrationOptions> table = {
      RB_PY_FIELD(NoiseCalibrationOptions, matcher),          RB_PY_FIELD(NoiseCalibrationOptions, first_frame),
      RB_PY_FIELD(NoiseCalibrationOptions, frames),           RB_PY_FIELD(NoiseCalibrationOptions, min_disparity_px),
      RB_PY_FIELD(NoiseCalibrationOptions, num_disparities),  RB_PY_FIELD(NoiseCalibrationOptions, window_px),
      RB_PY_FIELD(NoiseCalibrationOptions, image_noise_gray), RB_PY_FIELD(NoiseCalibrationOptions, stride_px),
  };
  return table;
}

const FieldTable<GroundTruthNoiseOptions>& GroundTruthNoiseOptionFields() {
  static const FieldTable<GroundTruthNoiseOptions> table = {
      RB_PY_FIELD(GroundTruthNoiseOptions, matcher),          RB_PY_FIELD(GroundTruthNoiseOptions, window_px),
      RB_PY_FIELD(GroundTruthNoiseOptions, image_noise_gray), RB_PY_FIELD(GroundTruthNoiseOptions, stride_px),
      RB_PY_FIELD(GroundTruthNoiseOptions, max_samples),
  };
  return table;
}

const FieldTable<DisparityEvaluationOptions>& DisparityEvaluationOptionFields() {
  static const FieldTable<DisparityEvaluationOptions> table = {
      RB_PY_FIELD(DisparityEvaluationOptions, bad_thresholds_px),
      RB_PY_FIELD(DisparityEvaluationOptions, estimate_scale),
  };
  return table;
}

RB_PY_ENUM_NAMES(SynthScene, {{"plane", SynthScene::kPlane},
                              {"planes", SynthScene::kPlanes},
                              {"box", SynthScene::kBox},
                              {"sphere", SynthScene::kSphere},
                              {"cylinder", SynthScene::kCylinder},
                              {"stairs", SynthScene::kStairs}});
RB_PY_ENUM_NAMES(SynthPattern, {{"random", SynthPattern::kRandom}, {"graycode", SynthPattern::kGrayCode}});

const FieldTable<SynthOptions>& SynthOptionFields() {
  static const FieldTable<SynthOptions> table = {
      RB_PY_FIELD(SynthOptions, scene),
      RB_PY_FIELD(SynthOptions, pattern),
      RB_PY_FIELD(SynthOptions, frames),
      RB_PY_FIELD(SynthOptions, image_noise_gray),
      RB_PY_FIELD(SynthOptions, seed),
      RB_PY_FIELD(SynthOptions, width),
      RB_PY_FIELD(SynthOptions, height),
      RB_PY_FIELD(SynthOptions, focal_px),
      RB_PY_FIELD(SynthOptions, baseline_m),
      RB_PY_FIELD(SynthOptions, pattern_cell_px),
      RB_PY_FIELD(SynthOptions, projector_roll_deg),
      RB_PY_FIELD(SynthOptions, optics_blur_px),
      RB_PY_FIELD(SynthOptions, ambient),
      RB_PY_FIELD(SynthOptions, supersample),
      RB_PY_FIELD(SynthOptions, pixel_jitter_px),
      RB_PY_FIELD(SynthOptions, pixel_jitter_cell_px),
  };
  return table;
}

RB_PY_ENUM_NAMES(Projection, {{"orthographic", Projection::kOrthographic}, {"perspective", Projection::kPerspective}});
RB_PY_ENUM_NAMES(Shading, {{"flat", Shading::kFlat}, {"smooth", Shading::kSmooth}});

// Vector fields (view_direction, up, colours) and the framing are separate keywords of render().
const FieldTable<RenderOptions>& RenderOptionFields() {
  static const FieldTable<RenderOptions> table = {
      RB_PY_FIELD(RenderOptions, width_px),        RB_PY_FIELD(RenderOptions, height_px),
      RB_PY_FIELD(RenderOptions, projection),      RB_PY_FIELD(RenderOptions, field_of_view_deg),
      RB_PY_FIELD(RenderOptions, margin_fraction), RB_PY_FIELD(RenderOptions, shading),
      RB_PY_FIELD(RenderOptions, ambient),         RB_PY_FIELD(RenderOptions, two_sided),
  };
  return table;
}

}  // namespace rangebayes::python
