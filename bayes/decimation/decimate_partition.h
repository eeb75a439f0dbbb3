// The discrete half of Bayesian decimation (paper §6.1–6.2, docs/design.md §6): a map g from dense faces to
// contiguous patches that minimises E(g) = λ·#patches + Σ_i w_i ‖u_i − n_g(i)‖², n_k the weighted mean of
// its faces' normals (eq. 34, not renormalised), found by hill climbing with the paper's three moves.
//
// Everything here works on an abstract problem (per-face normal vectors of dimension D = 3·M for M poses,
// one weight per face, face adjacency across manifold edges), so the same code serves static and animated
// meshes: with M poses the energy sums over poses (eq. 36) and one g is shared.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/progress.h"

namespace rangebayes {

// The normals and adjacency the hill climbing sees. normals: F×D row-major (D = 3·poses), each face's
// unit normal in every pose (zero for a zero-area face); weight: F, ≥ 0; neighbours: per face the face
// across edge k (corner k → k+1), −1 at a boundary. Adjacency must be symmetric.
struct DecimationProblem {
  int dim = 3;
  std::vector<double> normals;
  std::vector<double> weight;
  std::vector<std::array<int, 3>> neighbours;
  // Corner vertex ids per face (only used for the local contiguity test around a shared vertex).
  std::vector<std::array<int, 3>> corners;

  int num_faces() const { return static_cast<int>(weight.size()); }
};

// Counts of what the hill climbing did.
struct PartitionStats {
  std::int64_t fuses = 0;
  std::int64_t splits = 0;
  std::int64_t swaps = 0;
  std::int64_t rejected_disconnecting = 0;  // split/swap candidates refused because they cut a patch
  std::int64_t bfs_fallbacks = 0;           // contiguity searches run (the fan walk and earlier refusals undecided)
  int rounds = 0;
  bool converged = false;  // a full sweep over all pairs and faces found no improving move
  int num_patches = 0;
  double energy = 0.0;       // λ·#patches + data term
  double data_energy = 0.0;  // Σ_i w_i ‖u_i − n_k‖²
};

struct PartitionOptions {
  int max_rounds = 200;  // rounds of (fuse phase, split/swap phase); ≥ 1
  // Optional start (warm start): a contiguous map face → patch id (ids in [0, F), need not be dense), for
  // example the result at a smaller λ, which the climb then coarsens. Null or empty: every face its own patch.
  const std::vector<int>* initial = nullptr;
  ProgressCallback progress;
};

// Returns g (face → patch id in [0, #patches), ids dense). λ > 0. Every patch is edge-connected within the
// adjacency. Deterministic.
std::vector<int> HillClimbPartition(const DecimationProblem& problem, double lambda,
                                    const PartitionOptions& options = {}, PartitionStats* stats = nullptr);

// E(g) computed from scratch (for tests and summaries).
double PartitionEnergy(const DecimationProblem& problem, const std::vector<int>& face_patch, double lambda,
                       double* data_energy = nullptr);

// True when every patch of g is connected across the adjacency.
bool PartitionIsContiguous(const DecimationProblem& problem, const std::vector<int>& face_patch);

}  // namespace rangebayes
