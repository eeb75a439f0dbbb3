// libFuzzer entry for noise.yaml (ReadDisparityNoiseModel): any input reads or throws rangebayes::Error; a
// model read passes its own Check() and has finite parameters.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "calibration/disparity_noise_model.h"
#include "core/error.h"
#include "fuzz/fuzz_util.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rangebayes;
  const std::string path =
      fuzz::WriteScratch("noise.yaml", std::string_view(reinterpret_cast<const char*>(data), size));
  DisparityNoiseModel model;
  try {
    model = ReadDisparityNoiseModel(path);
  } catch (const Error&) {
    return 0;
  }
  model.Check();
  fuzz::RequireFinite(model.sigma_px, "sigma_px");
  fuzz::RequireFinite(model.floor_px, "floor_px");
  fuzz::RequireFinite(model.scale, "scale");
  fuzz::RequireFinite(model.outlier_fraction, "outlier_fraction");
  fuzz::RequireFinite(model.image_noise_gray, "image_noise_gray");
  fuzz::RequireFinite(model.Apply(1.0), "sigma for a finite prediction");
  return 0;
}
