// Coarser copies of an organized mesh (one vertex per pixel of a depth image: NoisyMesh::pixel set) for
// coarse-to-fine smoothing (docs/design.md "Solver"). Along the viewing rays the data term of a stereo mesh is
// weak and the prior acts like a biharmonic operator on the pixel grid, whose long wavelengths a single-level
// minimiser resolves slowly; on a grid of twice the spacing they cost a quarter of the work and converge in far
// fewer iterations.
//
// Level k+1 from level k (grid step h → 2h):
//   - vertices: the level-k vertices at even grid positions that belong to a coarse face;
//   - faces: a coarse cell (2×2 level-k cells) gets two triangles (split along the shorter 3-D diagonal, the
//     input's orientation) when all eight level-k triangles of its four cells exist, so the discontinuity cuts of
//     the triangulation (cut edges have no faces) are never bridged;
//   - data: information W_c = Σ_f ω_fc W_f and measurement z_c = W_c⁻¹ Σ_f ω_fc W_f z_f over the level-k vertices f
//     of the 3×3 block around c with the bilinear hat weights ω ∈ {1, ½, ¼}, only over vertices that lie within
//     kConnectedEdges local edge lengths per grid step of c (so no measurement from across a depth jump enters);
//     the covariance stored is ½ W_c⁻¹;
//   - prolongation: a level-k vertex takes the hat-weighted, renormalised displacement x_c − z_c of the coarse
//     vertices of its cell that pass the same distance test (none: no displacement).
#pragma once

#include <Eigen/SparseCore>
#include <string>
#include <vector>

#include "core/mesh.h"

namespace rangebayes {

struct GridLevel {
  NoisyMesh mesh;  // pixel holds each coarse vertex's pixel (that of the level-k vertex it sits on)
  // Prolongation to the next finer level (level k): fine vertex f takes the displacements of the coarse vertices
  // coarse[offsets[f] .. offsets[f+1]) with weights weight[...] (summing to 1).
  std::vector<int> offsets;
  std::vector<int> coarse;
  std::vector<double> weight;
};

struct GridHierarchyOptions {
  int min_vertices = 1500;  // no level with fewer vertices than this, [3, 1e9]
  int max_levels = 8;       // [0, 20]
  void Check() const;
};

// The step of an organized mesh's pixel grid (the smallest pixel distance along an edge, in pixels: 1 when every
// pixel of the depth image is a vertex, 4 for `--downsample 4`), when its pixels lie on such a lattice, one vertex
// per node; 0 otherwise (no pixels, a scatter, two vertices on one pixel), and then *why_not (when not null) says
// which vertex broke the lattice.
double PixelGridStep(const NoisyMesh& mesh, std::string* why_not = nullptr);

// levels[0] is one step coarser than `fine`, levels[1] one step coarser than levels[0], and so on. Empty when
// `fine` has no pixel positions (or they are not on a regular grid), has no covariances, or is too small.
// Throws Error on bad options.
std::vector<GridLevel> BuildGridHierarchy(const NoisyMesh& fine, const GridHierarchyOptions& options = {});

// Positions on the finer level: its measurements plus the prolongated coarse displacement (coarse_positions −
// coarse measurements). `finer` is the level `level` was built from (the input for levels[0]).
Vertices ProlongPositions(const GridLevel& level, const NoisyMesh& finer, const Vertices& coarse_positions);

// The prolongations of levels[first], levels[first+1], … as sparse matrices: P_k (#V_k × #V_(k+1)) maps
// values on level k+1 to level k with the weights of GridLevel (level first−1 being the mesh that levels[first]
// was built from, the input for first = 0). vertex_order (size #V of that mesh; empty: identity) renumbers the
// first matrix's rows: row n is that mesh's vertex vertex_order[n] (a solver's order).
std::vector<Eigen::SparseMatrix<double>> ProlongationMatrices(const std::vector<GridLevel>& levels, size_t first,
                                                             const std::vector<int>& vertex_order);

}  // namespace rangebayes
