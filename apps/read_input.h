// Reading the input mesh of the mesh commands (`smooth`, `decimate`, `convert`; `info` reads range grids and
// meshes alike with ReadMeshOrRangeGrid) and checking their output mesh, one way for all of them.
#pragma once

#include <string>

#include "core/mesh.h"

namespace rangebayes::apps {

// The mesh at `path` (fusion/scan.h ReadMeshOrRangeGrid: a range-grid scan without faces is triangulated, with
// its scanner covariances); the file's notices, a grid's triangulation among them, go to stderr unless quiet.
// Throws Error on an unreadable file.
NoisyMesh ReadInputMesh(const std::string& path, bool quiet);

// Throws Error unless a mesh can be written to `path`: a known format by its extension (.ply, .obj, .off) and a
// file that can be created there (core/files.h CheckFileToWrite). The commands call it before their work.
void CheckOutputMesh(const std::string& path);

}  // namespace rangebayes::apps
