// Mesh validation: counts of the defects that break smoothing, decimation or file round trips.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/mesh.h"

namespace rangebayes {

// The scale within which smoothing, decimation, fusion and evaluation compute: every coordinate within
// ±kMaxCoordinate and, unless all positions coincide, a bounding-box diagonal of at least kMinExtent. Areas and
// information matrices are fourth and inverse second powers of lengths, which beyond this scale overflow or
// underflow a double. Every physical unit fits (a nanometre to a light year is 1e-9 to 1e16 metres).
inline constexpr double kMaxCoordinate = 1e60;
inline constexpr double kMinExtent = 1e-60;

// Throws "WHAT: …" on non-finite coordinates (how many, the first), on a coordinate beyond ±kMaxCoordinate (the
// vertex) or an extent below kMinExtent, saying what to do about it.
void CheckComputableScale(const Vertices& V, std::string_view what);

struct ValidateMeshOptions {
  // A face with three distinct vertices counts as zero-area when its area is at most this fraction of its
  // longest edge squared (collinear corners give ~1e-16 from rounding). Range [0, 0.5).
  double zero_area_relative = 1e-12;

  void Check() const;
};

// What ValidateMesh found; every field is a count (0 everywhere: a clean mesh). Faces with an index out of
// range are left out of every other face count; faces with a repeated index (degenerate) are left out of the
// edge, orientation and manifold counts.
struct MeshValidation {
  int64_t out_of_range_indices = 0;     // face corners whose index is outside [0, #V)
  int64_t degenerate_faces = 0;         // faces using one vertex twice or three times
  int64_t zero_area_faces = 0;          // distinct vertices but (near) collinear, see zero_area_relative
  int64_t duplicate_faces = 0;          // faces with the same vertex set as an earlier face (any order)
  int64_t non_finite_vertices = 0;      // vertices with a NaN or infinite coordinate
  int64_t out_of_scale_vertices = 0;    // finite vertices with a coordinate beyond ±kMaxCoordinate
  int64_t below_scale_extent = 0;       // 1 when the finite positions differ but span less than kMinExtent
  int64_t unreferenced_vertices = 0;    // vertices no face uses
  int64_t non_manifold_edges = 0;       // edges shared by three or more faces
  int64_t non_manifold_vertices = 0;    // vertices whose faces form more than one fan (bow ties)
  int64_t inconsistent_edges = 0;       // edges whose two faces run along it in the same direction
  int64_t boundary_edges = 0;           // edges with one face (not a defect; reported for context)

  // True when no defect was found (boundary edges are not defects).
  bool clean() const;
};

MeshValidation ValidateMesh(const Mesh& mesh, const ValidateMeshOptions& options = {});

// One readable line per non-zero defect count ("3 duplicate faces"); empty for a clean mesh.
std::vector<std::string> DescribeFindings(const MeshValidation& validation);

}  // namespace rangebayes
