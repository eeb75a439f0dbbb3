// A preconditioner for the smoother's CG on meshes with anisotropic, ray-aligned covariances (stereo and range
// scans; docs/design.md "Solver"). Along each viewing ray the data term is weak and the prior couples the depths
// of neighbouring vertices like a biharmonic operator over the pixel grid: the slow modes of CG preconditioned by
// the data term alone. Across the ray the data term dominates, and its exact inverse is enough there.
//
// So the state is split per vertex into its weak direction r_i (the eigenvector of W_i with the smallest
// eigenvalue) and the plane across it:
//
//   z = r · A⁻¹ (rᵀ g) + (2 W)⁻¹ (g − r rᵀ g),
//
// A the Gauss–Newton matrix of the energy in the depths along r (SmoothingEnergy::RayGaussNewton) at the state of
// the last Update(). A⁻¹ is applied by a multigrid V-cycle over the pixel-grid hierarchy (bayes/grid_hierarchy.h)
// with Galerkin coarse matrices Pᵀ A P and symmetric Gauss–Seidel smoothing, the coarsest level factorised
// (sparse LDLᵀ); without a hierarchy, A itself is factorised. Both are fixed symmetric positive definite operators
// between updates, as CG needs.
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <vector>

#include "bayes/smoothing_energy.h"

namespace rangebayes {

// Meshes up to this many vertices factorise A directly (measured: on a 19,910-vertex stereo mesh the
// factorisation needs half the iterations of the V-cycle for less work in all); larger ones need the hierarchy.
constexpr int kRayDirectVertices = 40000;

class RayPreconditioner {
 public:
  // prolongations[k]: #V_k × #V_(k+1) interpolation from level k+1 to level k (rows of the first in the energy's
  // vertex order), used above kRayDirectVertices vertices; at or below it A is factorised directly. `energy` must
  // outlive this object; nothing is computed before the first Update().
  // direct_vertices: the size up to which A is factorised (tests set it to reach the multigrid on small meshes).
  RayPreconditioner(const SmoothingEnergy& energy, std::vector<Eigen::SparseMatrix<double>> prolongations,
                    int direct_vertices = kRayDirectVertices);

  // Rebuilds A (and the coarse levels) at state x. False when the preconditioner does not apply (a mesh above
  // kRayDirectVertices without a hierarchy) or the coarsest factorisation failed; Apply then falls back to the
  // data term's inverse.
  bool Update(const Eigen::VectorXd& x);

  // z = M⁻¹ g.
  void Apply(const Eigen::VectorXd& g, Eigen::VectorXd* z) const;

  int num_levels() const { return static_cast<int>(levels_.size()); }
  int updates() const { return updates_; }
  size_t MemoryBytes() const;

 private:
  struct Level {
    Eigen::SparseMatrix<double, Eigen::RowMajor> a;  // full symmetric; empty on level 0 (that is a_)
    Eigen::VectorXd inverse_diagonal;
  };
  void Cycle(int k, const Eigen::VectorXd& b, Eigen::VectorXd* x) const;
  static constexpr int kSweeps = 3;

  const SmoothingEnergy& energy_;
  std::vector<double> rays_;  // 3 per vertex
  std::vector<Eigen::SparseMatrix<double>> prolongations_;  // level k+1 → level k (fixed)
  std::vector<Eigen::SparseMatrix<double>> restrictions_;   // their transposes
  std::vector<Level> levels_;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> coarsest_;
  int direct_vertices_;
  // The pattern coarsest_ was analysed for: the Galerkin products drop exact zeros, so a weight that the
  // Gauss–Newton matrix clips to 0 (a learned prior's falling stretch) changes the coarse pattern between updates,
  // and factorize() on a pattern other than the analysed one writes outside its buffers.
  std::vector<int> analysed_outer_, analysed_inner_;
  bool valid_ = false;
  int updates_ = 0;
  // A's entries refilled in place: the pattern of SmoothingEnergy::RayGaussNewton, its values, and for each value
  // the positions in a_'s value array of its entry and (off the diagonal) of its mirror (the pattern keeps only
  // its face offsets once the slots are made).
  SmoothingEnergy::RayPattern pattern_;
  std::vector<double> values_;
  std::vector<int> slots_;  // 2 per value; −1: none
  Eigen::SparseMatrix<double> a_;
};

}  // namespace rangebayes
