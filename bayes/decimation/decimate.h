// Bayesian decimation (paper §6, docs/design.md §6): replace a dense mesh by planar patches that look like it when
// rendered, static or shared across the poses of an animated mesh.
//
//   E(g) = λ·#patches + Σ_i w_i ‖u_i − n_g(i)‖²   (paper eqs. 28–31 with W = I; eq. 36 sums it over poses)
//
// u_i the unit normal of dense face i, n_k the weighted mean of its patch's normals (eq. 34, not
// renormalised), g a map from faces to edge-connected patches found by hill climbing (fuse, split, swap;
// bayes/decimation/decimate_partition.h). The output keeps the dense vertices the patch structure needs and
// triangulates each patch on its own (bayes/decimation/decimate_geometry.h), with per-corner normals from a linear
// normal field fitted per patch (the smooth shading of the paper's figures).
//
// Face weights: area weighting is the default. The paper weights every face equally, which is the same thing
// on the regular grids its scans come from; on meshes whose triangle sizes vary (CAD models such as fandisk,
// where a flat side is a few large triangles and a fillet hundreds of slivers) equal weights let the small
// triangles dominate the energy although they cover little of the rendered image. Area weights follow what a
// rendering shows, and zero-area faces (undefined normals) drop out. The weights are normalised to mean 1 over
// the faces, so λ keeps the paper's scale: one patch costs as much as λ faces' worth of squared normal
// difference. Two patches of a and b faces whose normals differ by θ fuse when (ab/(a+b))·2(1 − cos θ) < λ
// (two single faces: 1 − cos θ < λ). `target_faces` finds λ for a requested triangle count instead.
//
// Target faces: a triangle budget is split between patches (each costs its corner vertices) and the detail
// of the patch boundaries (chain vertices). The search finds in log λ the smallest λ (to lambda_resolution)
// whose patches, with every chain straightened as far as the manifold and flip guards allow, fit in
// (1 − chain_reserve_share) of the budget (fewer patches usually fit at larger λ, but not always: see below); at
// that λ the chains are then straightened only down to the full budget,
// least chain error first, so the kept chain vertices are those where the boundaries curve most. Full
// decimations (hill climbing + triangulation) decide the bracket; the search is guided by the hill climbing
// alone, predicting the count from the vertices where ≥ 3 patch sides meet (times the faces per such vertex
// measured on the last full runs, 2 before any), with power-law extrapolation and safeguarded interpolation.
// Each round runs a full decimation at the guide's smallest fitting λ and, beside it on a second core, another
// one resolution step below it, which counts only when the first fits. The hill climbings of the search start from the
// partition at the smallest λ climbed (warm starts: coarsening it costs a fraction of a climb from single faces),
// and the output at the full budget is recorded on the way of the fitting run's chain pass. A climb's local optimum
// depends on where it starts, so a run with `lambda` set to a λ the search reports (a climb from single faces) can
// give other patches and another face count.
// The face count need not fall with λ: a large curved patch keeps vertices against flipped triangles, and when it
// merges into one patch that wraps around (closed patches are reduced by other guards) the count can jump from
// far above the target to far below it within the resolution. Where the smallest fitting λ's output comes below
// target − 1, the output is that of the λ tried whose output at the target has the most faces within it (its
// straightened patches may need more than the budget); a notice says so whenever the output has fewer faces than
// both the budget and target − 1, with what was reached and why.
#pragma once

#include <string>
#include <vector>

#include "bayes/decimation/decimate_refit.h"
#include "core/mesh.h"
#include "core/mesh_io.h"
#include "core/progress.h"

namespace rangebayes {

enum class DecimateWeighting { kArea, kUniform };

struct DecimateOptions {
  double lambda = 2.0;  // λ, the energy one patch costs (normal difference² × faces), > 0
  // > 0: find λ for this many output triangles (see "Target faces" above). The output normally has target_faces
  // or target_faces − 1 triangles; more when even one patch per component needs more (a notice says so), fewer
  // when the patches at the λ found come below the target with all their chain vertices, or when the face count
  // jumps past the target between two λ a resolution step apart (a notice says so when below the budget).
  int target_faces = 0;
  // With target_faces: share of the budget kept for patch-boundary detail, [0, 1). λ is the smallest for which
  // the patches with fully straightened chains fit in (1 − share)·target_faces triangles; the rest of the
  // budget keeps the chain vertices of largest chain error. Default 0.2, measured (BENCHMARKS.md): against 0
  // (all to patches) it halves the rendering difference and the Hausdorff distance on the smoothed angel scan
  // at 10% and lowers the normal error on bunny at 2% and on elephant, for ≤ 0.3° more normal error elsewhere;
  // 0.35 was worse than 0.2 on the angel scan's and elephant's normal errors.
  double chain_reserve_share = 0.2;
  double lambda_resolution = 0.02;  // the λ search stops when λ_fits / λ_too_many ≤ 1 + this, (0, 1)
  int max_bisection_steps = 30;     // full decimations tried when searching λ (guided runs not counted), ≥ 2
  DecimateWeighting weighting = DecimateWeighting::kArea;
  int max_rounds = 200;                   // hill-climbing rounds (fuse phase + split/swap phase), ≥ 1
  // An output triangle's normal keeps this cosine to its patch's, [0, 1): the guard of the reduction, the edge flips
  // and the vertex refit (a triangle moved by them; see bayes/decimation/decimate_geometry.h for closed patches).
  double min_cos_to_patch_normal = 0.02;
  // Patch-boundary chains are simplified while removed vertices stay within this share of the bounding-box
  // diagonal of the simplified chain, [0, ∞) (see bayes/decimation/decimate_geometry.h).
  double chain_tolerance_rel = 0.005;
  double shading_regularisation = 0.01;   // ridge on the normal-field gradient, share of the patch spread, ≥ 0
  // > 0: the corner normals are then refitted to the dense face normals as a piecewise-linear field over each
  // patch's triangles (each dense face fitted where the output covers it, for the angle: RefitCornerNormals in
  // decimate.cpp), with this ridge (share of each normal's data weight) towards the patch field; 0 keeps the
  // patch fields' values. ≥ 0.
  double corner_normal_ridge = 0.01;
  // After the patch structure and triangulation are fixed, move the kept vertices to their regularised
  // quadric-optimal positions under the flip guard (bayes/decimation/decimate_refit.h); false keeps the
  // output's vertices a subset of the input's.
  bool refit_vertices = true;
  VertexRefitOptions refit;
  ProgressCallback progress;              // optional

  // Throws Error naming the field that is out of range.
  void Check() const;
};

struct DecimateSummary {
  double lambda = 0.0;  // the λ used (found by the search when target_faces > 0)
  int target_faces = 0;       // DecimateOptions::target_faces of the run (0: λ given)
  bool refitted = false;      // DecimateOptions::refit_vertices of the run
  int poses = 0;              // meshes decimated with one patch map
  int input_faces = 0;
  int num_patches = 0;
  int output_faces = 0;
  int output_vertices = 0;
  double energy = 0.0;       // λ·#patches + data term, summed over poses
  double data_energy = 0.0;  // Σ w ‖u − n‖² over faces and poses
  long long fuses = 0, splits = 0, swaps = 0;  // moves applied
  long long rejected_disconnecting = 0;        // split/swap moves refused because they would cut a patch
  int rounds = 0;
  bool converged = false;  // the last round found no improving move
  int bisection_steps = 0;  // full decimations the λ search ran
  // The λ search's final bracket (target_faces > 0): at lambda_too_many the straightened patches need
  // faces_too_many > budget_faces triangles, at lambda_fits faces_fits ≤ budget_faces. lambda_fits is the λ used
  // unless its output came below target − 1 and another λ tried gave more faces within the target (see "Target
  // faces"), or no λ tried fits. lambda_too_many = 0 when even the smallest λ tried fits; lambda_fits = 0 when no
  // λ tried fits.
  int budget_faces = 0;
  double lambda_too_many = 0.0, lambda_fits = 0.0;
  int faces_too_many = 0, faces_fits = 0;
  double max_chain_error_rel = 0.0;  // largest chain error the budgeted chain pass accepted, share of the diagonal
  // Output vertices where ≥ 3 patch sides meet (and loop anchors, copies of a non-manifold input vertex), and the
  // others (kept because removing them would flip or break something, or the dense fallback's).
  int kept_corner_vertices = 0;
  int blocked_vertices = 0;
  bool fell_back_to_dense = false;  // the reduced mesh failed the topology check; the dense faces were kept
  double seconds_partition = 0.0;
  double seconds_geometry = 0.0;
  double seconds_refit_and_shading = 0.0;
  // Over every λ tried (target_faces > 0; otherwise the one run): hill climbing, and triangulation with checks.
  double seconds_search_partition = 0.0, seconds_search_geometry = 0.0;
  // Vertex refit, summed over poses: vertices moved and kept in place, Σ quadric error before and after.
  int refit_moved = 0, refit_blocked = 0;
  int refit_flips = 0;  // edges flipped inside patches before the refit (VertexRefitOptions::flip_sweeps)
  double refit_quadric_before = 0.0, refit_quadric_after = 0.0;
  // Of the first pose: the fit's area-weighted RMS distance of the dense vertices to the coarse faces, before
  // and after the fit rounds (VertexRefitSummary).
  double refit_rms_before = 0.0, refit_rms_after = 0.0;
  double seconds_total = 0.0;
  std::vector<std::string> notices;  // one line each: input problems found and how they were handled

  // Input and output sizes, λ (and its search), moves, kept vertices, the refit and the times, one per line.
  std::string BriefReport() const;
};

// One decimated pose.
struct DecimatedMesh {
  Mesh mesh;                     // output triangles; vertices: the input's kept ones, refitted (see refit_vertices)
  CornerNormals corner_normals;  // per-corner shading normals from the patch normal fields
  std::vector<int> face_patch;   // per output face, its patch in [0, num_patches)
  std::vector<int> vertex_source;         // per output vertex, its index in the input
  std::vector<int> dense_face_patch;      // per input face, its patch (−1 for a dropped degenerate face)
  std::vector<std::vector<int>> polygons;  // one polygon per patch (a patch that is not a disk: its triangles)
  int num_patches = 0;
};

// Decimates one mesh. Handles non-manifold input (cut apart, decimated with the cut vertices kept, welded
// back), zero-area faces (weight 0), faces that repeat a vertex (dropped), several components and open
// boundaries; each is reported in summary->notices. Throws Error for an empty mesh or NaN positions.
DecimatedMesh Decimate(const Mesh& mesh, const DecimateOptions& options = {}, DecimateSummary* summary = nullptr);

// Decimates M poses of one connectivity with one shared patch map (paper §6.3, eq. 36): the energy sums over
// poses, so a patch that bends in any pose splits. Returns one DecimatedMesh per pose, all with the same
// faces and patches. Throws Error when the poses differ in vertex count or faces.
std::vector<DecimatedMesh> DecimateAnimated(const std::vector<Mesh>& poses, const DecimateOptions& options = {},
                                            DecimateSummary* summary = nullptr);

// What keeps `pose` from having the connectivity of `first` (DecimateAnimated needs the same vertex count and the
// same faces in the same order, corners included), in words: the counts, or the first face that differs (same
// corners reversed, rotated, or other vertices, and whether the triangles are the same in another order) and how
// many differ; empty when they agree.
std::string ConnectivityDifference(const Mesh& first, const Mesh& pose);

// Shading error of a decimation that shares the dense mesh's patch map: the area-weighted mean angle
// (degrees) between each dense face normal and the patch's shading normal at the face centroid, for `pose`
// with patches `dense_face_patch` (fields fitted on that pose). Used to compare animated decimations.
double PatchShadingErrorDeg(const Mesh& pose, const std::vector<int>& dense_face_patch, double regularisation = 0.01);

}  // namespace rangebayes
