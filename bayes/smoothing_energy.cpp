#include "bayes/smoothing_energy.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <Eigen/Geometry>
#include <cmath>

#include "core/error.h"
#include "core/topology.h"

namespace rangebayes {
namespace {

// Fixed grain: with simple partitioning the reduction tree depends only on the range, not on the threads.
constexpr int kGrain = 1024;

template <typename Body>
double DeterministicSum(int n, const Body& body) {
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<int>(0, n, kGrain), 0.0,
      [&](const tbb::blocked_range<int>& r, double sum) {
        for (int i = r.begin(); i != r.end(); ++i) sum += body(i);
        return sum;
      },
      [](double a, double b) { return a + b; });
}

inline Eigen::Vector3d Position(const double* x, int v) { return Eigen::Vector3d(x[3 * v], x[3 * v + 1], x[3 * v + 2]); }

}  // namespace

SmoothingEnergy::SmoothingEnergy(const Mesh& measured, const std::vector<Eigen::Matrix3d>& information,
                                 double prior_weight, const Potential& potential,
                                 const std::vector<double>* face_epsilon_squared)
    : num_vertices_(measured.num_vertices()),
      faces_(measured.F),
      z_(measured.V.data(), 3 * static_cast<Eigen::Index>(measured.num_vertices())),
      prior_weight_(prior_weight),
      potential_(&potential) {
  const int nv = num_vertices_, nf = measured.num_faces();
  RB_CHECK(static_cast<int>(information.size()) == nv, "smoothing: ", information.size(),
           " information matrices for ", nv, " vertices");
  RB_CHECK(prior_weight >= 0 && std::isfinite(prior_weight), "smoothing: prior weight ", prior_weight,
           " must be finite and non-negative");
  RB_CHECK(measured.V.allFinite(), "smoothing: the input mesh has non-finite vertex coordinates");
  if (face_epsilon_squared != nullptr) {
    RB_CHECK(dynamic_cast<const SqrtPotential*>(&potential) != nullptr,
             "smoothing: a per-face epsilon_squared needs the square-root potential, not ", potential.Name());
    RB_CHECK(static_cast<int>(face_epsilon_squared->size()) == nf, "smoothing: ", face_epsilon_squared->size(),
             " per-face epsilon_squared values for ", nf, " faces");
    for (int f = 0; f < nf; ++f) {
      const double e2 = (*face_epsilon_squared)[static_cast<size_t>(f)];
      RB_CHECK(e2 > 0 && e2 <= 4, "smoothing: epsilon_squared of face ", f, " is ", e2, ", outside (0, 4]");
    }
    face_epsilon_squared_ = *face_epsilon_squared;
  }
  information_.resize(6 * static_cast<size_t>(nv));
  for (int i = 0; i < nv; ++i) {
    const Eigen::Matrix3d& W = information[static_cast<size_t>(i)];
    RB_CHECK(W.allFinite(), "smoothing: information matrix of vertex ", i, " is not finite");
    double* w = &information_[6 * static_cast<size_t>(i)];
    // Symmetrise: only the symmetric part enters rᵀ W r.
    w[0] = W(0, 0);
    w[1] = 0.5 * (W(0, 1) + W(1, 0));
    w[2] = 0.5 * (W(0, 2) + W(2, 0));
    w[3] = W(1, 1);
    w[4] = 0.5 * (W(1, 2) + W(2, 1));
    w[5] = W(2, 2);
  }

  // Active faces: distinct indices and a measured area that is not negligible.
  active_.assign(static_cast<size_t>(nf), 1);
  std::vector<double> area2(static_cast<size_t>(nf), 0.0);
  double sum_area2 = 0;
  for (int f = 0; f < nf; ++f) {
    const int a = faces_(f, 0), b = faces_(f, 1), c = faces_(f, 2);
    for (int v : {a, b, c}) {
      RB_CHECK(v >= 0 && v < nv, "smoothing: face ", f, " refers to vertex ", v, ", but the mesh has ", nv,
               " vertices");
    }
    if (a == b || b == c || a == c) {
      active_[static_cast<size_t>(f)] = 0;
      continue;
    }
    const Eigen::Vector3d pa = z_.segment<3>(3 * a), pb = z_.segment<3>(3 * b), pc = z_.segment<3>(3 * c);
    area2[static_cast<size_t>(f)] = (pb - pa).cross(pc - pa).norm();
    sum_area2 += area2[static_cast<size_t>(f)];
  }
  const double threshold = nf > 0 ? 1e-10 * sum_area2 / nf : 0.0;
  for (int f = 0; f < nf; ++f) {
    if (active_[static_cast<size_t>(f)] && !(area2[static_cast<size_t>(f)] > threshold)) {
      active_[static_cast<size_t>(f)] = 0;
    }
    if (!active_[static_cast<size_t>(f)]) ++num_inactive_faces_;
  }

  // Face adjacency over active pairs, both directions, ascending within each row.
  {
    const IndexPairs pairs = ComputeFacePairs(measured);
    neighbour_offsets_.assign(static_cast<size_t>(nf) + 1, 0);
    auto keep = [&](Eigen::Index p) {
      return active_[static_cast<size_t>(pairs(p, 0))] && active_[static_cast<size_t>(pairs(p, 1))];
    };
    for (Eigen::Index p = 0; p < pairs.rows(); ++p) {
      if (!keep(p)) continue;
      ++neighbour_offsets_[static_cast<size_t>(pairs(p, 0)) + 1];
      ++neighbour_offsets_[static_cast<size_t>(pairs(p, 1)) + 1];
    }
    for (int f = 0; f < nf; ++f) neighbour_offsets_[f + 1] += neighbour_offsets_[f];
    neighbours_.resize(static_cast<size_t>(neighbour_offsets_[nf]));
    std::vector<int> fill(neighbour_offsets_.begin(), neighbour_offsets_.end() - 1);
    // The pairs are sorted by (s, t) with s < t, so every row comes out ascending: a fixed gather order.
    for (Eigen::Index p = 0; p < pairs.rows(); ++p) {
      if (!keep(p)) continue;
      const int s = pairs(p, 0), t = pairs(p, 1);
      neighbours_[static_cast<size_t>(fill[s]++)] = t;
      neighbours_[static_cast<size_t>(fill[t]++)] = s;
    }
  }

  // Vertex → corners, ascending.
  corner_offsets_.assign(static_cast<size_t>(nv) + 1, 0);
  for (int f = 0; f < nf; ++f) {
    if (!active_[static_cast<size_t>(f)]) continue;
    for (int k = 0; k < 3; ++k) ++corner_offsets_[static_cast<size_t>(faces_(f, k)) + 1];
  }
  for (int v = 0; v < nv; ++v) corner_offsets_[v + 1] += corner_offsets_[v];
  corners_.resize(static_cast<size_t>(corner_offsets_[nv]));
  {
    std::vector<int> fill(corner_offsets_.begin(), corner_offsets_.end() - 1);
    for (int f = 0; f < nf; ++f) {
      if (!active_[static_cast<size_t>(f)]) continue;
      for (int k = 0; k < 3; ++k) corners_[static_cast<size_t>(fill[faces_(f, k)]++)] = 3 * f + k;
    }
  }
  normals_.assign(3 * static_cast<size_t>(nf), 0.0);
  inverse_length_.assign(static_cast<size_t>(nf), 0.0);
  h_.assign(3 * static_cast<size_t>(nf), 0.0);
}

Eigen::VectorXd SmoothingEnergy::Measurements() const { return z_; }

size_t SmoothingEnergy::MemoryBytes() const {
  return sizeof(int) * (neighbour_offsets_.size() + neighbours_.size() + corner_offsets_.size() +
                        corners_.size()) +
         sizeof(double) * (information_.size() + normals_.size() +
                           inverse_length_.size() + h_.size() + face_epsilon_squared_.size()) +
         active_.size();
}

EnergyParts SmoothingEnergy::Evaluate(const Eigen::VectorXd& x_vector, Eigen::VectorXd* gradient) const {
  RB_CHECK(x_vector.size() == z_.size(), "smoothing: state has ", x_vector.size(), " entries, expected ", z_.size());
  const int nf = num_faces(), nv = num_vertices_;
  const double* x = x_vector.data();

  // Pass 1: unit normal and 1/|c_t| per active face.
  tbb::parallel_for(tbb::blocked_range<int>(0, nf, kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int f = r.begin(); f != r.end(); ++f) {
      double* n = &normals_[3 * static_cast<size_t>(f)];
      if (!active_[static_cast<size_t>(f)]) {
        n[0] = n[1] = n[2] = 0;
        inverse_length_[static_cast<size_t>(f)] = 0;
        continue;
      }
      const Eigen::Vector3d pa = Position(x, faces_(f, 0));
      const Eigen::Vector3d c = (Position(x, faces_(f, 1)) - pa).cross(Position(x, faces_(f, 2)) - pa);
      const double length = c.norm();
      if (length > 0 && std::isfinite(length)) {
        const double inv = 1.0 / length;
        n[0] = c.x() * inv;
        n[1] = c.y() * inv;
        n[2] = c.z() * inv;
        inverse_length_[static_cast<size_t>(f)] = inv;
      } else {
        n[0] = n[1] = n[2] = 0;
        inverse_length_[static_cast<size_t>(f)] = 0;
      }
    }
  });

  // Pass 2: per face, half of each pair's potential (both faces of a pair count it) and h_t.
  const bool want_gradient = gradient != nullptr;
  const double beta = prior_weight_;
  const Potential& potential = *potential_;
  const bool per_face_epsilon = !face_epsilon_squared_.empty();
  const double* face_e2 = face_epsilon_squared_.data();
  const double prior_sum = DeterministicSum(nf, [&](int t) {
    const double* nt = &normals_[3 * static_cast<size_t>(t)];
    double energy = 0;
    double g[3] = {0, 0, 0};
    for (int q = neighbour_offsets_[t]; q < neighbour_offsets_[t + 1]; ++q) {
      const int s = neighbours_[static_cast<size_t>(q)];
      const double* ns = &normals_[3 * static_cast<size_t>(s)];
      const double dx = nt[0] - ns[0], dy = nt[1] - ns[1], dz = nt[2] - ns[2];
      const double d2 = dx * dx + dy * dy + dz * dz;
      double value = 0, weight = 0;
      if (per_face_epsilon) {
        value = std::sqrt(d2 + 0.5 * (face_e2[t] + face_e2[s]));
        weight = 1.0 / value;
      } else {
        potential.EvaluateWeight(std::sqrt(d2), &value, &weight);
      }
      energy += value;
      g[0] += weight * dx;
      g[1] += weight * dy;
      g[2] += weight * dz;
    }
    if (want_gradient) {
      double* h = &h_[3 * static_cast<size_t>(t)];
      const double inv = inverse_length_[static_cast<size_t>(t)] * beta;
      const double ng = nt[0] * g[0] + nt[1] * g[1] + nt[2] * g[2];
      h[0] = (g[0] - nt[0] * ng) * inv;
      h[1] = (g[1] - nt[1] * ng) * inv;
      h[2] = (g[2] - nt[2] * ng) * inv;
    }
    return 0.5 * energy;
  });

  // Pass 3: per vertex, the data term and the gather of face contributions in corner order.
  if (want_gradient) gradient->resize(z_.size());
  double* grad = want_gradient ? gradient->data() : nullptr;
  const double data_sum = DeterministicSum(nv, [&](int i) {
    const double* w = &information_[6 * static_cast<size_t>(i)];
    const double rx = x[3 * i] - z_[3 * i], ry = x[3 * i + 1] - z_[3 * i + 1], rz = x[3 * i + 2] - z_[3 * i + 2];
    const double wx = w[0] * rx + w[1] * ry + w[2] * rz;
    const double wy = w[1] * rx + w[3] * ry + w[4] * rz;
    const double wz = w[2] * rx + w[4] * ry + w[5] * rz;
    if (grad != nullptr) {
      Eigen::Vector3d sum(2 * wx, 2 * wy, 2 * wz);
      for (int q = corner_offsets_[i]; q < corner_offsets_[i + 1]; ++q) {
        const int corner = corners_[static_cast<size_t>(q)];
        const int f = corner / 3, k = corner % 3;
        const Eigen::Vector3d h(&h_[3 * static_cast<size_t>(f)]);
        const Eigen::Vector3d edge = Position(x, faces_(f, (k + 2) % 3)) - Position(x, faces_(f, (k + 1) % 3));
        sum += h.cross(edge);
      }
      grad[3 * i] = sum.x();
      grad[3 * i + 1] = sum.y();
      grad[3 * i + 2] = sum.z();
    }
    return rx * wx + ry * wy + rz * wz;
  });
  return EnergyParts{data_sum, beta * prior_sum};
}

double SmoothingEnergy::DataCurvature(const Eigen::VectorXd& p) const {
  return DeterministicSum(num_vertices_, [&](int i) {
    const double* w = &information_[6 * static_cast<size_t>(i)];
    const double px = p[3 * i], py = p[3 * i + 1], pz = p[3 * i + 2];
    return 2 * (px * (w[0] * px + w[1] * py + w[2] * pz) + py * (w[1] * px + w[3] * py + w[4] * pz) +
                pz * (w[2] * px + w[4] * py + w[5] * pz));
  });
}

Normals SmoothingEnergy::FaceNormals(const Eigen::VectorXd& x) const {
  Normals normals = Normals::Zero(num_faces(), 3);
  for (int f = 0; f < num_faces(); ++f) {
    if (!active_[static_cast<size_t>(f)]) continue;
    const Eigen::Vector3d pa = Position(x.data(), faces_(f, 0));
    const Eigen::Vector3d c = (Position(x.data(), faces_(f, 1)) - pa).cross(Position(x.data(), faces_(f, 2)) - pa);
    const double length = c.norm();
    if (length > 0 && std::isfinite(length)) normals.row(f) = c.transpose() / length;
  }
  return normals;
}

int SmoothingEnergy::CountFoldedFaces(const Eigen::VectorXd& x) const {
  const Normals normals = FaceNormals(x);
  int folded = 0;
  for (int t = 0; t < num_faces(); ++t) {
    if (neighbour_offsets_[t] == neighbour_offsets_[t + 1]) continue;
    Eigen::RowVector3d sum = Eigen::RowVector3d::Zero();
    for (int q = neighbour_offsets_[t]; q < neighbour_offsets_[t + 1]; ++q) sum += normals.row(neighbours_[static_cast<size_t>(q)]);
    if (normals.row(t).dot(sum) < 0) ++folded;
  }
  return folded;
}

}  // namespace rangebayes
