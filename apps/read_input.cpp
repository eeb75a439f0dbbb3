#include "apps/read_input.h"

#include "apps/progress.h"
#include "core/error.h"
#include "core/mesh_io.h"
#include "fusion/scan.h"

namespace rangebayes::apps {

NoisyMesh ReadInputMesh(const std::string& path, bool quiet) {
  MeshReadSummary summary;
  RangeGridScanSummary grid;
  NoisyMesh noisy = ReadMeshOrRangeGrid(path, &summary, &grid);
  for (const std::string& notice : summary.notices) Notice(quiet, path + ": " + notice);
  if (grid.faces > 0) {
    Notice(quiet, StrCat(path, ": range grid triangulated: ", grid.faces, " faces, ", grid.cut_edges,
                         " edges cut at discontinuities; covariance along the scanner's rays (", grid.ray_model,
                         "), as `fuse` reads it"));
  }
  return noisy;
}

}  // namespace rangebayes::apps
