// Shared by the pipeline tests: a small synthetic recording and pipeline options sized for it.
#pragma once

#include <string>

#include "pipeline/pipeline.h"
#include "stereo/synth.h"
#include "tests/capture/test_util.h"

namespace rangebayes::testing {

// A 96×72 synthetic recording of a tilted wall, floor and panel (stereo/synth.h) with `frames` frames, written
// into `dir`; returns its folder.
inline std::string MakeSynthRecording(const TempDir& dir, int frames) {
  SynthOptions o;
  o.scene = SynthScene::kPlanes;
  o.frames = frames;
  o.width = 96;
  o.height = 72;
  o.supersample = 1;
  const std::string folder = dir.path() + "/synth";
  WriteSyntheticRecording(RenderSynthetic(o), o, folder);
  return folder;
}

// Options for that recording: 16 disparities, the fast smoothing preset on one thread.
inline PipelineOptions SmallPipelineOptions() {
  PipelineOptions p;
  p.sgbm.num_disparities = 16;
  p.spacetime.num_disparities = 16;
  p.smoothing.tolerance = SmoothTolerance::kFast;
  p.smoothing.num_threads = 1;
  return p;
}

}  // namespace rangebayes::testing
