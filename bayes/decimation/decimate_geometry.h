// The geometric half of Bayesian decimation (paper §6.2, last paragraphs): from a dense manifold mesh and its
// patch map g, the coarse triangle mesh that keeps only the vertices the patch structure needs, triangulated
// patch by patch, plus the per-patch linear normal fields used for shading.
//
// How the patches are triangulated: instead of cutting each patch out and re-triangulating its boundary
// polygon in a plane (which needs a simple projected polygon, hole bridging, and breaks on patches that wrap
// around), the dense mesh is reduced in place by half-edge collapses that never cross a patch: a vertex inside
// a patch collapses onto a neighbour, a vertex on a patch-boundary chain (exactly two feature edges: patch
// boundaries or mesh boundary) collapses along its chain. Every face keeps its patch label, so each output
// triangle lies in one patch and the patch boundaries survive as chains between the kept vertices. A collapse
// is refused when it would
//   - break the link condition (link(u) ∩ link(v) = link(uv), with the mesh boundary as a virtual vertex),
//     which is what keeps the output a manifold of the input's topology (Dey et al. 1999);
//   - create a duplicate face, or leave a patch without faces;
//   - flip a triangle: every moved triangle must stay within 90° of its patch normal (cosine above
//     `min_cos_to_patch_normal`) in every pose and keep a positive area. A patch that is closed or nearly so
//     has no such normal (its faces' area vectors cancel, PatchConeAxes); there each moved triangle must stay
//     within 90° of the dense normal at each of its corners instead (DenseVertexNormals), a reference that
//     collapses cannot drift, so a closed surface is never folded or flattened across itself.
// Vertices whose collapses are all refused stay: the fallback for a patch that cannot be reduced to its
// corners is to keep more of its vertices, never to emit a broken triangle. Kept without condition: vertices
// with three or more feature edges (where three patches meet, or two patches meet the mesh boundary, or a
// patch touches itself), vertices the caller locks, and three vertices of every closed chain that has no
// corner (so an island patch keeps a triangle). A chain is simplified only while its removed vertices stay
// within `chain_tolerance_rel` of it, so a curved crease or a square's outline keeps its shape (the paper keeps
// only the vertices where three patches meet; that would turn an open square into a triangle).
#pragma once

#include <Eigen/Core>
#include <array>
#include <vector>

#include "core/mesh.h"

namespace rangebayes {

// A patch's faces must have |Σ area vectors| ≥ this share of Σ areas for its normal to orient its triangles. A
// closed surface sums to zero (up to rounding) and a spherical cap of half-angle θ to (1 + cos θ) / 2, so 0.1 treats
// as closed only patches that wrap around beyond θ ≈ 143°, where the cone of the patch normal (≤ 90°) has long
// stopped holding the patch's faces anyway.
constexpr double kMinPatchNormalCoherence = 0.1;

// Per patch of faces F in pose V: the unit sum of its faces' area vectors, the axis of the cone the guards keep
// its triangles in; zero when that sum is shorter than kMinPatchNormalCoherence × the patch's area (or the
// patch has none), a patch whose triangles are then oriented by the dense normals of their corners.
std::vector<Eigen::Vector3d> PatchConeAxes(const Vertices& V, const Faces& F, const std::vector<int>& face_patch,
                                           int num_patches);

// Per vertex of F in pose V: the unit sum of the area vectors of its faces (zero where it vanishes).
std::vector<Eigen::Vector3d> DenseVertexNormals(const Vertices& V, const Faces& F);

// Whether triangle area vector `cross` lies in the guards' cone for a face of a patch with cone axis `axis`
// (PatchConeAxes) and corners `corners`: cosine ≥ min_cos to the axis, or, where the axis is zero, to the
// dense normal at each corner (vertex_normal, DenseVertexNormals).
bool InPatchCone(const Eigen::Vector3d& cross, const Eigen::Vector3d& axis, const std::array<int, 3>& corners,
                 const std::vector<Eigen::Vector3d>& vertex_normal, double min_cos);

struct PatchTriangulationOptions {
  double min_cos_to_patch_normal = 0.02;  // cosine a moved triangle keeps to its patch normal, [0, 1)
  // A chain vertex is removed only while every removed vertex of its chain stays within this distance of
  // the simplified chain (share of the bounding-box diagonal), [0, ∞). 0 keeps straight chains only.
  double chain_tolerance_rel = 0.005;
  // > 0: after the pass above, chain vertices are removed in order of the chain error their removal causes
  // (largest distance of a removed vertex to the straightened chain), least first, until at most this many
  // faces remain or no chain vertex can go. The budget goes where the boundaries are straightest, and the
  // kept chain vertices are those where the boundaries curve most. 0: no budgeted pass.
  int target_faces = 0;
  // > target_faces (with target_faces > 0): PatchTriangulation::recorded also holds the triangulation as it
  // was when the budgeted pass first had at most this many faces, the result of a run with this target.
  int record_faces = 0;
};

struct PatchTriangulation {
  Faces F;                      // output faces, indices into the dense vertex array
  std::vector<int> face_patch;  // per output face
  int kept_corner_vertices = 0;     // vertices kept unconditionally (≥ 3 feature edges, welded, loop anchors)
  int blocked_vertices = 0;         // removable vertices kept because every collapse was refused
  int collapses = 0;
  long long collapse_attempts = 0;  // collapses tested (refused ones included)
  long long pops = 0;
  // Budgeted pass (target_faces > 0): the largest chain error accepted, share of the bounding-box diagonal.
  double max_chain_error_rel = 0.0;
  // Per dense vertex, the kept vertex its star collapsed onto (itself when kept), −1 for one no face used.
  std::vector<int> representative;
  // Per dense vertex, 1 when it is kept unconditionally (those of them that F uses are kept_corner_vertices).
  std::vector<char> unconditional;
  // With PatchTriangulationOptions::record_faces: the triangulation at that face count (one entry; empty when
  // the pass never had that few faces).
  std::vector<PatchTriangulation> recorded;
};

// poses: M ≥ 1 vertex arrays of one connectivity F (manifold: each edge in ≤ 2 faces with opposite
// orientation, each vertex a single fan). face_patch: per face in [0, num_patches). weld_group: per vertex, −1,
// or the id shared by the copies of one vertex that the caller welds back together afterwards (may be empty).
// Those vertices stay, and no collapse joins two of them by an edge F does not have or gives two copies of one
// id a common neighbour that they did not have: welded, such an edge made in two sheets would be shared by
// more than two faces, or two boundary edges would merge (closing a hole). boundary_vertex: per vertex, 1 on
// the mesh boundary (empty: derived here; callers that have the edge topology already pass it to save a sort).
PatchTriangulation TriangulatePatches(const std::vector<const Vertices*>& poses, const Faces& F,
                                      const std::vector<int>& face_patch, int num_patches,
                                      const std::vector<int>& weld_group, const PatchTriangulationOptions& options = {},
                                      const std::vector<char>& boundary_vertex = {});

// A linear normal field n(p) = a + G·(E·(p − c)) over one patch in one pose: c the weighted centroid of its
// dense face centroids, E the 2×3 tangent basis of the patch plane, a the mean normal, G 3×2.
struct PatchNormalField {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  Eigen::Matrix<double, 2, 3> basis = Eigen::Matrix<double, 2, 3>::Zero();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Matrix<double, 3, 2> gradient = Eigen::Matrix<double, 3, 2>::Zero();

  // The unit normal at p (the normalised mean when the field vanishes there).
  Eigen::Vector3d Evaluate(const Eigen::Vector3d& p) const;
};

// Least-squares fit of one field per patch to the dense face normals placed at the face centroids, weighted
// by `face_weight`. Ridge regularisation on G of `regularisation` × the patch's centroid spread keeps small
// and nearly collinear patches well posed; patches with fewer than 3 faces get G = 0 (constant normal).
std::vector<PatchNormalField> FitPatchNormalFields(const Vertices& V, const Faces& F,
                                                   const std::vector<double>& face_weight,
                                                   const std::vector<int>& face_patch, int num_patches,
                                                   double regularisation);

}  // namespace rangebayes
