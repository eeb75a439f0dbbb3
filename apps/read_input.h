// Reading the input mesh of the mesh commands (`info`, `smooth`, `decimate`, `convert`), one way for all of them.
#pragma once

#include <string>

#include "core/mesh.h"

namespace rangebayes::apps {

// The mesh at `path` (fusion/scan.h ReadMeshOrRangeGrid: a range-grid scan without faces is triangulated, with
// its scanner covariances); the file's notices, a grid's triangulation among them, go to stderr unless quiet.
// Throws Error on an unreadable file.
NoisyMesh ReadInputMesh(const std::string& path, bool quiet);

}  // namespace rangebayes::apps
