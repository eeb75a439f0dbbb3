// Reading and writing meshes: PLY (ascii, binary little/big endian), OBJ and OFF, chosen by file extension.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "core/mesh.h"

namespace rangebayes {

enum class MeshFormat { kPly, kObj, kOff };
enum class PlyEncoding { kBinaryLittleEndian, kAscii, kBinaryBigEndian };

// What a reader noticed that is not an error (polygons triangulated, properties skipped, ...). Each notice
// is one line a user can read.
struct MeshReadSummary {
  MeshFormat format = MeshFormat::kPly;
  int polygons_triangulated = 0;
  std::vector<std::string> notices;  // what the reader left out or changed (skipped elements, ignored normals, ...)
  std::string range_grid;            // how a range grid without faces was triangulated (fusion/scan.h); "" if not
};

// Per-face-corner normals: normal_index(f, k) indexes a row of normals for corner k of face f.
struct CornerNormals {
  Normals normals;
  Faces normal_index;
  bool empty() const { return normals.rows() == 0; }
};

struct MeshWriteOptions {
  PlyEncoding ply_encoding = PlyEncoding::kBinaryLittleEndian;  // PLY only
  bool write_vertex_normals = true;  // write Mesh::N when present
  CornerNormals corner_normals;      // OBJ `vn` per corner, PLY face property; empty: none
  int precision = 17;                // significant digits for ascii output (17 round-trips doubles)
};

// Guesses the format from the extension (.ply, .obj, .off, case-insensitive); throws Error otherwise.
MeshFormat MeshFormatFromPath(const std::string& path);

// Reads a mesh. Throws Error with one line naming the file and what is wrong on any malformed input.
// Polygons are triangulated (fans; concave ones by ear clipping in their plane; counted in the summary). Never
// allocates more than the file size justifies.
Mesh ReadMesh(const std::string& path, MeshReadSummary* summary = nullptr);

// Reads a mesh and, from PLY vertex properties cov_xx cov_xy cov_xz cov_yy cov_yz cov_zz, its per-vertex
// covariance (and pixel_u pixel_v into NoisyMesh::pixel). Covariance stays empty when the file has none.
NoisyMesh ReadNoisyMesh(const std::string& path, MeshReadSummary* summary = nullptr);

// Parses a mesh file's bytes already in memory (what ReadNoisyMesh does after reading the file); `name` (a
// path) names the source in error messages. Shared by the readers and the fuzz targets.
NoisyMesh ParseNoisyMesh(std::string_view bytes, MeshFormat format, const std::string& name,
                         MeshReadSummary* summary = nullptr);

// A scan stored as an organized grid (PLY `element range_grid`, as the Stanford/Cyberware scans are): its
// vertices (and whatever else the file holds, faces included) plus, per grid cell, the vertex it holds.
struct RangeGridScan {
  NoisyMesh mesh;
  int width = 0;                 // cells per row (PLY header 'obj_info num_cols')
  int height = 0;                // rows ('obj_info num_rows')
  std::vector<int> cell_vertex;  // width·height entries, row by row: cell (x, y) at y·width + x; -1: empty
  bool has_grid() const { return width > 0 && height > 0; }
};

// Reads a PLY file with its `range_grid` element (one list of 0 or 1 vertex indices per cell; the grid size
// from the header lines 'obj_info num_cols N' / 'obj_info num_rows N', or the same words as comments). A PLY
// without range_grid reads as a plain mesh (has_grid() false). Throws Error naming the file and cell on a
// malformed grid (cell count not num_cols × num_rows, a cell with two vertices, an index out of range).
RangeGridScan ReadRangeGridScan(const std::string& path, MeshReadSummary* summary = nullptr);

// Writes a mesh in the format of the extension. Vertex order and faces are kept exactly.
void WriteMesh(const Mesh& mesh, const std::string& path, const MeshWriteOptions& options = {});

// Writes covariance (and pixel positions when present) as the PLY vertex properties named above. Only PLY
// can hold them: other formats throw Error when the mesh has either (a plain mesh is written as WriteMesh).
// Throws Error when a face index is out of range or a per-vertex array has the wrong length.
void WriteNoisyMesh(const NoisyMesh& mesh, const std::string& path, const MeshWriteOptions& options = {});

// Writes a mesh whose faces are polygons (each row of `polygons` a list of vertex indices), OBJ or OFF or
// PLY. Used for the decimator's one-polygon-per-patch output.
void WritePolygonMesh(const Vertices& V, const std::vector<std::vector<int>>& polygons, const std::string& path,
                      const MeshWriteOptions& options = {});

}  // namespace rangebayes
