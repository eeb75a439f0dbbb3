#include "bayes/decimation/decimate_refit.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>
#include <utility>
#include <unordered_set>

#include <tbb/parallel_for.h>

#include "core/error.h"

namespace rangebayes {
namespace {

// error(x) = xᵀ A x − 2 bᵀ x + c
struct Quadric {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  double c = 0.0;

  void AddPlane(const Eigen::Vector3d& n, double offset, double weight) {
    A += weight * n * n.transpose();
    b += weight * offset * n;
    c += weight * offset * offset;
  }
  double Error(const Eigen::Vector3d& x) const { return x.dot(A * x) - 2.0 * b.dot(x) + c; }
};

Eigen::Vector3d Row(const Vertices& V, int i) { return V.row(i).transpose(); }

// Squared distance from p to triangle abc and the barycentric coordinates of the closest point (Ericson,
// Real-Time Collision Detection, 5.1.5).
double ClosestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                              const Eigen::Vector3d& c, Eigen::Vector3d* bary) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  auto result = [&](double u, double v, double w) {
    *bary = Eigen::Vector3d(u, v, w);
    return (u * a + v * b + w * c - p).squaredNorm();
  };
  if (d1 <= 0.0 && d2 <= 0.0) return result(1, 0, 0);
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return result(0, 1, 0);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    const double v = d1 / (d1 - d3);
    return result(1 - v, v, 0);
  }
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return result(0, 0, 1);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    const double w = d2 / (d2 - d6);
    return result(1 - w, 0, w);
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    return result(0, 1 - w, w);
  }
  const double denom = va + vb + vc;
  if (!(std::abs(denom) > 0.0)) return result(1, 0, 0);
  const double v = vb / denom, w = vc / denom;
  return result(1 - v - w, v, w);
}

}  // namespace

void VertexRefitOptions::Check() const {
  RB_CHECK(regularisation > 0.0 && std::isfinite(regularisation), "decimate: refit regularisation must be > 0, got ",
           regularisation);
  RB_CHECK(boundary_weight >= 0.0, "decimate: refit boundary_weight must be ≥ 0, got ", boundary_weight);
  RB_CHECK(min_cos_to_patch_normal >= 0.0 && min_cos_to_patch_normal < 1.0,
           "decimate: refit min_cos_to_patch_normal must be in [0, 1)");
  RB_CHECK(fit_rounds >= 0, "decimate: refit fit_rounds must be ≥ 0, got ", fit_rounds);
  RB_CHECK(max_halvings >= 0, "decimate: refit max_halvings must be ≥ 0, got ", max_halvings);
}

Vertices RefitVertices(const RefitInput& in, const VertexRefitOptions& options, VertexRefitSummary* summary) {
  options.Check();
  RB_CHECK(in.dense_V && in.dense_F && in.dense_face_patch && in.representative && in.coarse_F &&
               in.coarse_face_patch,
           "decimate: refit input incomplete");
  const Vertices& V = *in.dense_V;
  const Faces& F = *in.dense_F;
  const Faces& C = *in.coarse_F;
  const int nv = static_cast<int>(V.rows());
  const int nf = static_cast<int>(F.rows());
  RB_CHECK(static_cast<int>(in.representative->size()) == nv, "decimate: refit representative size mismatch");
  RB_CHECK(static_cast<int>(in.dense_face_patch->size()) == nf, "decimate: refit patch map size mismatch");
  RB_CHECK(static_cast<int>(in.coarse_face_patch->size()) == C.rows(), "decimate: refit coarse patch size mismatch");
  const std::vector<int>& rep = *in.representative;
  const bool has_boundary = in.boundary_vertex != nullptr && static_cast<int>(in.boundary_vertex->size()) == nv;
  const bool has_fixed = in.fixed != nullptr && static_cast<int>(in.fixed->size()) == nv;
  VertexRefitSummary local;
  VertexRefitSummary& s = summary != nullptr ? *summary : local;
  s = VertexRefitSummary{};

  // Quadrics per kept vertex, from the dense faces of its cluster (a face counts for each of its corners'
  // clusters, as in Garland–Heckbert), and patch normals for the cone guard.
  std::vector<Quadric> Q(nv), Qb(nv);  // face planes of the cluster; boundary planes
  std::vector<char> kept(nv, 0);
  for (int v = 0; v < nv; ++v) {
    if (rep[v] >= 0) kept[rep[v]] = 1;
  }
  std::vector<Eigen::Vector3d> patch_normal(std::max(in.num_patches, 0), Eigen::Vector3d::Zero());
  double diag2 = (V.colwise().maxCoeff() - V.colwise().minCoeff()).squaredNorm();
  const double area_eps = 1e-14 * diag2;
  for (int f = 0; f < nf; ++f) {
    const Eigen::Vector3d a = Row(V, F(f, 0)), b = Row(V, F(f, 1)), c = Row(V, F(f, 2));
    const Eigen::Vector3d cr = (b - a).cross(c - a);
    const double len = cr.norm();
    const int k = (*in.dense_face_patch)[f];
    if (k >= 0 && k < in.num_patches) patch_normal[k] += cr;
    if (len <= area_eps) continue;
    const Eigen::Vector3d n = cr / len;
    const double area = 0.5 * len;
    const double offset = n.dot(a);
    int r[3] = {rep[F(f, 0)], rep[F(f, 1)], rep[F(f, 2)]};
    for (int j = 0; j < 3; ++j) {
      if (r[j] < 0 || (j > 0 && r[j] == r[0]) || (j == 2 && r[2] == r[1])) continue;
      Q[r[j]].AddPlane(n, offset, area);
    }
  }
  for (auto& n : patch_normal) {
    const double len = n.norm();
    n = len > 0.0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
  }
  if (has_boundary && options.boundary_weight > 0.0) {
    // Directed edges between boundary vertices; one without its reverse is on the mesh boundary.
    std::unordered_set<long long> directed;
    auto key = [](int a, int b) { return (static_cast<long long>(a) << 32) | static_cast<unsigned>(b); };
    for (int f = 0; f < nf; ++f) {
      for (int j = 0; j < 3; ++j) {
        const int x = F(f, j), y = F(f, (j + 1) % 3);
        if ((*in.boundary_vertex)[x] && (*in.boundary_vertex)[y]) directed.insert(key(x, y));
      }
    }
    for (int f = 0; f < nf; ++f) {
      for (int j = 0; j < 3; ++j) {
        const int x = F(f, j), y = F(f, (j + 1) % 3);
        if (!(*in.boundary_vertex)[x] || !(*in.boundary_vertex)[y] || directed.count(key(y, x))) continue;
        const Eigen::Vector3d a = Row(V, F(f, 0)), b = Row(V, F(f, 1)), c = Row(V, F(f, 2));
        const Eigen::Vector3d cr = (b - a).cross(c - a);
        const Eigen::Vector3d e = Row(V, y) - Row(V, x);
        Eigen::Vector3d m = e.cross(cr);
        const double mlen = m.norm();
        if (mlen <= 0.0) continue;
        m /= mlen;
        const double w = options.boundary_weight * e.squaredNorm();
        const double offset = m.dot(Row(V, x));
        const int rx = rep[x], ry = rep[y];
        if (rx >= 0) Qb[rx].AddPlane(m, offset, w);
        if (ry >= 0 && ry != rx) Qb[ry].AddPlane(m, offset, w);
      }
    }
  }

  // Coarse stars.
  std::vector<std::vector<int>> star(nv);
  for (int f = 0; f < C.rows(); ++f) {
    for (int j = 0; j < 3; ++j) star[C(f, j)].push_back(f);
  }
  Vertices X = V;
  auto cross_of = [&](int f) {
    const Eigen::Vector3d a = Row(X, C(f, 0)), b = Row(X, C(f, 1)), c = Row(X, C(f, 2));
    return Eigen::Vector3d((b - a).cross(c - a));
  };
  std::vector<Eigen::Vector3d> before;
  // Moves v from where it is towards `target`, halving the step while a triangle of its star would lose its
  // area, reverse or leave its patch's cone (where it was inside before); false when v stays.
  auto guarded_move = [&](int v, const Eigen::Vector3d& target) {
    if (!target.allFinite()) return false;
    const Eigen::Vector3d x0 = Row(X, v);
    before.clear();
    for (int f : star[v]) before.push_back(cross_of(f));
    double t = 1.0;
    for (int h = 0; h <= options.max_halvings; ++h, t *= 0.5) {
      X.row(v) = (x0 + t * (target - x0)).transpose();
      bool ok = true;
      for (size_t i = 0; i < star[v].size() && ok; ++i) {
        const int f = star[v][i];
        const Eigen::Vector3d now = cross_of(f);
        const double len = now.norm();
        const Eigen::Vector3d& pn = patch_normal[(*in.coarse_face_patch)[f]];
        const double min_cos = options.min_cos_to_patch_normal;
        const bool cone_before = before[i].dot(pn) >= min_cos * before[i].norm();
        ok = len > area_eps && now.dot(before[i]) > 0.0 && (!cone_before || now.dot(pn) >= min_cos * len);
      }
      if (ok) return true;
    }
    X.row(v) = x0.transpose();
    return false;
  };
  auto movable = [&](int v) { return kept[v] && !star[v].empty() && !(has_fixed && (*in.fixed)[v]); };

  // Phase 1: the regularised minimiser of each cluster's quadric.
  for (int v = 0; v < nv; ++v) {
    if (!movable(v)) continue;
    Quadric q = Q[v];
    q.A += Qb[v].A;
    q.b += Qb[v].b;
    q.c += Qb[v].c;
    const double trace = q.A.trace();
    if (!(trace > 0.0)) continue;
    const Eigen::Vector3d x0 = Row(V, v);
    const double e0 = q.Error(x0);
    const double alpha = options.regularisation * trace / 3.0;
    const Eigen::Vector3d target = (q.A + alpha * Eigen::Matrix3d::Identity()).ldlt().solve(q.b + alpha * x0);
    s.quadric_error_before += e0;
    if (guarded_move(v, target)) {
      ++s.moved;
      s.quadric_error_after += q.Error(Row(X, v));
    } else {
      ++s.blocked;
      s.quadric_error_after += e0;
    }
  }

  // Phase 2: fit to the dense vertices (point-to-plane, as in Hoppe et al. 1993's mesh optimisation). Each
  // dense vertex is projected onto the nearest coarse face around the vertex it collapsed onto; then every
  // kept vertex moves, one at a time, to the regularised minimiser of its samples' squared distances along
  // their faces' normals (a quadric again: Σ w b_v² (nᵀx − …)², b_v its barycentric weight).
  if (options.fit_rounds > 0) {
    std::vector<double> vertex_area(nv, 0.0);
    for (int f = 0; f < nf; ++f) {
      const Eigen::Vector3d a = Row(V, F(f, 0)), b = Row(V, F(f, 1)), c = Row(V, F(f, 2));
      const double area = 0.5 * (b - a).cross(c - a).norm();
      for (int j = 0; j < 3; ++j) vertex_area[F(f, j)] += area / 3.0;
    }
    struct Sample {
      int face;
      Eigen::Vector3d bary;
    };
    std::vector<Sample> sample(nv, Sample{-1, Eigen::Vector3d::Zero()});
    std::vector<double> sample_d2(nv, 0.0);
    std::vector<std::vector<int>> face_samples(C.rows());
    // stamp: per coarse face, the last j that considered it (one array per block of a parallel scan).
    auto project = [&](int j, std::vector<int>& stamp) {
      const Eigen::Vector3d p = Row(V, j);
      double best = std::numeric_limits<double>::infinity();
      Sample out{-1, Eigen::Vector3d::Zero()};
      auto consider = [&](int f) {
        if (stamp[f] == j) return;
        stamp[f] = j;
        Eigen::Vector3d bary;
        const double d2 = ClosestPointOnTriangle(p, Row(X, C(f, 0)), Row(X, C(f, 1)), Row(X, C(f, 2)), &bary);
        if (d2 < best) {
          best = d2;
          out = {f, bary};
        }
      };
      for (int f : star[rep[j]]) consider(f);
      if (out.face >= 0) {
        const int f0 = out.face;
        for (int k = 0; k < 3; ++k) {
          for (int f : star[C(f0, k)]) consider(f);
        }
      }
      return std::make_pair(out, best);
    };
    auto assign = [&](double* sum_d2, double* sum_w) {
      for (auto& list : face_samples) list.clear();
      *sum_d2 = 0.0;
      *sum_w = 0.0;
      // The projections in parallel (X is only read), the sums in vertex order as a serial scan makes them.
      constexpr int kBlock = 16384;
      tbb::parallel_for(0, (nv + kBlock - 1) / kBlock, [&](int block) {
        std::vector<int> stamp(C.rows(), -1);
        for (int j = block * kBlock, end = std::min(nv, j + kBlock); j < end; ++j) {
          if (rep[j] < 0 || vertex_area[j] <= 0.0) continue;
          std::tie(sample[j], sample_d2[j]) = project(j, stamp);
        }
      });
      for (int j = 0; j < nv; ++j) {
        if (rep[j] < 0 || vertex_area[j] <= 0.0) continue;
        const Sample& smp = sample[j];
        const double d2 = sample_d2[j];
        if (smp.face < 0) continue;
        face_samples[smp.face].push_back(j);
        *sum_d2 += vertex_area[j] * d2;
        *sum_w += vertex_area[j];
      }
    };
    double d2 = 0.0, w = 0.0;
    assign(&d2, &w);
    s.fit_rms_before = w > 0.0 ? std::sqrt(d2 / w) : 0.0;
    for (int round = 0; round < options.fit_rounds; ++round) {
      for (int v = 0; v < nv; ++v) {
        if (!movable(v)) continue;
        Eigen::Matrix3d A = Qb[v].A;
        Eigen::Vector3d rhs = Qb[v].b;
        for (int f : star[v]) {
          if (face_samples[f].empty()) continue;
          Eigen::Vector3d n = cross_of(f);
          const double len = n.norm();
          if (len <= area_eps) continue;
          n /= len;
          int corner = 0;
          while (C(f, corner) != v) ++corner;
          for (int j : face_samples[f]) {
            const Eigen::Vector3d& b = sample[j].bary;
            Eigen::Vector3d rest = Row(V, j);
            for (int k = 0; k < 3; ++k) {
              if (k != corner) rest -= b[k] * Row(X, C(f, k));
            }
            const double bv = b[corner];
            A += vertex_area[j] * bv * bv * n * n.transpose();
            rhs += vertex_area[j] * bv * n.dot(rest) * n;
          }
        }
        const double trace = A.trace();
        if (!(trace > 0.0)) continue;
        const double alpha = options.regularisation * trace / 3.0;
        const Eigen::Vector3d target = (A + alpha * Eigen::Matrix3d::Identity()).ldlt().solve(rhs + alpha * Row(V, v));
        guarded_move(v, target);
      }
      assign(&d2, &w);
    }
    s.fit_rms_after = w > 0.0 ? std::sqrt(d2 / w) : 0.0;
  }
  return X;
}

}  // namespace rangebayes
