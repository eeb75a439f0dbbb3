// The keyword tables of the Options structs the module exposes (python/src/option_tables.cpp).
#pragma once

#include "python/src/library.h"
#include "python/src/options_table.h"

namespace rangebayes::python {

// SmoothOptions fields that are plain values (numbers, bools, enums as strings, lists). prior, potential,
// initial_positions and progress are separate arguments of smooth().
const FieldTable<SmoothOptions>& SmoothOptionFields();
const FieldTable<GenericNoiseOptions>& GenericNoiseOptionFields();
const FieldTable<DecimateOptions>& DecimateOptionFields();
const FieldTable<SgbmMatcherOptions>& SgbmOptionFields();
const FieldTable<SpaceTimeMatcherOptions>& SpaceTimeOptionFields();
const FieldTable<DepthFromDisparityOptions>& DepthOptionFields();
const FieldTable<TriangulateOptions>& TriangulateOptionFields();
const FieldTable<RectifierOptions>& RectifierOptionFields();
const FieldTable<LearnPriorOptions>& LearnPriorOptionFields();
const FieldTable<PipelineOptions>& PipelineOptionFields();
const FieldTable<PlaybackOptions>& PlaybackOptionFields();
const FieldTable<RangeGridScanOptions>& ScanOptionFields();
const FieldTable<RegisterOptions>& RegisterOptionFields();
const FieldTable<ModelOptions>& ModelOptionFields();
const FieldTable<FuseOptions>& FuseOptionFields();
const FieldTable<BoardSpec>& BoardOptionFields();
const FieldTable<StereoCalibrationOptions>& StereoCalibrationOptionFields();
const FieldTable<NoiseCalibrationOptions>& PlaneNoiseOptionFields();
const FieldTable<GroundTruthNoiseOptions>& GroundTruthNoiseOptionFields();
const FieldTable<DisparityEvaluationOptions>& DisparityEvaluationOptionFields();
const FieldTable<SynthOptions>& SynthOptionFields();
const FieldTable<RenderOptions>& RenderOptionFields();

}  // namespace rangebayes::python
