// libFuzzer entry for rig.yaml (ReadStereoRig, OpenCV FileStorage YAML): any input reads or throws
// rangebayes::Error; a rig read has a positive size and finite matrices.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "calibration/stereo_rig.h"
#include "core/error.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rangebayes;
  const std::string path = fuzz::WriteScratch("rig.yaml", std::string_view(reinterpret_cast<const char*>(data), size));
  StereoRig rig;
  try {
    rig = ReadStereoRig(path);
  } catch (const Error&) {
    return 0;
  }
  fuzz::Require(rig.width > 0 && rig.height > 0, "positive image size");
  fuzz::RequireFinite(rig.K_left, "K_left");
  fuzz::RequireFinite(rig.K_right, "K_right");
  fuzz::RequireFinite(rig.distortion_left, "D_left");
  fuzz::RequireFinite(rig.distortion_right, "D_right");
  fuzz::RequireFinite(rig.R_right_from_left, "R");
  fuzz::RequireFinite(rig.t_right_from_left_m, "T");
  fuzz::RequireFinite(rig.R1, "R1");
  fuzz::RequireFinite(rig.R2, "R2");
  fuzz::RequireFinite(rig.P1, "P1");
  fuzz::RequireFinite(rig.P2, "P2");
  fuzz::RequireFinite(rig.Q, "Q");
  fuzz::RequireFinite(rig.doffs_px, "doffs");
  fuzz::Require(rig.view_names.size() == rig.view_rms_stereo_px.size() || rig.view_rms_stereo_px.empty(),
                "per-view RMS list matches the view names");
  return 0;
}
