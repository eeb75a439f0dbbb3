// The library headers the module binds. Headers that may move (decimation, prior learning) are included here
// only, so that a move is a one-line change.
#pragma once

#include "bayes/decimation/decimate.h"
#include "bayes/learning/learn_prior.h"
#include "bayes/learn_prior_io.h"
#include "bayes/noise_model.h"
#include "bayes/potential.h"
#include "bayes/smooth.h"
#include "bayes/spline_potential.h"
#include "calibration/disparity_noise_model.h"
#include "calibration/stereo_rig.h"
#include "capture/playback_source.h"
#include "capture/recording.h"
#include "core/error.h"
#include "core/mesh.h"
#include "core/mesh_io.h"
#include "pipeline/pipeline.h"
#include "reconstruction/triangulate.h"
#include "stereo/depth_frame.h"
#include "stereo/rectify.h"
#include "stereo/sgbm_matcher.h"
#include "stereo/spacetime_matcher.h"
