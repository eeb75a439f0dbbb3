#include "bayes/ray_preconditioner.h"

#include <Eigen/Eigenvalues>
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
  energy_.RayGaussNewton(x, rays_, &triplets_);
  Eigen::SparseMatrix<double> upper(nv, nv);
  upper.setFromTriplets(triplets_.begin(), triplets_.end());
  Eigen::SparseMatrix<double> a = upper.selfadjointView<Eigen::Upper>();
  levels_.resize(prolongations_.size() + 1);
  for (size_t k = 0; k < levels_.size(); ++k) {
    Level& level = levels_[k];
    level.a = a;
    level.a.makeCompressed();
    level.inverse_diagonal = a.diagonal().cwiseInverse();
    if (k + 1 == levels_.size()) break;
    a = (restrictions_[k] * a * prolongations_[k]).pruned();
  }
  if (!analysed_) {
    coarsest_.analyzePattern(a);
    analysed_ = true;
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
  const auto& a = level.a;
  const int n = static_cast<int>(b.size());
  x->setZero(n);
  double* xv = x->data();
  const int* outer = a.outerIndexPtr();
  const int* inner = a.innerIndexPtr();
  const double* value = a.valuePtr();
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
  const Eigen::VectorXd residual = b - a * (*x);
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
  for (int i = 0; i < nv; ++i) {
    const double* r = &rays_[3 * static_cast<size_t>(i)];
    const double d = r[0] * g[3 * i] + r[1] * g[3 * i + 1] + r[2] * g[3 * i + 2];
    along[i] = d;
    for (int k = 0; k < 3; ++k) across[3 * i + k] = g[3 * i + k] - d * r[k];
  }
  energy_.ApplyDataInverse(across, z);
  Eigen::VectorXd depth;
  Cycle(0, along, &depth);
  for (int i = 0; i < nv; ++i) {
    const double* r = &rays_[3 * static_cast<size_t>(i)];
    for (int k = 0; k < 3; ++k) (*z)[3 * i + k] += depth[i] * r[k];
  }
}

size_t RayPreconditioner::MemoryBytes() const {
  size_t bytes = rays_.size() * sizeof(double) + triplets_.capacity() * sizeof(Eigen::Triplet<double>);
  if (valid_) bytes += static_cast<size_t>(coarsest_.matrixL().nestedExpression().nonZeros()) * 12;
  for (const Level& level : levels_) bytes += static_cast<size_t>(level.a.nonZeros()) * 12;
  for (size_t k = 0; k < prolongations_.size(); ++k) {
    bytes += static_cast<size_t>(prolongations_[k].nonZeros() + restrictions_[k].nonZeros()) * 12;
  }
  return bytes;
}

}  // namespace rangebayes
