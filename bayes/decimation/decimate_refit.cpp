#include "bayes/decimation/decimate_refit.h"

#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <tuple>
#include <unordered_map>
#include <unordered_set>
#include <utility>

#include "bayes/decimation/decimate_geometry.h"
#include "core/error.h"

namespace rangebayes {
namespace {

// A sum of weighted squared plane distances, error(x) = xᵀ A x − 2 bᵀ x + const; the minimisers solve with A and b.
// Its value comes from the expansion about a point near the planes (`origin`, the kept vertex's dense position),
// dᵀ A d − 2 b_originᵀ d + c_origin with d = x − origin: about the coordinate origin the terms are of the size of the
// squared coordinates and cancel for a point near the planes, down to negative errors.
struct Quadric {
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b = Eigen::Vector3d::Zero();
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d b_origin = Eigen::Vector3d::Zero();
  double c_origin = 0.0;

  // The plane through `point` with unit normal n.
  void AddPlane(const Eigen::Vector3d& n, const Eigen::Vector3d& point, double weight) {
    A += weight * n * n.transpose();
    b += weight * n.dot(point) * n;
    const double offset = n.dot(point - origin);
    b_origin += weight * offset * n;
    c_origin += weight * offset * offset;
  }
  // q, expanded about the same origin.
  void Add(const Quadric& q) {
    A += q.A;
    b += q.b;
    b_origin += q.b_origin;
    c_origin += q.c_origin;
  }
  // Clamped at 0: rounding can still take the sum of squares a hair below it.
  double Error(const Eigen::Vector3d& x) const {
    const Eigen::Vector3d d = x - origin;
    return std::max(0.0, d.dot(A * d) - 2.0 * b_origin.dot(d) + c_origin);
  }
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

// Calls visit(r) once for each distinct kept vertex r among the representatives of dense face f's corners.
template <class Visit>
void ForEachCluster(const Faces& F, const std::vector<int>& rep, int f, const Visit& visit) {
  const int r[3] = {rep[F(f, 0)], rep[F(f, 1)], rep[F(f, 2)]};
  for (int j = 0; j < 3; ++j) {
    if (r[j] < 0 || (j > 0 && r[j] == r[0]) || (j == 2 && r[2] == r[1])) continue;
    visit(r[j]);
  }
}

// Adds each dense face's plane, weighted by its area, to the quadric of every distinct cluster among its
// corners (as in Garland–Heckbert).
void AddFaceQuadrics(const RefitInput& in, double area_eps, std::vector<Quadric>* Q_out) {
  const Vertices& V = *in.dense_V;
  const Faces& F = *in.dense_F;
  const std::vector<int>& rep = *in.representative;
  std::vector<Quadric>& Q = *Q_out;
  const int nf = static_cast<int>(F.rows());
  for (int f = 0; f < nf; ++f) {
    const Eigen::Vector3d a = Row(V, F(f, 0)), b = Row(V, F(f, 1)), c = Row(V, F(f, 2));
    const Eigen::Vector3d cr = (b - a).cross(c - a);
    const double len = cr.norm();
    if (len <= area_eps) continue;
    const Eigen::Vector3d n = cr / len;
    const double area = 0.5 * len;
    ForEachCluster(F, rep, f, [&](int r) { Q[r].AddPlane(n, a, area); });
  }
}

// Adds, for each mesh-boundary edge (between boundary vertices, without its reverse), the plane through it
// perpendicular to its face, weighted by boundary_weight × its squared length, to its endpoints' clusters.
void AddBoundaryQuadrics(const RefitInput& in, double boundary_weight, std::vector<Quadric>* Qb_out) {
  const Vertices& V = *in.dense_V;
  const Faces& F = *in.dense_F;
  const std::vector<int>& rep = *in.representative;
  std::vector<Quadric>& Qb = *Qb_out;
  const int nf = static_cast<int>(F.rows());
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
      const double w = boundary_weight * e.squaredNorm();
      const int rx = rep[x], ry = rep[y];
      if (rx >= 0) Qb[rx].AddPlane(m, Row(V, x), w);
      if (ry >= 0 && ry != rx) Qb[ry].AddPlane(m, Row(V, x), w);
    }
  }
}

// The coarse mesh being refitted: positions X (over dense vertex ids), the coarse stars, and the guarded move.
struct CoarseState {
  const Faces& C;
  const std::vector<int>& coarse_face_patch;
  const std::vector<Eigen::Vector3d>& patch_normal;   // PatchConeAxes
  const std::vector<Eigen::Vector3d>& vertex_normal;  // DenseVertexNormals where a patch has no axis, else empty
  const VertexRefitOptions& options;
  double min_cos;  // RefitInput::min_cos_to_patch_normal
  double area_eps;
  Vertices X;
  std::vector<std::vector<int>> star;  // per vertex, its coarse faces
  // Per coarse face, its area vector where the refit started. Each step is held within 90° of the one before it,
  // and every step to this too: steps that each turn a triangle by less than 90° can add up to a reversal.
  std::vector<Eigen::Vector3d> start;
  std::vector<Eigen::Vector3d> before;  // scratch of GuardedMove

  // Twice the area vector of coarse face f at the current positions.
  Eigen::Vector3d CrossOf(int f) const {
    const Eigen::Vector3d a = Row(X, C(f, 0)), b = Row(X, C(f, 1)), c = Row(X, C(f, 2));
    return Eigen::Vector3d((b - a).cross(c - a));
  }

  // Moves v from where it is towards `target`, halving the step while a triangle of its star would lose its
  // area, reverse (against where the step or the refit started) or leave its patch's cone (where it was inside
  // before; InPatchCone); false when v stays.
  bool GuardedMove(int v, const Eigen::Vector3d& target) {
    if (!target.allFinite()) return false;
    const Eigen::Vector3d x0 = Row(X, v);
    before.clear();
    for (int f : star[v]) before.push_back(CrossOf(f));
    double t = 1.0;
    for (int h = 0; h <= options.max_halvings; ++h, t *= 0.5) {
      X.row(v) = (x0 + t * (target - x0)).transpose();
      bool ok = true;
      for (size_t i = 0; i < star[v].size() && ok; ++i) {
        const int f = star[v][i];
        const Eigen::Vector3d now = CrossOf(f);
        const double len = now.norm();
        const Eigen::Vector3d& pn = patch_normal[coarse_face_patch[f]];
        const std::array<int, 3> corners = {C(f, 0), C(f, 1), C(f, 2)};

        const bool cone_before = InPatchCone(before[i], pn, corners, vertex_normal, min_cos);
        ok = len > area_eps && now.dot(before[i]) > 0.0 && now.dot(start[f]) > 0.0 &&
             (!cone_before || InPatchCone(now, pn, corners, vertex_normal, min_cos));
      }
      if (ok) return true;
    }
    X.row(v) = x0.transpose();
    return false;
  }
};

// Phase 1: each movable vertex to the regularised minimiser of its cluster's face and boundary quadrics;
// counts and quadric errors into s.
void MoveToQuadricMinimisers(const Vertices& V, const std::vector<Quadric>& Q, const std::vector<Quadric>& Qb,
                             const std::vector<char>& movable, CoarseState* st, VertexRefitSummary* s) {
  const int nv = static_cast<int>(V.rows());
  for (int v = 0; v < nv; ++v) {
    if (!movable[v]) continue;
    Quadric q = Q[v];
    q.Add(Qb[v]);
    const double trace = q.A.trace();
    if (!(trace > 0.0)) continue;
    const Eigen::Vector3d x0 = Row(V, v);
    const double e0 = q.Error(x0);
    const double alpha = st->options.regularisation * trace / 3.0;
    const Eigen::Vector3d target = (q.A + alpha * Eigen::Matrix3d::Identity()).ldlt().solve(q.b + alpha * x0);
    s->quadric_error_before += e0;
    if (st->GuardedMove(v, target)) {
      ++s->moved;
      s->quadric_error_after += q.Error(Row(st->X, v));
    } else {
      ++s->blocked;
      s->quadric_error_after += e0;
    }
  }
}

struct Sample {
  int face;
  Eigen::Vector3d bary;
};

// Dense vertices projected onto the coarse mesh: per dense vertex its face (−1: none) and squared distance,
// per coarse face the dense vertices projected onto it.
struct DenseSamples {
  std::vector<Sample> sample;
  std::vector<double> sample_d2;
  std::vector<std::vector<int>> face_samples;
};

// The points of a coarse triangle held on the dense surface, in barycentric coordinates: its centroid and the
// points halfway from there to its corners.
constexpr int kCoveragePoints = 4;
const Eigen::Vector3d kCoverageBary[kCoveragePoints] = {
    {1.0 / 3, 1.0 / 3, 1.0 / 3}, {2.0 / 3, 1.0 / 6, 1.0 / 6}, {1.0 / 6, 2.0 / 3, 1.0 / 6}, {1.0 / 6, 1.0 / 6, 2.0 / 3}};

// Per coarse face and point, the plane of the dense face nearest to the point (unit normal, offset nᵀp) and the
// point's weight (0: no dense face found).
struct CoveragePlane {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  double offset = 0.0;
  double weight = 0.0;
};

// Per kept vertex, the dense faces with a corner in its cluster (compressed rows); per dense face a bounding
// sphere (its centroid, the distance to its farthest corner), to skip faces that cannot be nearer.
struct ClusterFaces {
  std::vector<int> begin;  // size nv + 1
  std::vector<int> faces;
  std::vector<Eigen::Vector3d> centre;
  std::vector<double> radius;
};

ClusterFaces BuildClusterFaces(const Vertices& V, const Faces& F, const std::vector<int>& rep) {
  const int nv = static_cast<int>(V.rows());
  ClusterFaces out;
  out.begin.assign(nv + 1, 0);
  const int nf = static_cast<int>(F.rows());
  out.centre.resize(nf);
  out.radius.resize(nf);
  for (int f = 0; f < nf; ++f) {
    const Eigen::Vector3d a = Row(V, F(f, 0)), b = Row(V, F(f, 1)), c = Row(V, F(f, 2));
    out.centre[f] = (a + b + c) / 3.0;
    out.radius[f] = std::sqrt(std::max({(a - out.centre[f]).squaredNorm(), (b - out.centre[f]).squaredNorm(),
                                        (c - out.centre[f]).squaredNorm()}));
  }
  for (int f = 0; f < nf; ++f) ForEachCluster(F, rep, f, [&](int r) { ++out.begin[r + 1]; });
  for (int v = 0; v < nv; ++v) out.begin[v + 1] += out.begin[v];
  out.faces.resize(out.begin[nv]);
  std::vector<int> fill(out.begin.begin(), out.begin.end() - 1);
  for (int f = 0; f < nf; ++f) ForEachCluster(F, rep, f, [&](int r) { out.faces[fill[r]++] = f; });
  return out;
}

// For every coarse face, each of its points' nearest dense face among those of its patch in its corners'
// clusters, with weight coverage_weight × a quarter of its area (at the current positions).
void AssignCoverage(const RefitInput& in, const ClusterFaces& clusters, const CoarseState& st,
                    std::vector<CoveragePlane>* planes) {
  const Vertices& V = *in.dense_V;
  const Faces& F = *in.dense_F;
  const Faces& C = st.C;
  const double weight = st.options.coverage_weight;
  planes->assign(static_cast<size_t>(C.rows()) * kCoveragePoints, CoveragePlane{});
  tbb::parallel_for(0, static_cast<int>(C.rows()), [&](int f) {
    const int patch = st.coarse_face_patch[f];
    const Eigen::Vector3d x[3] = {Row(st.X, C(f, 0)), Row(st.X, C(f, 1)), Row(st.X, C(f, 2))};
    const double area = 0.5 * (x[1] - x[0]).cross(x[2] - x[0]).norm();
    if (!(area > 0.0)) return;
    Eigen::Vector3d q[kCoveragePoints];
    double best[kCoveragePoints];
    int nearest[kCoveragePoints];
    for (int i = 0; i < kCoveragePoints; ++i) {
      q[i] = kCoverageBary[i](0) * x[0] + kCoverageBary[i](1) * x[1] + kCoverageBary[i](2) * x[2];
      best[i] = std::numeric_limits<double>::infinity();
      nearest[i] = -1;
    }
    Eigen::Vector3d bary;
    for (int k = 0; k < 3; ++k) {
      const int v = C(f, k);
      for (int e = clusters.begin[v]; e < clusters.begin[v + 1]; ++e) {
        const int g = clusters.faces[e];
        if ((*in.dense_face_patch)[g] != patch) continue;
        const Eigen::Vector3d a = Row(V, F(g, 0)), b = Row(V, F(g, 1)), c = Row(V, F(g, 2));
        for (int i = 0; i < kCoveragePoints; ++i) {
          const double lower = (q[i] - clusters.centre[g]).norm() - clusters.radius[g];
          if (lower > 0.0 && lower * lower >= best[i]) continue;
          const double d2 = ClosestPointOnTriangle(q[i], a, b, c, &bary);
          if (d2 < best[i]) {
            best[i] = d2;
            nearest[i] = g;
          }
        }
      }
    }
    for (int i = 0; i < kCoveragePoints; ++i) {
      if (nearest[i] < 0) continue;
      const int g = nearest[i];
      const Eigen::Vector3d a = Row(V, F(g, 0));
      const Eigen::Vector3d cr = (Row(V, F(g, 1)) - a).cross(Row(V, F(g, 2)) - a);
      const double len = cr.norm();
      if (len <= st.area_eps) continue;
      CoveragePlane& plane = (*planes)[static_cast<size_t>(f) * kCoveragePoints + i];
      plane.n = cr / len;
      plane.offset = plane.n.dot(a);
      plane.weight = weight * area / kCoveragePoints;
    }
  });
}

// One third of the area of each dense face on each of its corners.
std::vector<double> VertexAreas(const Vertices& V, const Faces& F) {
  const int nv = static_cast<int>(V.rows());
  const int nf = static_cast<int>(F.rows());
  std::vector<double> vertex_area(nv, 0.0);
  for (int f = 0; f < nf; ++f) {
    const Eigen::Vector3d a = Row(V, F(f, 0)), b = Row(V, F(f, 1)), c = Row(V, F(f, 2));
    const double area = 0.5 * (b - a).cross(c - a).norm();
    for (int j = 0; j < 3; ++j) vertex_area[F(f, j)] += area / 3.0;
  }
  return vertex_area;
}

// Steps of the walk that projects a dense vertex onto the coarse mesh: from the star of its representative to
// the stars of the best face's corners, while that finds a nearer face.
constexpr int kProjectionSteps = 8;

// That walk for query j from the faces of star[start]; distance2(f) is the squared distance to coarse face f.
// Returns the nearest face found (−1: none) and its squared distance in *best. stamp: per coarse face, the last
// query that considered it.
template <class Distance2>
int WalkToNearestFace(const std::vector<std::vector<int>>& star, const Faces& C, int start, int j,
                      std::vector<int>& stamp, const Distance2& distance2, double* best) {
  *best = std::numeric_limits<double>::infinity();
  int out = -1;
  auto consider = [&](int f) {
    if (stamp[f] == j) return;
    stamp[f] = j;
    const double d2 = distance2(f);
    if (d2 < *best) {
      *best = d2;
      out = f;
    }
  };
  for (int f : star[start]) consider(f);
  for (int step = 0; step < kProjectionSteps && out >= 0; ++step) {
    const int f0 = out;
    for (int k = 0; k < 3; ++k) {
      for (int f : star[C(f0, k)]) consider(f);
    }
    if (out == f0) break;
  }
  return out;
}

// The closest point to dense vertex j found by that walk, with its squared distance.
std::pair<Sample, double> ProjectDenseVertex(const Vertices& V, const std::vector<int>& rep, const CoarseState& st,
                                             int j, std::vector<int>& stamp) {
  const Faces& C = st.C;
  const Vertices& X = st.X;
  const Eigen::Vector3d p = Row(V, j);
  auto distance2 = [&](int f, Eigen::Vector3d* bary) {
    return ClosestPointOnTriangle(p, Row(X, C(f, 0)), Row(X, C(f, 1)), Row(X, C(f, 2)), bary);
  };
  Eigen::Vector3d bary;
  double best = 0.0;
  const int face = WalkToNearestFace(st.star, C, rep[j], j, stamp, [&](int f) { return distance2(f, &bary); }, &best);
  Sample out{face, Eigen::Vector3d::Zero()};
  if (face >= 0) best = distance2(face, &out.bary);
  return std::make_pair(out, best);
}

// Projects every dense vertex with a representative and area onto the coarse mesh into ds; the area-weighted
// sum of squared distances and the sum of the weights into sum_d2, sum_w.
void AssignSamples(const Vertices& V, const std::vector<int>& rep, const std::vector<double>& vertex_area,
                   const CoarseState& st, DenseSamples* ds, double* sum_d2, double* sum_w) {
  const int nv = static_cast<int>(V.rows());
  const Faces& C = st.C;
  for (auto& list : ds->face_samples) list.clear();
  *sum_d2 = 0.0;
  *sum_w = 0.0;
  // The projections in parallel (X is only read), the sums in vertex order as a serial scan makes them.
  constexpr int kBlock = 16384;
  tbb::parallel_for(0, (nv + kBlock - 1) / kBlock, [&](int block) {
    std::vector<int> stamp(C.rows(), -1);
    for (int j = block * kBlock, end = std::min(nv, j + kBlock); j < end; ++j) {
      if (rep[j] < 0 || vertex_area[j] <= 0.0) continue;
      std::tie(ds->sample[j], ds->sample_d2[j]) = ProjectDenseVertex(V, rep, st, j, stamp);
    }
  });
  for (int j = 0; j < nv; ++j) {
    if (rep[j] < 0 || vertex_area[j] <= 0.0) continue;
    const Sample& smp = ds->sample[j];
    const double d2 = ds->sample_d2[j];
    if (smp.face < 0) continue;
    ds->face_samples[smp.face].push_back(j);
    *sum_d2 += vertex_area[j] * d2;
    *sum_w += vertex_area[j];
  }
}

// Moves v to the regularised minimiser of its boundary quadric plus its samples' squared point-to-plane
// distances (Σ w b_v² (nᵀx − …)², b_v the sample's barycentric weight of v) through the guard.
void FitVertexToSamples(const Vertices& V, const std::vector<double>& vertex_area, const Quadric& boundary,
                        const DenseSamples& ds, const std::vector<CoveragePlane>& coverage, int v,
                        CoarseState* st) {
  const Faces& C = st->C;
  const Vertices& X = st->X;
  Eigen::Matrix3d A = boundary.A;
  Eigen::Vector3d rhs = boundary.b;
  for (int f : st->star[v]) {
    int corner = 0;
    while (C(f, corner) != v) ++corner;
    // The face's own points held on the dense surface.
    for (int i = 0; i < kCoveragePoints && !coverage.empty(); ++i) {
      const CoveragePlane& plane = coverage[static_cast<size_t>(f) * kCoveragePoints + i];
      if (plane.weight <= 0.0) continue;
      const Eigen::Vector3d& b = kCoverageBary[i];
      double rest = plane.offset;
      for (int k = 0; k < 3; ++k) {
        if (k != corner) rest -= b[k] * plane.n.dot(Row(X, C(f, k)));
      }
      const double bv = b[corner];
      A += plane.weight * bv * bv * plane.n * plane.n.transpose();
      rhs += plane.weight * bv * rest * plane.n;
    }
    if (ds.face_samples[f].empty()) continue;
    Eigen::Vector3d n = st->CrossOf(f);
    const double len = n.norm();
    if (len <= st->area_eps) continue;
    n /= len;
    for (int j : ds.face_samples[f]) {
      const Eigen::Vector3d& b = ds.sample[j].bary;
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
  if (!(trace > 0.0)) return;
  const double alpha = st->options.regularisation * trace / 3.0;
  const Eigen::Vector3d target = (A + alpha * Eigen::Matrix3d::Identity()).ldlt().solve(rhs + alpha * Row(V, v));
  st->GuardedMove(v, target);
}

// Phase 2: fit to the dense vertices (point-to-plane, as in Hoppe et al. 1993's mesh optimisation). Each
// dense vertex is projected onto the nearest coarse face around the vertex it collapsed onto; then every
// kept vertex moves, one at a time, to the regularised minimiser of its samples' squared distances along
// their faces' normals and of its faces' points' squared distances to their nearest dense faces (coverage,
// found again at the start of each round), for fit_rounds rounds; the fit RMS before and after into s.
void FitToDenseVertices(const RefitInput& in, const std::vector<Quadric>& Qb, const std::vector<char>& movable,
                        CoarseState* st, VertexRefitSummary* s) {
  const Vertices& V = *in.dense_V;
  const std::vector<int>& rep = *in.representative;
  const int nv = static_cast<int>(V.rows());
  const std::vector<double> vertex_area = VertexAreas(V, *in.dense_F);
  DenseSamples ds;
  ds.sample.assign(nv, Sample{-1, Eigen::Vector3d::Zero()});
  ds.sample_d2.assign(nv, 0.0);
  ds.face_samples.resize(st->C.rows());
  double d2 = 0.0, w = 0.0;
  AssignSamples(V, rep, vertex_area, *st, &ds, &d2, &w);
  s->fit_rms_before = w > 0.0 ? std::sqrt(d2 / w) : 0.0;
  const bool coverage = st->options.coverage_weight > 0.0;
  const ClusterFaces clusters = coverage ? BuildClusterFaces(V, *in.dense_F, rep) : ClusterFaces{};
  std::vector<CoveragePlane> planes;
  for (int round = 0; round < st->options.fit_rounds; ++round) {
    if (coverage) AssignCoverage(in, clusters, *st, &planes);
    for (int v = 0; v < nv; ++v) {
      if (!movable[v]) continue;
      FitVertexToSamples(V, vertex_area, Qb[v], ds, planes, v, st);
    }
    AssignSamples(V, rep, vertex_area, *st, &ds, &d2, &w);
  }
  s->fit_rms_after = w > 0.0 ? std::sqrt(d2 / w) : 0.0;
}

}  // namespace

void VertexRefitOptions::Check() const {
  RB_CHECK(regularisation > 0.0 && std::isfinite(regularisation), "decimate: refit regularisation must be > 0, got ",
           regularisation);
  RB_CHECK(boundary_weight >= 0.0, "decimate: refit boundary_weight must be ≥ 0, got ", boundary_weight);
  RB_CHECK(fit_rounds >= 0, "decimate: refit fit_rounds must be ≥ 0, got ", fit_rounds);
  RB_CHECK(coverage_weight >= 0.0 && std::isfinite(coverage_weight),
           "decimate: refit coverage_weight must be ≥ 0, got ", coverage_weight);
  RB_CHECK(max_halvings >= 0, "decimate: refit max_halvings must be ≥ 0, got ", max_halvings);
  RB_CHECK(flip_sweeps >= 0, "decimate: refit flip_sweeps must be ≥ 0, got ", flip_sweeps);
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
  RB_CHECK(in.min_cos_to_patch_normal >= 0.0 && in.min_cos_to_patch_normal < 1.0,
           "decimate: refit min_cos_to_patch_normal must be in [0, 1), got ", in.min_cos_to_patch_normal);
  const std::vector<int>& rep = *in.representative;
  const bool has_boundary = in.boundary_vertex != nullptr && static_cast<int>(in.boundary_vertex->size()) == nv;
  const bool has_fixed = in.fixed != nullptr && static_cast<int>(in.fixed->size()) == nv;
  VertexRefitSummary local;
  VertexRefitSummary& s = summary != nullptr ? *summary : local;
  s = VertexRefitSummary{};

  // Quadrics per kept vertex, from the dense faces of its cluster, and patch normals for the cone guard.
  std::vector<Quadric> Q(nv), Qb(nv);  // face planes of the cluster; boundary planes; both about the vertex
  for (int v = 0; v < nv; ++v) Q[v].origin = Qb[v].origin = Row(V, v);
  std::vector<char> kept(nv, 0);
  for (int v = 0; v < nv; ++v) {
    if (rep[v] >= 0) kept[rep[v]] = 1;
  }
  const std::vector<Eigen::Vector3d> patch_normal = PatchConeAxes(V, F, *in.dense_face_patch, in.num_patches);
  std::vector<Eigen::Vector3d> vertex_normal;
  if (std::any_of(patch_normal.begin(), patch_normal.end(), [](const Eigen::Vector3d& n) { return n.isZero(0.0); })) {
    vertex_normal = DenseVertexNormals(V, F);
  }
  double diag2 = BoundingBoxExtent(V).squaredNorm();
  const double area_eps = 1e-14 * diag2;
  AddFaceQuadrics(in, area_eps, &Q);
  if (has_boundary && options.boundary_weight > 0.0) AddBoundaryQuadrics(in, options.boundary_weight, &Qb);

  CoarseState st{C,
                 *in.coarse_face_patch,
                 patch_normal,
                 vertex_normal,
                 options,
                 in.min_cos_to_patch_normal,
                 area_eps,
                 V,
                 std::vector<std::vector<int>>(nv),
                 {},
                 {}};
  st.start.resize(C.rows());
  for (int f = 0; f < C.rows(); ++f) {
    for (int j = 0; j < 3; ++j) st.star[C(f, j)].push_back(f);
    st.start[f] = st.CrossOf(f);
  }
  std::vector<char> movable(nv, 0);
  for (int v = 0; v < nv; ++v) movable[v] = kept[v] && !st.star[v].empty() && !(has_fixed && (*in.fixed)[v]);

  MoveToQuadricMinimisers(V, Q, Qb, movable, &st, &s);
  if (options.fit_rounds > 0) FitToDenseVertices(in, Qb, movable, &st, &s);
  return std::move(st.X);
}

}  // namespace rangebayes

namespace rangebayes {
namespace {

uint64_t EdgeKey(int a, int b) {
  const auto lo = static_cast<uint32_t>(std::min(a, b)), hi = static_cast<uint32_t>(std::max(a, b));
  return (static_cast<uint64_t>(lo) << 32) | hi;
}

// The coarse mesh and its samples during FlipEdgesToFit.
class Flipper {
 public:
  Flipper(const EdgeFlipInput& in, double min_cos, Faces* C) : in_(in), min_cos_(min_cos), C_(*C) {
    const Vertices& V0 = *in.dense_poses[0];
    const int nv = static_cast<int>(V0.rows());
    weight_ = VertexAreas(V0, *in.dense_F);
    area_eps_ = 1e-14 * BoundingBoxExtent(V0).squaredNorm();
    patch_normal_.resize(in.dense_poses.size());
    vertex_normal_.resize(in.dense_poses.size());
    for (size_t m = 0; m < in.dense_poses.size(); ++m) {
      const Vertices& V = *in.dense_poses[m];
      patch_normal_[m] = PatchConeAxes(V, *in.dense_F, *in.dense_face_patch, in.num_patches);
      if (std::any_of(patch_normal_[m].begin(), patch_normal_[m].end(),
                      [](const Eigen::Vector3d& n) { return n.isZero(0.0); })) {
        vertex_normal_[m] = DenseVertexNormals(V, *in.dense_F);
      }
    }
    star_.resize(nv);
    for (int f = 0; f < C_.rows(); ++f) {
      for (int k = 0; k < 3; ++k) star_[C_(f, k)].push_back(f);
    }
    if (in.weld_group != nullptr && !in.weld_group->empty()) {
      for (int v = 0; v < nv; ++v) {
        if ((*in.weld_group)[v] >= 0) copies_[(*in.weld_group)[v]].push_back(v);
      }
    }
    face_samples_.resize(C_.rows());
    d2_.assign(in.dense_poses.size(), std::vector<double>(nv, 0.0));
    changed_.assign(C_.rows(), 1);
    // The nearest faces in parallel (C and the positions are only read), the lists in vertex order.
    const std::vector<int>& rep = *in.representative;
    std::vector<int> face_of(nv, -1);
    constexpr int kBlock = 16384;
    tbb::parallel_for(0, (nv + kBlock - 1) / kBlock, [&](int block) {
      std::vector<int> stamp(C_.rows(), -1);
      for (int j = block * kBlock, end = std::min(nv, j + kBlock); j < end; ++j) {
        if (rep[j] < 0 || !(weight_[j] > 0.0) || star_[rep[j]].empty()) continue;
        const int f = Nearest(j, stamp);
        face_of[j] = f;
        if (f < 0) continue;
        for (size_t m = 0; m < d2_.size(); ++m) d2_[m][j] = Distance2(m, j, C_(f, 0), C_(f, 1), C_(f, 2));
      }
    });
    for (int j = 0; j < nv; ++j) {
      if (face_of[j] >= 0) face_samples_[face_of[j]].push_back(j);
    }
  }

  // Over the samples at their faces' distances, first pose.
  double Rms() const {
    double sum = 0.0, w = 0.0;
    for (int f = 0; f < C_.rows(); ++f) {
      for (int j : face_samples_[f]) {
        sum += weight_[j] * d2_[0][j];
        w += weight_[j];
      }
    }
    return w > 0.0 ? std::sqrt(sum / w) : 0.0;
  }

  // One sweep over the edges in key order; edges of faces flipped in this sweep wait for the next. Returns
  // the number of flips.
  int Sweep() {
    std::unordered_map<uint64_t, std::pair<int, int>> faces_of;
    faces_of.reserve(static_cast<size_t>(C_.rows()) * 2);
    for (int f = 0; f < C_.rows(); ++f) {
      for (int k = 0; k < 3; ++k) {
        auto [it, inserted] = faces_of.try_emplace(EdgeKey(C_(f, k), C_(f, (k + 1) % 3)), f, -1);
        if (!inserted) it->second.second = it->second.second == -1 ? f : -2;  // −2: more than two faces
      }
    }
    std::vector<std::tuple<uint64_t, int, int>> edges;
    edges.reserve(faces_of.size());
    for (const auto& [key, fs] : faces_of) {
      if (fs.second >= 0 && (*in_.coarse_face_patch)[fs.first] == (*in_.coarse_face_patch)[fs.second]) {
        edges.emplace_back(key, fs.first, fs.second);
      }
    }
    std::sort(edges.begin(), edges.end());
    std::unordered_set<uint64_t> exists;
    exists.reserve(faces_of.size());
    for (const auto& entry : faces_of) exists.insert(entry.first);
    // After the first sweep only edges with a face flipped in the last sweep are tried: for the others the
    // samples, the guard and the cost are as when they were refused (only a refusal because the other diagonal
    // existed could now go the other way, and is not revisited).
    std::vector<char> touched(C_.rows(), 0);
    int flips = 0;
    for (const auto& [key, f1, f2] : edges) {
      if (touched[f1] || touched[f2] || !(changed_[f1] || changed_[f2])) continue;
      if (TryFlip(f1, f2, &exists)) {
        touched[f1] = touched[f2] = 1;
        ++flips;
      }
    }
    changed_.swap(touched);
    return flips;
  }

 private:
  Eigen::Vector3d At(size_t m, int v) const { return Row(*in_.dense_poses[m], v); }
  Eigen::Vector3d Corner(size_t m, int v) const {
    return Row(in_.coarse_poses.empty() ? *in_.dense_poses[m] : *in_.coarse_poses[m], v);
  }

  double Distance2(size_t m, int j, int a, int b, int c) const {
    Eigen::Vector3d bary;
    return ClosestPointOnTriangle(At(m, j), Corner(m, a), Corner(m, b), Corner(m, c), &bary);
  }

  // The nearest coarse face to dense vertex j in the first pose (WalkToNearestFace from its representative).
  int Nearest(int j, std::vector<int>& stamp) const {
    double best = 0.0;
    return WalkToNearestFace(
        star_, C_, (*in_.representative)[j], j, stamp,
        [&](int f) { return Distance2(0, j, C_(f, 0), C_(f, 1), C_(f, 2)); }, &best);
  }

  // Whether triangle (a, b, c) keeps an area and stays in its patch's cone in pose m, at the coarse positions
  // (dense: at the dense ones); its area vector into *cross.
  bool Acceptable(size_t m, bool dense, int a, int b, int c, int patch, Eigen::Vector3d* cross) const {
    auto at = [&](int v) { return dense ? At(m, v) : Corner(m, v); };
    const Eigen::Vector3d pa = at(a);
    *cross = (at(b) - pa).cross(at(c) - pa);
    return cross->norm() > area_eps_ &&
           InPatchCone(*cross, patch_normal_[m][patch], {a, b, c}, vertex_normal_[m], min_cos_);
  }

  void Remove(int v, int f) {
    auto& s = star_[v];
    s.erase(std::find(s.begin(), s.end(), f));
  }

  // Whether a new edge cd joins two welded vertices, or gives two copies of one weld group a common neighbour
  // (welded, two edges would become one: see TriangulatePatches).
  bool BreaksWeld(int c, int d, const std::unordered_set<uint64_t>& exists) const {
    if (copies_.empty()) return false;
    const std::vector<int>& group = *in_.weld_group;
    if (group[c] >= 0 && group[d] >= 0) return true;
    for (const auto& [x, y] : {std::make_pair(c, d), std::make_pair(d, c)}) {
      if (group[x] < 0) continue;
      for (int other : copies_.at(group[x])) {
        if (other != x && exists.count(EdgeKey(other, y))) return true;
      }
    }
    return false;
  }

  bool TryFlip(int f1, int f2, std::unordered_set<uint64_t>* exists) {
    // f1 = (u, v, c) with the edge u → v, f2 = (v, u, d).
    int k1 = -1;
    for (int k = 0; k < 3 && k1 < 0; ++k) {
      const int x = C_(f1, k), y = C_(f1, (k + 1) % 3);
      for (int l = 0; l < 3; ++l) {
        if (C_(f2, l) == y && C_(f2, (l + 1) % 3) == x) k1 = k;
      }
    }
    if (k1 < 0) return false;  // the two faces disagree in orientation
    const int u = C_(f1, k1), v = C_(f1, (k1 + 1) % 3), c = C_(f1, (k1 + 2) % 3);
    int d = -1;
    for (int l = 0; l < 3; ++l) {
      if (C_(f2, l) != u && C_(f2, l) != v) d = C_(f2, l);
    }
    if (d < 0 || d == c || exists->count(EdgeKey(c, d))) return false;
    if (BreaksWeld(c, d, *exists)) return false;
    const int patch = (*in_.coarse_face_patch)[f1];
    // At the coarse positions, and at the dense ones where the refit starts (its guard then keeps the cone).
    for (size_t m = 0; m < in_.dense_poses.size(); ++m) {
      for (const bool dense : {false, true}) {
        Eigen::Vector3d n1, n2;
        if (!Acceptable(m, dense, c, u, d, patch, &n1) || !Acceptable(m, dense, d, v, c, patch, &n2) ||
            !(n1.dot(n2) > 0.0)) {
          return false;
        }
      }
    }
    // Each sample of the two faces goes to the nearer new triangle in the first pose, at its distances there
    // in every pose.
    samples_.assign(face_samples_[f1].begin(), face_samples_[f1].end());
    samples_.insert(samples_.end(), face_samples_[f2].begin(), face_samples_[f2].end());
    if (samples_.empty()) return false;
    const size_t poses = d2_.size(), ns = samples_.size();
    first_.resize(ns);
    next_d2_.resize(poses * ns);
    double before = 0.0, after = 0.0;
    for (size_t i = 0; i < ns; ++i) {
      const int j = samples_[i];
      for (size_t m = 0; m < poses; ++m) {
        const double d1 = Distance2(m, j, c, u, d), d2 = Distance2(m, j, d, v, c);
        if (m == 0) first_[i] = d1 <= d2;
        next_d2_[m * ns + i] = first_[i] ? d1 : d2;
        before += weight_[j] * d2_[m][j];
        after += weight_[j] * next_d2_[m * ns + i];
      }
    }
    if (!(after < (1.0 - 1e-6) * before)) return false;
    C_.row(f1) << c, u, d;
    C_.row(f2) << d, v, c;
    exists->erase(EdgeKey(u, v));
    exists->insert(EdgeKey(c, d));
    Remove(u, f2);
    Remove(v, f1);
    star_[c].push_back(f2);
    star_[d].push_back(f1);
    face_samples_[f1].clear();
    face_samples_[f2].clear();
    for (size_t i = 0; i < ns; ++i) {
      const int j = samples_[i];
      face_samples_[first_[i] ? f1 : f2].push_back(j);
      for (size_t m = 0; m < poses; ++m) d2_[m][j] = next_d2_[m * ns + i];
    }
    return true;
  }

  const EdgeFlipInput& in_;
  const double min_cos_;
  Faces& C_;
  std::vector<double> weight_;
  double area_eps_ = 0.0;
  std::vector<std::vector<Eigen::Vector3d>> patch_normal_;   // per pose, per patch: PatchConeAxes
  std::vector<std::vector<Eigen::Vector3d>> vertex_normal_;  // per pose: DenseVertexNormals where a patch has no axis
  std::vector<std::vector<int>> star_;                      // per dense vertex, its coarse faces
  std::unordered_map<int, std::vector<int>> copies_;        // per weld group, its vertices
  std::vector<std::vector<int>> face_samples_;              // per coarse face, its dense vertices
  std::vector<std::vector<double>> d2_;                     // per pose, per dense vertex: squared distance to its face
  std::vector<char> changed_;                               // per coarse face: flipped in the last sweep
  std::vector<int> samples_;                                // TryFlip's scratch
  std::vector<char> first_;
  std::vector<double> next_d2_;
};

}  // namespace

void FlipEdgesToFit(const EdgeFlipInput& in, double min_cos_to_patch_normal, int max_sweeps, Faces* coarse_F,
                    EdgeFlipSummary* summary) {
  EdgeFlipSummary local;
  EdgeFlipSummary& s = summary != nullptr ? *summary : local;
  s = EdgeFlipSummary{};
  RB_CHECK(!in.dense_poses.empty() && in.dense_F && in.dense_face_patch && in.representative &&
               in.coarse_face_patch && coarse_F,
           "decimate: edge flip input incomplete");
  const Eigen::Index nv = in.dense_poses[0]->rows();
  RB_CHECK(in.coarse_poses.empty() || in.coarse_poses.size() == in.dense_poses.size(),
           "decimate: edge flip needs coarse positions for every pose or none");
  for (const Vertices* V : in.dense_poses) RB_CHECK(V->rows() == nv, "decimate: edge flip pose size mismatch");
  for (const Vertices* X : in.coarse_poses) RB_CHECK(X->rows() == nv, "decimate: edge flip pose size mismatch");
  RB_CHECK(static_cast<Eigen::Index>(in.representative->size()) == nv,
           "decimate: edge flip representative size mismatch");
  RB_CHECK(static_cast<Eigen::Index>(in.dense_face_patch->size()) == in.dense_F->rows(),
           "decimate: edge flip patch map size mismatch");
  RB_CHECK(static_cast<Eigen::Index>(in.coarse_face_patch->size()) == coarse_F->rows(),
           "decimate: edge flip coarse patch size mismatch");
  RB_CHECK(in.weld_group == nullptr || in.weld_group->empty() || static_cast<Eigen::Index>(in.weld_group->size()) == nv,
           "decimate: edge flip weld_group size mismatch");
  if (max_sweeps <= 0 || coarse_F->rows() == 0) return;
  Flipper flipper(in, min_cos_to_patch_normal, coarse_F);
  s.fit_rms_before = flipper.Rms();
  while (s.sweeps < max_sweeps) {
    ++s.sweeps;
    const int flips = flipper.Sweep();
    s.flips += flips;
    if (flips == 0) break;
  }
  s.fit_rms_after = flipper.Rms();
}

}  // namespace rangebayes
