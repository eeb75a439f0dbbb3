// libFuzzer entry for one mesh reader (RB_FUZZ_FORMAT: 0 PLY, 1 OBJ, 2 OFF). Any input must either parse or
// throw rangebayes::Error; what parses must validate and survive a write/read round trip unchanged.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "core/error.h"
#include "core/mesh_io.h"
#include "core/mesh_io_internal.h"
#include "core/validate.h"

namespace {

constexpr rangebayes::MeshFormat kFormat = static_cast<rangebayes::MeshFormat>(RB_FUZZ_FORMAT);

bool SameBits(double a, double b) { return a == b || (std::isnan(a) && std::isnan(b)); }

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace rangebayes;
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  NoisyMesh mesh;
  try {
    mesh = ParseNoisyMesh(bytes, kFormat, "fuzz");
  } catch (const Error&) {
    return 0;
  }
  ValidateMesh(mesh.mesh);
  // Round trip through binary PLY (keeps everything the readers produce) must be exact.
  const std::string written = mesh_io::FormatPly(mesh, MeshWriteOptions{});
  const NoisyMesh back = ParseNoisyMesh(written, MeshFormat::kPly, "fuzz round trip");
  if (back.mesh.V.rows() != mesh.mesh.V.rows() || back.mesh.F.rows() != mesh.mesh.F.rows() ||
      back.mesh.N.rows() != mesh.mesh.N.rows() || back.covariance.size() != mesh.covariance.size()) {
    std::abort();
  }
  if (back.mesh.F != mesh.mesh.F) std::abort();
  for (Eigen::Index i = 0; i < mesh.mesh.V.size(); ++i) {
    if (!SameBits(back.mesh.V.data()[i], mesh.mesh.V.data()[i])) std::abort();
  }
  return 0;
}
