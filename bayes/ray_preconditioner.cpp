#include "bayes/ray_preconditioner.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <utility>

namespace rangebayes {

RayPreconditioner::RayPreconditioner(const SmoothingEnergy& energy,
                                     std::vector<Eigen::SparseMatrix<double>> prolongations, int direct_vertices)
    : energy_(energy), direct_vertices_(direct_vertices) {
  if (energy.num_vertices() <= direct_vertices) return;
  prolongations_ = std::move(prolongations);
  for (const Eigen::SparseMatrix<double>& p : prolongations_) restrictions_.push_back(p.transpose());
}

bool RayPreconditioner::Update(const Eigen::VectorXd& x) {
  const int nv = energy_.num_vertices();
  if (nv > direct_vertices_ && prolongations_.empty()) return false;  // too large to factorise, no hierarchy
  if (rays_.empty()) {
    rays_.resize(3 * static_cast<size_t>(nv));
    for (int i = 0; i < nv; ++i) {
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(energy_.InformationMatrix(i));
      const Eigen::Vector3d r = solver.eigenvectors().col(0);
      for (int k = 0; k < 3; ++k) rays_[3 * static_cast<size_t>(i) + k] = r[k];
    }
  }
  if (slots_.empty()) {
    pattern_ = energy_.RayGaussNewtonPattern();
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(2 * pattern_.entries.size());
    for (const auto& [row, column] : pattern_.entries) {
      triplets.emplace_back(row, column, 1.0);
      if (row != column) triplets.emplace_back(column, row, 1.0);
    }
    a_.resize(nv, nv);
    a_.setFromTriplets(triplets.begin(), triplets.end());
    a_.makeCompressed();
    auto slot = [&](int row, int column) {
      const int* begin = a_.innerIndexPtr() + a_.outerIndexPtr()[column];
      const int* end = a_.innerIndexPtr() + a_.outerIndexPtr()[column + 1];
      return static_cast<int>(std::lower_bound(begin, end, row) - a_.innerIndexPtr());
    };
    slots_.resize(2 * pattern_.entries.size());
    for (size_t q = 0; q < pattern_.entries.size(); ++q) {
      const auto [row, column] = pattern_.entries[q];
      slots_[2 * q] = slot(row, column);
      slots_[2 * q + 1] = row != column ? slot(column, row) : -1;
    }
    pattern_.entries = {};  // placed: only the slots and the face offsets are needed from here on
  }
  energy_.RayGaussNewton(x, rays_, pattern_, &values_);
  double* a_values = a_.valuePtr();
  std::fill(a_values, a_values + a_.nonZeros(), 0.0);
  for (size_t q = 0; q < values_.size(); ++q) {
    a_values[slots_[2 * q]] += values_[q];
    if (slots_[2 * q + 1] >= 0) a_values[slots_[2 * q + 1]] += values_[q];
  }
  // Level 0 is a_ (symmetric exactly: an entry and its mirror get the same sums), the coarser ones Galerkin
  // products Pᵀ A P; the coarsest is factorised.
  levels_.resize(prolongations_.size() + 1);
  Eigen::SparseMatrix<double> coarse;
  for (size_t k = 0; k + 1 < levels_.size(); ++k) {
    Level& level = levels_[k];
    if (k > 0) level.a = coarse;
    const Eigen::SparseMatrix<double>& ak = k == 0 ? a_ : coarse;
    level.inverse_diagonal = ak.diagonal().cwiseInverse();
    Eigen::SparseMatrix<double> next = (restrictions_[k] * ak * prolongations_[k]).pruned();
    coarse = std::move(next);
  }
  const Eigen::SparseMatrix<double>& a = levels_.size() == 1 ? a_ : coarse;
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
  const auto columns = static_cast<size_t>(a.outerSize()) + 1;
  const auto entries = static_cast<size_t>(a.nonZeros());
  if (analysed_outer_.size() != columns || analysed_inner_.size() != entries ||
      !std::equal(outer, outer + columns, analysed_outer_.begin()) ||
      !std::equal(inner, inner + entries, analysed_inner_.begin())) {
    coarsest_.analyzePattern(a);
    analysed_outer_.assign(outer, outer + columns);
    analysed_inner_.assign(inner, inner + entries);
  }
  coarsest_.factorize(a);
  ++updates_;
  valid_ = coarsest_.info() == Eigen::Success;
  return valid_;
}

void RayPreconditioner::Cycle(int k, const Eigen::VectorXd& b, Eigen::VectorXd* x) const {
  if (k + 1 == static_cast<int>(levels_.size())) {
    *x = coarsest_.solve(b);
    return;
  }
  const Level& level = levels_[static_cast<size_t>(k)];
  // Rows of A_k: on level 0 the columns of the symmetric a_.
  const int n = static_cast<int>(b.size());
  x->setZero(n);
  double* xv = x->data();
  const int* outer = k == 0 ? a_.outerIndexPtr() : level.a.outerIndexPtr();
  const int* inner = k == 0 ? a_.innerIndexPtr() : level.a.innerIndexPtr();
  const double* value = k == 0 ? a_.valuePtr() : level.a.valuePtr();
  const double* inverse_diagonal = level.inverse_diagonal.data();
  // x_i += (b_i − (A x)_i) / a_ii: the row sum includes the diagonal term, so no branch per entry.
  auto relax = [&](int i) {
    double sum = b[i];
    for (int q = outer[i]; q < outer[i + 1]; ++q) sum -= value[q] * xv[inner[q]];
    xv[i] += sum * inverse_diagonal[i];
  };
  // kSweeps symmetric Gauss–Seidel sweeps (2·kSweeps − 1 alternating passes) before the coarse correction,
  // forward first, and their mirror image after it, backward first, so the cycle is a symmetric operator. One
  // sweep each was too weak a smoother on this operator (docs/journal/smoothing-real-stereo.md, round 4).
  auto smooth = [&](bool forward) {
    for (int pass = 0; pass < 2 * kSweeps - 1; ++pass, forward = !forward) {
      if (forward) {
        for (int i = 0; i < n; ++i) relax(i);
      } else {
        for (int i = n - 1; i >= 0; --i) relax(i);
      }
    }
  };
  smooth(true);
  Eigen::VectorXd residual(n);
  for (int i = 0; i < n; ++i) {
    double ax = 0;
    for (int q = outer[i]; q < outer[i + 1]; ++q) ax += value[q] * xv[inner[q]];
    residual[i] = b[i] - ax;
  }
  Eigen::VectorXd coarse;
  Cycle(k + 1, restrictions_[static_cast<size_t>(k)] * residual, &coarse);
  *x += prolongations_[static_cast<size_t>(k)] * coarse;
  smooth(false);
}

void RayPreconditioner::Apply(const Eigen::VectorXd& g, Eigen::VectorXd* z) const {
  if (!valid_) {
    energy_.ApplyDataInverse(g, z);
    return;
  }
  const int nv = energy_.num_vertices();
  Eigen::VectorXd along(nv), across(g.size());
  tbb::parallel_for(tbb::blocked_range<int>(0, nv, 4096), [&](const tbb::blocked_range<int>& range) {
    for (int i = range.begin(); i != range.end(); ++i) {
      const double* r = &rays_[3 * static_cast<size_t>(i)];
      const double d = r[0] * g[3 * i] + r[1] * g[3 * i + 1] + r[2] * g[3 * i + 2];
      along[i] = d;
      for (int k = 0; k < 3; ++k) across[3 * i + k] = g[3 * i + k] - d * r[k];
    }
  });
  energy_.ApplyDataInverse(across, z);
  Eigen::VectorXd depth;
  Cycle(0, along, &depth);
  tbb::parallel_for(tbb::blocked_range<int>(0, nv, 4096), [&](const tbb::blocked_range<int>& range) {
    for (int i = range.begin(); i != range.end(); ++i) {
      const double* r = &rays_[3 * static_cast<size_t>(i)];
      for (int k = 0; k < 3; ++k) (*z)[3 * i + k] += depth[i] * r[k];
    }
  });
}

size_t RayPreconditioner::MemoryBytes() const {
  size_t bytes = rays_.size() * sizeof(double) + values_.capacity() * sizeof(double) +
                 slots_.capacity() * sizeof(int) +
                 pattern_.face_offsets.capacity() * sizeof(size_t) + static_cast<size_t>(a_.nonZeros()) * 12;
  if (valid_) bytes += static_cast<size_t>(coarsest_.matrixL().nestedExpression().nonZeros()) * 12;
  for (const Level& level : levels_) bytes += static_cast<size_t>(level.a.nonZeros()) * 12;
  for (size_t k = 0; k < prolongations_.size(); ++k) {
    bytes += static_cast<size_t>(prolongations_[k].nonZeros() + restrictions_[k].nonZeros()) * 12;
  }
  return bytes;
}

}  // namespace rangebayes
