#include "bayes/warm_start.h"

#include <Eigen/Dense>
#include <cmath>

#include "core/error.h"

namespace rangebayes {
namespace {

// Pixels of an organized mesh sit on an integer grid (a multiple of the triangulation step).
std::int64_t PixelKey(float u, float v) {
  return (static_cast<std::int64_t>(std::lround(v)) << 32) ^ static_cast<std::int64_t>(std::lround(u) & 0xffffffff);
}

bool Organized(const NoisyMesh& m) {
  return m.mesh.num_vertices() > 0 && m.pixel.rows() == m.mesh.num_vertices() && m.has_covariance();
}

}  // namespace

void WarmStartOptions::Check() const {
  RB_CHECK(max_sigmas > 0 && max_sigmas <= 1e3, "warm start: max_sigmas ", max_sigmas, " is outside (0, 1e3]");
  RB_CHECK(min_fraction >= 0 && min_fraction <= 1, "warm start: min_fraction ", min_fraction, " is outside [0, 1]");
}

WarmStart::WarmStart(const WarmStartOptions& options) : options_(options) { options_.Check(); }

void WarmStart::Reset() {
  pixel_to_vertex_.clear();
  measured_.resize(0, 3);
  displacement_.resize(0, 3);
  covariance_.clear();
}

void WarmStart::Remember(const NoisyMesh& raw, const Mesh& smoothed) {
  RB_CHECK(smoothed.num_vertices() == raw.mesh.num_vertices(), "warm start: ", smoothed.num_vertices(),
           " smoothed vertices for ", raw.mesh.num_vertices(), " measured ones");
  Reset();
  if (!Organized(raw) || !smoothed.V.allFinite()) return;
  const int n = raw.mesh.num_vertices();
  pixel_to_vertex_.reserve(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) pixel_to_vertex_.emplace(PixelKey(raw.pixel(i, 0), raw.pixel(i, 1)), i);
  measured_ = raw.mesh.V;
  displacement_ = smoothed.V - raw.mesh.V;
  covariance_ = raw.covariance;
}

bool WarmStart::Initial(const NoisyMesh& raw, Vertices* initial, WarmStartStats* stats) const {
  const int n = raw.mesh.num_vertices();
  if (stats != nullptr) *stats = {0, n};
  if (pixel_to_vertex_.empty() || !Organized(raw)) return false;
  Vertices x = raw.mesh.V;
  int agreed = 0;
  const double limit = options_.max_sigmas * options_.max_sigmas;
  for (int i = 0; i < n; ++i) {
    const auto it = pixel_to_vertex_.find(PixelKey(raw.pixel(i, 0), raw.pixel(i, 1)));
    if (it == pixel_to_vertex_.end()) continue;
    const int j = it->second;
    const Eigen::Vector3d d = (raw.mesh.V.row(i) - measured_.row(j)).transpose();
    const Eigen::Matrix3d sum = raw.covariance[static_cast<size_t>(i)] + covariance_[static_cast<size_t>(j)];
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(sum);
    if (ldlt.info() != Eigen::Success || !(ldlt.vectorD().minCoeff() > 0)) continue;
    const double m2 = d.dot(ldlt.solve(d));
    if (!(m2 <= limit)) continue;
    x.row(i) += displacement_.row(j);
    ++agreed;
  }
  if (stats != nullptr) stats->agreed = agreed;
  if (agreed == 0 || agreed < options_.min_fraction * n) return false;
  *initial = std::move(x);
  return true;
}

}  // namespace rangebayes
