#include "bayes/smoothing_energy.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/error.h"

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
  // Isotropic W_i = w_i I (every generic mesh) is stored as one number per vertex instead of six.
  isotropic_ = true;
  for (int i = 0; i < nv && isotropic_; ++i) {
    const Eigen::Matrix3d& W = information[static_cast<size_t>(i)];
    isotropic_ = W(0, 1) == 0 && W(1, 0) == 0 && W(0, 2) == 0 && W(2, 0) == 0 && W(1, 2) == 0 && W(2, 1) == 0 &&
                 W(0, 0) == W(1, 1) && W(1, 1) == W(2, 2);
  }
  information_.resize((isotropic_ ? 1 : 6) * static_cast<size_t>(nv));
  uniform_isotropic_ = isotropic_;
  for (int i = 1; i < nv && uniform_isotropic_; ++i) {
    uniform_isotropic_ = information[static_cast<size_t>(i)](0, 0) == information[0](0, 0);
  }
  for (int i = 0; i < nv; ++i) {
    const Eigen::Matrix3d& W = information[static_cast<size_t>(i)];
    RB_CHECK(W.allFinite(), "smoothing: information matrix of vertex ", i, " is not finite");
    if (isotropic_) {
      information_[static_cast<size_t>(i)] = W(0, 0);
      continue;
    }
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

  // Vertex → corners of active faces, ascending.
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

  // Face adjacency over active faces (the pairs of ComputeFacePairs, both directions, each row ascending):
  // the active faces around an edge's first vertex that also hold its second. Linear time through the
  // corner lists above, where the sort in ComputeEdgeTopology took a third of the setup at 1M faces.
  {
    auto collect = [&](int t, std::vector<int>* out) {
      out->clear();
      if (!active_[static_cast<size_t>(t)]) return;
      for (int k = 0; k < 3; ++k) {
        const int u = faces_(t, k), v = faces_(t, k == 2 ? 0 : k + 1);
        for (int q = corner_offsets_[u]; q < corner_offsets_[u + 1]; ++q) {
          const int s = corners_[static_cast<size_t>(q)] / 3;
          if (s != t && (faces_(s, 0) == v || faces_(s, 1) == v || faces_(s, 2) == v)) out->push_back(s);
        }
      }
      std::sort(out->begin(), out->end());
      out->erase(std::unique(out->begin(), out->end()), out->end());  // two faces sharing two edges: one pair
    };
    // One search per face into three slots per face (every face of a manifold mesh has at most three
    // neighbours), compacted in place; a second search only for faces with more (non-manifold edges).
    neighbour_offsets_.assign(static_cast<size_t>(nf) + 1, 0);
    neighbours_.resize(3 * static_cast<size_t>(nf));
    tbb::parallel_for(tbb::blocked_range<int>(0, nf, kGrain), [&](const tbb::blocked_range<int>& r) {
      std::vector<int> buffer;
      for (int t = r.begin(); t != r.end(); ++t) {
        collect(t, &buffer);
        neighbour_offsets_[static_cast<size_t>(t) + 1] = static_cast<int>(buffer.size());
        std::copy_n(buffer.begin(), std::min<size_t>(buffer.size(), 3), neighbours_.begin() + 3 * static_cast<size_t>(t));
      }
    });
    bool all_fit = true;
    for (int f = 0; f < nf; ++f) {
      all_fit = all_fit && neighbour_offsets_[f + 1] <= 3;
      neighbour_offsets_[f + 1] += neighbour_offsets_[f];
    }
    if (all_fit) {
      // offsets[f] ≤ 3f: moving left in increasing f never overwrites a slot not yet moved.
      for (int f = 0; f < nf; ++f) {
        const int count = neighbour_offsets_[f + 1] - neighbour_offsets_[f];
        for (int k = 0; k < count; ++k) {
          neighbours_[static_cast<size_t>(neighbour_offsets_[f] + k)] = neighbours_[3 * static_cast<size_t>(f) + k];
        }
      }
      neighbours_.resize(static_cast<size_t>(neighbour_offsets_[nf]));
      neighbours_.shrink_to_fit();
    } else {
      neighbours_.assign(static_cast<size_t>(neighbour_offsets_[nf]), 0);
      tbb::parallel_for(tbb::blocked_range<int>(0, nf, kGrain), [&](const tbb::blocked_range<int>& r) {
        std::vector<int> buffer;
        for (int t = r.begin(); t != r.end(); ++t) {
          collect(t, &buffer);
          std::copy(buffer.begin(), buffer.end(), neighbours_.begin() + neighbour_offsets_[static_cast<size_t>(t)]);
        }
      });
    }
  }
  normals_.assign(3 * static_cast<size_t>(nf), 0.0);
  inverse_length_.assign(static_cast<size_t>(nf), 0.0);
  h_.assign(9 * static_cast<size_t>(nf), 0.0);
}

Eigen::VectorXd SmoothingEnergy::Measurements() const { return z_; }

size_t SmoothingEnergy::MemoryBytes() const {
  return sizeof(int) * (neighbour_offsets_.size() + neighbours_.size() + corner_offsets_.size() +
                        corners_.size()) +
         sizeof(double) * (information_.size() + normals_.size() +
                           inverse_length_.size() + h_.size() + face_epsilon_squared_.size()) +
         active_.size();
}

// Unit normal and 1/|c_t| per active face into normals_ / inverse_length_.
void SmoothingEnergy::ComputeNormals(const double* x) const {
  const int nf = num_faces();
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

}

EnergyParts SmoothingEnergy::Evaluate(const Eigen::VectorXd& x_vector, Eigen::VectorXd* gradient) const {
  RB_CHECK(x_vector.size() == z_.size(), "smoothing: state has ", x_vector.size(), " entries, expected ", z_.size());
  const int nf = num_faces(), nv = num_vertices_;
  const double* x = x_vector.data();

  ComputeNormals(x);

  // Pass 2: per face t, half of each pair's potential (both faces of a pair count it), then, for the gradient,
  // h_t = β P_t g_t / |c_t| with g_t = Σ_s w_ts (n_t − n_s), and the face's three corner contributions
  // h_t × e_k (e_k the edge opposite corner k) into h_[9t + 3k ..]. The pair kernel is a template argument so
  // the square root (the default) is inlined; other potentials go through the virtual call.
  const bool want_gradient = gradient != nullptr;
  const double beta = prior_weight_;
  // neighbour_sum(t, n_t, sums) adds face t's Σ_s φ and Σ_s w_ts (n_t − n_s) into sums[0] and sums[1..3], one
  // neighbour after another in row order.
  auto face_pass = [&](auto neighbour_sum) {
    return DeterministicSum(nf, [&](int t) {
      const double* nt = &normals_[3 * static_cast<size_t>(t)];
      double sums[4] = {0, 0, 0, 0};
      neighbour_sum(t, nt, sums);
      const double energy = sums[0], gx = sums[1], gy = sums[2], gz = sums[3];
      if (want_gradient) {
        double* out = &h_[9 * static_cast<size_t>(t)];
        const double inv = inverse_length_[static_cast<size_t>(t)] * beta;
        if (inv == 0) {
          for (int k = 0; k < 9; ++k) out[k] = 0;
        } else {
          const double ng = nt[0] * gx + nt[1] * gy + nt[2] * gz;
          const double hx = (gx - nt[0] * ng) * inv, hy = (gy - nt[1] * ng) * inv, hz = (gz - nt[2] * ng) * inv;
          const double* p[3] = {x + 3 * faces_(t, 0), x + 3 * faces_(t, 1), x + 3 * faces_(t, 2)};
          for (int k = 0; k < 3; ++k) {
            const double* p1 = p[k == 2 ? 0 : k + 1];
            const double* p2 = p[k == 0 ? 2 : k - 1];
            const double ex = p2[0] - p1[0], ey = p2[1] - p1[1], ez = p2[2] - p1[2];
            out[3 * k] = hy * ez - hz * ey;
            out[3 * k + 1] = hz * ex - hx * ez;
            out[3 * k + 2] = hx * ey - hy * ex;
          }
        }
      }
      return 0.5 * energy;
    });
  };
  // Any potential: pair(t, s, d², &w) returns φ(d) and sets w = φ'(d)/d.
  auto pairwise = [&](auto pair) {
    return [&, pair](int t, const double* nt, double* sums) {
      const int end = neighbour_offsets_[t + 1];
      for (int q = neighbour_offsets_[t]; q < end; ++q) {
        const int s = neighbours_[static_cast<size_t>(q)];
        const double* ns = &normals_[3 * static_cast<size_t>(s)];
        const double dx = nt[0] - ns[0], dy = nt[1] - ns[1], dz = nt[2] - ns[2];
        double weight;
        sums[0] += pair(t, s, dx * dx + dy * dy + dz * dz, &weight);
        sums[1] += weight * dx;
        sums[2] += weight * dy;
        sums[3] += weight * dz;
      }
    };
  };
  // The square root, φ = sqrt(d² + ε²) and w = 1/φ, two neighbours at a time in SSE2 lanes (sqrtpd, divpd):
  // the square roots and divisions were ~1/6 of an evaluation. Correctly rounded either way and summed in
  // the same order, so the bytes are those of the scalar loop. argument(t, s, d²) = d² + ε².
  auto square_root = [&](auto argument) {
    return [&, argument](int t, const double* nt, double* sums) {
      const int begin = neighbour_offsets_[t], end = neighbour_offsets_[t + 1];
      for (int q = begin; q < end; q += 2) {
        const bool two = q + 1 < end;
        const int s0 = neighbours_[static_cast<size_t>(q)];
        const int s1 = two ? neighbours_[static_cast<size_t>(q) + 1] : s0;
        const double* n0 = &normals_[3 * static_cast<size_t>(s0)];
        const double* n1 = &normals_[3 * static_cast<size_t>(s1)];
        const double dx0 = nt[0] - n0[0], dy0 = nt[1] - n0[1], dz0 = nt[2] - n0[2];
        const double dx1 = nt[0] - n1[0], dy1 = nt[1] - n1[1], dz1 = nt[2] - n1[2];
        const double a0 = argument(t, s0, dx0 * dx0 + dy0 * dy0 + dz0 * dz0);
        const double a1 = argument(t, s1, dx1 * dx1 + dy1 * dy1 + dz1 * dz1);
        double value[2], weight[2];
#if defined(__SSE2__)
        const __m128d v = _mm_sqrt_pd(_mm_set_pd(a1, a0));
        _mm_storeu_pd(value, v);
        _mm_storeu_pd(weight, _mm_div_pd(_mm_set1_pd(1.0), v));
#else
        value[0] = std::sqrt(a0);
        value[1] = std::sqrt(a1);
        weight[0] = 1.0 / value[0];
        weight[1] = 1.0 / value[1];
#endif
        sums[0] += value[0];
        sums[1] += weight[0] * dx0;
        sums[2] += weight[0] * dy0;
        sums[3] += weight[0] * dz0;
        if (two) {
          sums[0] += value[1];
          sums[1] += weight[1] * dx1;
          sums[2] += weight[1] * dy1;
          sums[3] += weight[1] * dz1;
        }
      }
    };
  };
  double prior_sum;
  const auto* sqrt_potential = dynamic_cast<const SqrtPotential*>(potential_);
  if (!face_epsilon_squared_.empty()) {
    const double* face_e2 = face_epsilon_squared_.data();
    prior_sum = face_pass(square_root([face_e2](int t, int s, double d2) { return d2 + 0.5 * (face_e2[t] + face_e2[s]); }));
  } else if (sqrt_potential != nullptr) {
    const double e2 = sqrt_potential->epsilon_squared();
    prior_sum = face_pass(square_root([e2](int, int, double d2) { return d2 + e2; }));
  } else {
    const Potential& potential = *potential_;
    prior_sum = face_pass(pairwise([&potential](int, int, double d2, double* weight) {
      double value = 0;
      potential.EvaluateWeight(std::sqrt(d2), &value, weight);
      return value;
    }));
  }

  // Pass 3: per vertex, the data term and the gather of corner contributions in corner order.
  if (want_gradient) gradient->resize(z_.size());
  double* grad = want_gradient ? gradient->data() : nullptr;
  const double* contributions = h_.data();
  const double data_sum = DeterministicSum(nv, [&](int i) {
    double w[6];
    Information(i, w);
    const double rx = x[3 * i] - z_[3 * i], ry = x[3 * i + 1] - z_[3 * i + 1], rz = x[3 * i + 2] - z_[3 * i + 2];
    const double wx = w[0] * rx + w[1] * ry + w[2] * rz;
    const double wy = w[1] * rx + w[3] * ry + w[4] * rz;
    const double wz = w[2] * rx + w[4] * ry + w[5] * rz;
    if (grad != nullptr) {
      double sx = 2 * wx, sy = 2 * wy, sz = 2 * wz;
      const int end = corner_offsets_[i + 1];
      for (int q = corner_offsets_[i]; q < end; ++q) {
        const double* c = contributions + 3 * static_cast<size_t>(corners_[static_cast<size_t>(q)]);
        sx += c[0];
        sy += c[1];
        sz += c[2];
      }
      grad[3 * i] = sx;
      grad[3 * i + 1] = sy;
      grad[3 * i + 2] = sz;
    }
    return rx * wx + ry * wy + rz * wz;
  });
  return EnergyParts{data_sum, beta * prior_sum};
}

void SmoothingEnergy::BlockJacobiInverse(const Eigen::VectorXd& x_vector, std::vector<double>* inverse_blocks) const {
  RB_CHECK(x_vector.size() == z_.size(), "smoothing: state has ", x_vector.size(), " entries, expected ", z_.size());
  const int nf = num_faces(), nv = num_vertices_;
  const double* x = x_vector.data();
  ComputeNormals(x);
  // Per face t the prior's Hessian with respect to n_t, A_t = β Σ_s [w I + (max(0, φ'') − w) û ûᵀ] (û the unit
  // normal difference), then per corner k the curvature of moving that corner along n_t:
  // (e_k × n_t)ᵀ A_t (e_k × n_t) / |c_t|², into h_[3t + k].
  const bool per_face_epsilon = !face_epsilon_squared_.empty();
  const double* face_e2 = face_epsilon_squared_.data();
  const Potential& potential = *potential_;
  const auto* sqrt_potential = dynamic_cast<const SqrtPotential*>(potential_);
  const double global_e2 = sqrt_potential != nullptr ? sqrt_potential->epsilon_squared() : 0.0;
  tbb::parallel_for(tbb::blocked_range<int>(0, nf, kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int t = r.begin(); t != r.end(); ++t) {
      double* out = &h_[3 * static_cast<size_t>(t)];
      out[0] = out[1] = out[2] = 0;
      if (!active_[static_cast<size_t>(t)]) continue;
      const double* nt = &normals_[3 * static_cast<size_t>(t)];
      double A[6] = {0, 0, 0, 0, 0, 0};
      for (int q = neighbour_offsets_[t]; q < neighbour_offsets_[t + 1]; ++q) {
        const int s = neighbours_[static_cast<size_t>(q)];
        const double* ns = &normals_[3 * static_cast<size_t>(s)];
        const double dx = nt[0] - ns[0], dy = nt[1] - ns[1], dz = nt[2] - ns[2];
        const double d2 = dx * dx + dy * dy + dz * dz;
        const double d = std::sqrt(d2);
        double weight = 0, second = 0;
        if (per_face_epsilon || sqrt_potential != nullptr) {
          const double e2 = per_face_epsilon ? 0.5 * (face_e2[t] + face_e2[s]) : global_e2;
          const double phi = std::sqrt(d2 + e2);
          weight = 1.0 / phi;
          second = e2 / (phi * phi * phi);
        } else {
          double value = 0, dp = 0, dm = 0;
          potential.EvaluateWeight(d, &value, &weight);
          const double step = 1e-4;
          potential.Evaluate(std::min(d + step, 2.0), &value, &dp);
          potential.Evaluate(std::max(d - step, 0.0), &value, &dm);
          second = (dp - dm) / (std::min(d + step, 2.0) - std::max(d - step, 0.0));
        }
        weight = std::max(0.0, weight);
        second = std::max(0.0, second);
        A[0] += weight;
        A[3] += weight;
        A[5] += weight;
        if (d > 1e-12) {
          const double k = (second - weight) / d2;
          A[0] += k * dx * dx;
          A[1] += k * dx * dy;
          A[2] += k * dx * dz;
          A[3] += k * dy * dy;
          A[4] += k * dy * dz;
          A[5] += k * dz * dz;
        }
      }
      const double scale = prior_weight_ * inverse_length_[static_cast<size_t>(t)] * inverse_length_[static_cast<size_t>(t)];
      for (int k = 0; k < 3; ++k) {
        const double* p1 = x + 3 * faces_(t, (k + 1) % 3);
        const double* p2 = x + 3 * faces_(t, (k + 2) % 3);
        const double ex = p2[0] - p1[0], ey = p2[1] - p1[1], ez = p2[2] - p1[2];
        const double mx = ey * nt[2] - ez * nt[1], my = ez * nt[0] - ex * nt[2], mz = ex * nt[1] - ey * nt[0];
        out[k] = scale * (A[0] * mx * mx + A[3] * my * my + A[5] * mz * mz +
                          2 * (A[1] * mx * my + A[2] * mx * mz + A[4] * my * mz));
      }
    }
  });
  inverse_blocks->resize(6 * static_cast<size_t>(nv));
  double* out = inverse_blocks->data();
  tbb::parallel_for(tbb::blocked_range<int>(0, nv, kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i != r.end(); ++i) {
      double w[6];
      Information(i, w);
      double b[6] = {2 * w[0], 2 * w[1], 2 * w[2], 2 * w[3], 2 * w[4], 2 * w[5]};
      for (int q = corner_offsets_[i]; q < corner_offsets_[i + 1]; ++q) {
        const int corner = corners_[static_cast<size_t>(q)];
        const int f = corner / 3;
        const double* n = &normals_[3 * static_cast<size_t>(f)];
        const double c = h_[static_cast<size_t>(corner)];
        b[0] += c * n[0] * n[0];
        b[1] += c * n[0] * n[1];
        b[2] += c * n[0] * n[2];
        b[3] += c * n[1] * n[1];
        b[4] += c * n[1] * n[2];
        b[5] += c * n[2] * n[2];
      }
      // Inverse of the symmetric 3×3 by cofactors; B is positive definite (W_i is, by construction).
      const double c00 = b[3] * b[5] - b[4] * b[4], c01 = b[2] * b[4] - b[1] * b[5], c02 = b[1] * b[4] - b[2] * b[3];
      const double c11 = b[0] * b[5] - b[2] * b[2], c12 = b[1] * b[2] - b[0] * b[4], c22 = b[0] * b[3] - b[1] * b[1];
      const double det = b[0] * c00 + b[1] * c01 + b[2] * c02;
      double* o = out + 6 * static_cast<size_t>(i);
      if (det > 0 && std::isfinite(det)) {
        const double inv = 1.0 / det;
        o[0] = c00 * inv;
        o[1] = c01 * inv;
        o[2] = c02 * inv;
        o[3] = c11 * inv;
        o[4] = c12 * inv;
        o[5] = c22 * inv;
      } else {
        o[0] = o[3] = o[5] = 0;  // should not happen; a zero block keeps the direction a descent one
        o[1] = o[2] = o[4] = 0;
      }
    }
  });
}

void SmoothingEnergy::ApplyBlocks(const std::vector<double>& blocks, const Eigen::VectorXd& v,
                                  Eigen::VectorXd* out) const {
  out->resize(v.size());
  const double* in = v.data();
  double* o = out->data();
  tbb::parallel_for(tbb::blocked_range<int>(0, num_vertices_, kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i != r.end(); ++i) {
      const double* b = &blocks[6 * static_cast<size_t>(i)];
      const double a0 = in[3 * i], a1 = in[3 * i + 1], a2 = in[3 * i + 2];
      o[3 * i] = b[0] * a0 + b[1] * a1 + b[2] * a2;
      o[3 * i + 1] = b[1] * a0 + b[3] * a1 + b[4] * a2;
      o[3 * i + 2] = b[2] * a0 + b[4] * a1 + b[5] * a2;
    }
  });
}

void SmoothingEnergy::ApplyDataInverse(const Eigen::VectorXd& v, Eigen::VectorXd* out) const {
  out->resize(v.size());
  const double* in = v.data();
  double* o = out->data();
  tbb::parallel_for(tbb::blocked_range<int>(0, num_vertices_, kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i != r.end(); ++i) {
      double b[6];
      Information(i, b);
      const double a0 = in[3 * i], a1 = in[3 * i + 1], a2 = in[3 * i + 2];
      // (2W)⁻¹ by cofactors; W_i is positive definite (Smooth raises its eigenvalues to 1e-6 of the largest).
      const double c00 = b[3] * b[5] - b[4] * b[4], c01 = b[2] * b[4] - b[1] * b[5], c02 = b[1] * b[4] - b[2] * b[3];
      const double c11 = b[0] * b[5] - b[2] * b[2], c12 = b[1] * b[2] - b[0] * b[4], c22 = b[0] * b[3] - b[1] * b[1];
      const double det = b[0] * c00 + b[1] * c01 + b[2] * c02;
      if (!(det > 0) || !std::isfinite(det)) {
        o[3 * i] = a0;  // not positive definite (a caller-built W): leave this vertex unpreconditioned
        o[3 * i + 1] = a1;
        o[3 * i + 2] = a2;
        continue;
      }
      const double s = 0.5 / det;
      o[3 * i] = s * (c00 * a0 + c01 * a1 + c02 * a2);
      o[3 * i + 1] = s * (c01 * a0 + c11 * a1 + c12 * a2);
      o[3 * i + 2] = s * (c02 * a0 + c12 * a1 + c22 * a2);
    }
  });
}

double SmoothingEnergy::DataCurvature(const Eigen::VectorXd& p) const {
  return DeterministicSum(num_vertices_, [&](int i) {
    double w[6];
      Information(i, w);
    const double px = p[3 * i], py = p[3 * i + 1], pz = p[3 * i + 2];
    return 2 * (px * (w[0] * px + w[1] * py + w[2] * pz) + py * (w[1] * px + w[3] * py + w[4] * pz) +
                pz * (w[2] * px + w[4] * py + w[5] * pz));
  });
}

Normals SmoothingEnergy::FaceNormals(const Eigen::VectorXd& x) const {
  Normals normals = Normals::Zero(num_faces(), 3);
  tbb::parallel_for(tbb::blocked_range<int>(0, num_faces(), kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int f = r.begin(); f != r.end(); ++f) {
      if (!active_[static_cast<size_t>(f)]) continue;
      const Eigen::Vector3d pa = Position(x.data(), faces_(f, 0));
      const Eigen::Vector3d c = (Position(x.data(), faces_(f, 1)) - pa).cross(Position(x.data(), faces_(f, 2)) - pa);
      const double length = c.norm();
      if (length > 0 && std::isfinite(length)) normals.row(f) = c.transpose() / length;
    }
  });
  return normals;
}

int SmoothingEnergy::CountFoldedFaces(const Eigen::VectorXd& x) const {
  const Normals normals = FaceNormals(x);
  return static_cast<int>(DeterministicSum(num_faces(), [&](int t) {
    if (neighbour_offsets_[t] == neighbour_offsets_[t + 1]) return 0.0;
    Eigen::RowVector3d sum = Eigen::RowVector3d::Zero();
    for (int q = neighbour_offsets_[t]; q < neighbour_offsets_[t + 1]; ++q) sum += normals.row(neighbours_[static_cast<size_t>(q)]);
    return normals.row(t).dot(sum) < 0 ? 1.0 : 0.0;
  }));
}

}  // namespace rangebayes
