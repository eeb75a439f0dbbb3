// Vertex refit, the continuous half of the paper's mixed discrete–continuous optimisation (docs/design.md §6): with
// the patch structure and the coarse triangulation fixed, each kept vertex moves to the minimiser of the
// Garland–Heckbert quadric of the dense faces it stands for (the faces around the dense vertices whose stars
// collapsed onto it, plus perpendicular planes along the mesh boundary), regularised towards its dense
// position, under the flip guard of the reduction (bayes/decimation/decimate_geometry.h).
//
//   Q_v(x) = Σ_{f ∈ cluster(v)} A_f (n_fᵀ x − n_fᵀ p_f)² + Σ_{boundary edges e} w_b |e|² (m_eᵀ x − m_eᵀ p_e)²
//   x_v = argmin Q_v(x) + α_v ‖x − x_v⁰‖²,   α_v = regularisation · trace(quadric matrix of v) / 3
//
// The step towards x_v is halved up to `max_halvings` times while any triangle of v would lose area, reverse
// its orientation (against its orientation before the step or before the refit: no sequence of moves turns a
// triangle by more than 90°) or leave the cone of its patch normal (InPatchCone in
// bayes/decimation/decimate_geometry.h: the dense normals at its corners for a closed patch); otherwise the vertex
// stays. Since Q_v + α_v‖·‖² is convex and equals Q_v at x_v⁰, every accepted step lowers Q_v: the refit never
// increases the quadric error. Then `fit_rounds` rounds fit the kept vertices to the dense vertices themselves (each
// projected onto the nearest coarse face around the vertex it collapsed onto; per kept vertex the regularised minimiser
// of the area-weighted point-to-plane distances of the samples on its faces, weighted by their barycentric share, plus
// the boundary planes), under the same guard; this lowers the surface distance further (Hoppe et al. 1993).
// That distance is one-sided: a coarse cone over a rounded tip grows outward until its faces reach the dense
// vertices there. So the fit also holds the coarse surface on the dense one (the other half of the symmetric
// distance): four points of each coarse triangle (its centroid and the points halfway from there to its
// corners), each at its nearest point among the dense faces of the triangle's patch around the dense vertices
// its corners stand for, add their squared distances along that dense face's normal, weighted by
// `coverage_weight` × a quarter of the triangle's area (the dense vertices weigh their areas; the default 2, the
// coarse side at twice the weight per unit of area, was chosen on meshes outside the decimation benchmark).
// RefitVertices leaves the connectivity untouched, so manifoldness and the patch map are kept as they are.
// FlipEdgesToFit below is the discrete half: the decimator runs the quadric step alone, flips edges at those
// positions, then RefitVertices in full on the flipped faces (DecimateOptions::refit, flip_sweeps).
#pragma once

#include <vector>

#include "core/mesh.h"

namespace rangebayes {

struct VertexRefitOptions {
  double regularisation = 0.01;           // α_v as a share of the quadric's mean eigenvalue, > 0
  double boundary_weight = 1.0;           // weight of the boundary planes against the face planes, ≥ 0
  int max_halvings = 4;                   // step halvings tried before a vertex stays, ≥ 0
  int fit_rounds = 2;                     // rounds of the fit to the dense vertices after the quadric step, ≥ 0
  double coverage_weight = 2.0;           // weight of the coarse points' distances to the dense faces in the fit, ≥ 0
  int flip_sweeps = 4;                    // sweeps of FlipEdgesToFit before the full refit (at most), ≥ 0; 0: none

  // Throws Error naming the field that is out of range.
  void Check() const;
};

struct VertexRefitSummary {
  int moved = 0;    // vertices that took their full or a halved step
  int blocked = 0;  // vertices that stayed because every step would flip or squash a triangle
  double quadric_error_before = 0.0, quadric_error_after = 0.0;  // Σ_v Q_v over the refitted vertices
  // Area-weighted RMS distance of the dense vertices to the coarse faces they project onto (fit_rounds > 0),
  // after the quadric step and after the fit.
  double fit_rms_before = 0.0, fit_rms_after = 0.0;
};

// The dense surface and how the coarse mesh covers it. All vertex ids index the dense vertex array.
struct RefitInput {
  const Vertices* dense_V = nullptr;       // dense positions of this pose
  const Faces* dense_F = nullptr;          // dense faces
  const std::vector<int>* dense_face_patch = nullptr;  // per dense face, its patch
  const std::vector<int>* representative = nullptr;    // per dense vertex, the kept vertex it collapsed onto, or −1
  const std::vector<char>* boundary_vertex = nullptr;  // per dense vertex, 1 on the mesh boundary (may be empty)
  const std::vector<char>* fixed = nullptr;            // per dense vertex, 1 to keep it where it is (may be empty)
  const Faces* coarse_F = nullptr;                     // coarse faces over dense vertex ids
  const std::vector<int>* coarse_face_patch = nullptr;  // per coarse face, its patch
  int num_patches = 0;
  // The flip guard's cosine to the patch normal, [0, 1): the reduction's (DecimateOptions::min_cos_to_patch_normal).
  double min_cos_to_patch_normal = 0.02;
};

// Returns the dense vertex array with the kept vertices moved (other rows as in dense_V). Throws Error for
// inconsistent sizes or a cosine outside [0, 1).
Vertices RefitVertices(const RefitInput& input, const VertexRefitOptions& options = {},
                       VertexRefitSummary* summary = nullptr);

// The discrete half of the same fit: edges between two coarse faces of one patch are flipped where the other
// diagonal of their quadrilateral lies closer to the dense vertices (Hoppe et al. 1993's edge swap). Each dense
// vertex is a sample of the coarse face nearest to it around its representative (in the first pose); a flip is
// taken when the samples of the two faces, each moved to the nearer new triangle (first pose), come closer to
// their faces (squared distances weighted by the dense vertex areas, summed over the poses) by more than 1e-6
// of the sum, so that every flip lowers the sum and the sweeps end. A flip is refused when the new edge exists
// already (so the mesh stays manifold with the same vertices, faces and patches), joins two vertices of weld
// groups or gives two copies of one weld group a common neighbour (TriangulatePatches' weld_group), or when, in any
// pose, a new triangle would lose its area, leave the cone of its patch normal (InPatchCone) or fold onto its
// partner. Sweeps over the edges in a fixed order until one flips nothing or `max_sweeps` ran.
struct EdgeFlipInput {
  std::vector<const Vertices*> dense_poses;            // per pose, the dense positions (the samples)
  std::vector<const Vertices*> coarse_poses;           // per pose, the coarse vertices' positions; empty: dense
  const Faces* dense_F = nullptr;
  const std::vector<int>* dense_face_patch = nullptr;  // per dense face, its patch
  const std::vector<int>* representative = nullptr;    // per dense vertex, its kept vertex, or −1
  const std::vector<int>* coarse_face_patch = nullptr; // per coarse face, its patch
  int num_patches = 0;
  // Per dense vertex, −1 or the id shared by the copies of one vertex that are welded together afterwards (may be
  // null or empty; TriangulatePatches' weld_group).
  const std::vector<int>* weld_group = nullptr;
};

struct EdgeFlipSummary {
  int flips = 0;
  int sweeps = 0;
  // Area-weighted RMS distance of the dense vertices to their coarse faces (first pose), before and after.
  double fit_rms_before = 0.0, fit_rms_after = 0.0;
};

// Flips edges of *coarse_F (faces over dense vertex ids) in place. Throws Error for inconsistent sizes.
void FlipEdgesToFit(const EdgeFlipInput& input, double min_cos_to_patch_normal, int max_sweeps, Faces* coarse_F,
                    EdgeFlipSummary* summary = nullptr);

}  // namespace rangebayes
