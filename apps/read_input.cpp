#include "apps/read_input.h"

#include "apps/progress.h"
#include "core/files.h"
#include "core/mesh_io.h"
#include "fusion/scan.h"

namespace rangebayes::apps {

NoisyMesh ReadInputMesh(const std::string& path, bool quiet) {
  MeshReadSummary summary;
  NoisyMesh noisy = ReadMeshOrRangeGrid(path, &summary);
  for (const std::string& notice : summary.notices) Notice(quiet, path + ": " + notice);
  if (!summary.range_grid.empty()) Notice(quiet, path + ": " + summary.range_grid);
  return noisy;
}

void CheckOutputMesh(const std::string& path) {
  MeshFormatFromPath(path);
  CheckFileToWrite(path);
}

}  // namespace rangebayes::apps
