#include "bayes/adaptive_epsilon.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>

#include "core/error.h"
#include "core/topology.h"

namespace rangebayes {

void AdaptiveEpsilonOptions::Check() const {
  RB_CHECK(normal_smoothing_rings >= 0 && normal_smoothing_rings <= 50, "adaptive epsilon: normal_smoothing_rings ",
           normal_smoothing_rings, " is outside [0, 50]");
  RB_CHECK(ring_iterations >= 0 && ring_iterations <= 20, "adaptive epsilon: ring_iterations ", ring_iterations,
           " is outside [0, 20]");
  RB_CHECK(truncate_normal_difference > 0 && truncate_normal_difference <= 2,
           "adaptive epsilon: truncate_normal_difference ", truncate_normal_difference, " is outside (0, 2]");
  RB_CHECK(protect_normal_difference > 0 && protect_normal_difference <= 2,
           "adaptive epsilon: protect_normal_difference ", protect_normal_difference, " is outside (0, 2]");
  RB_CHECK(protect_rings >= -1 && protect_rings <= 10, "adaptive epsilon: protect_rings ", protect_rings,
           " is outside [-1, 10]");
  RB_CHECK(protect_min_crease_degree >= 0 && protect_min_crease_degree <= 10,
           "adaptive epsilon: protect_min_crease_degree ", protect_min_crease_degree, " is outside [0, 10]");
  RB_CHECK(scale >= 0 && scale <= 1e4, "adaptive epsilon: scale ", scale, " is outside [0, 1e4]");
  RB_CHECK(floor_normal_difference >= 0 && floor_normal_difference <= 2, "adaptive epsilon: floor_normal_difference ",
           floor_normal_difference, " is outside [0, 2]");
  RB_CHECK(min_epsilon_squared > 0 && min_epsilon_squared <= 4, "adaptive epsilon: min_epsilon_squared ",
           min_epsilon_squared, " is outside (0, 4]");
  RB_CHECK(max_epsilon_squared >= min_epsilon_squared && max_epsilon_squared <= 4,
           "adaptive epsilon: max_epsilon_squared ", max_epsilon_squared, " is outside [min_epsilon_squared, 4]");
}

namespace {

void CheckFaces(const Mesh& reference) {
  const int nf = reference.num_faces(), nv = reference.num_vertices();
  for (int f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = reference.F(f, k);
      RB_CHECK(v >= 0 && v < nv, "adaptive epsilon: face ", f, " refers to vertex ", v, ", but the mesh has ", nv,
               " vertices");
    }
  }
}

// Unit normals; faces without one (zero area, repeated index) are marked invalid.
void FaceNormals(const Mesh& reference, std::vector<Eigen::Vector3d>* normal, std::vector<char>* valid) {
  const int nf = reference.num_faces();
  normal->assign(static_cast<size_t>(nf), Eigen::Vector3d::Zero());
  valid->assign(static_cast<size_t>(nf), 0);
  tbb::parallel_for(tbb::blocked_range<int>(0, nf, 4096), [&](const tbb::blocked_range<int>& r) {
    for (int f = r.begin(); f != r.end(); ++f) {
      const int a = reference.F(f, 0), b = reference.F(f, 1), c = reference.F(f, 2);
      if (a == b || b == c || a == c) continue;
      const Eigen::Vector3d pa = reference.V.row(a).transpose();
      const Eigen::Vector3d cross = (reference.V.row(b).transpose() - pa).cross(reference.V.row(c).transpose() - pa);
      const double length = cross.norm();
      if (length > 0 && std::isfinite(length)) {
        (*normal)[static_cast<size_t>(f)] = cross / length;
        (*valid)[static_cast<size_t>(f)] = 1;
      }
    }
  });
}

// The options of a fast pre-pass (no per-face ε, no progress) on which a rule reads the shape.
SmoothOptions FastPrepassOptions(const SmoothOptions& options, int max_iterations) {
  SmoothOptions pre = options;
  pre.tolerance = SmoothTolerance::kFast;
  pre.max_iterations = max_iterations;
  pre.face_epsilon_squared.clear();
  pre.epsilon_continuation_stages = 0;  // the final solve takes per-face ε, so no stages there either
  pre.progress = nullptr;
  pre.adaptive_epsilon = false;
  return pre;
}

}  // namespace

namespace {

// The topology every rule reads (it depends on the faces only, so one copy serves the gate and the detail rule
// of AdaptiveEpsilonAuto): the face pairs, the faces of each vertex, and per face the faces that share a vertex
// with it (itself included), each once, in the order of first occurrence over its corners' vertex-face lists.
struct RuleTopology {
  IndexPairs pairs;
  Adjacency vertex_faces;
  Adjacency rings;
};

// Appends the faces sharing a vertex with f, each once, in first-occurrence order, to `out`; `marks` (one int per
// face, never equal to f + 1 before this call for f) remembers which were taken.
void GatherRing(const Mesh& mesh, const Adjacency& vertex_faces, int f, std::vector<int>* marks,
                std::vector<int>* out) {
  for (int k = 0; k < 3; ++k) {
    const int v = mesh.F(f, k);
    for (const int* g = vertex_faces.begin(v); g != vertex_faces.end(v); ++g) {
      int& mark = (*marks)[static_cast<size_t>(*g)];
      if (mark == f + 1) continue;
      mark = f + 1;
      out->push_back(*g);
    }
  }
}

RuleTopology MakeRuleTopology(const Mesh& mesh) {
  RuleTopology topology;
  topology.vertex_faces = ComputeVertexFaces(mesh);
  topology.pairs = ComputeFacePairs(mesh, topology.vertex_faces);
  // One gathering pass per block of faces into the block's own list, then the lists joined in block order.
  const int nf = mesh.num_faces();
  constexpr int kBlock = 4096;
  const int blocks = (nf + kBlock - 1) / kBlock;
  std::vector<std::vector<int>> block_items(static_cast<size_t>(blocks));
  std::vector<int> counts(static_cast<size_t>(nf) + 1, 0);
  {
    tbb::enumerable_thread_specific<std::vector<int>> marks(std::vector<int>(static_cast<size_t>(nf), 0));
    tbb::parallel_for(0, blocks, [&](int b) {
      std::vector<int>& mark = marks.local();
      std::vector<int>& items = block_items[static_cast<size_t>(b)];
      for (int f = b * kBlock; f < std::min(nf, (b + 1) * kBlock); ++f) {
        const size_t before = items.size();
        GatherRing(mesh, topology.vertex_faces, f, &mark, &items);
        counts[static_cast<size_t>(f) + 1] = static_cast<int>(items.size() - before);
      }
    });
  }
  for (int f = 0; f < nf; ++f) counts[static_cast<size_t>(f) + 1] += counts[static_cast<size_t>(f)];
  topology.rings.items.resize(static_cast<size_t>(counts.back()));
  tbb::parallel_for(0, blocks, [&](int b) {
    const std::vector<int>& items = block_items[static_cast<size_t>(b)];
    std::copy(items.begin(), items.end(), topology.rings.items.begin() + counts[static_cast<size_t>(b) * kBlock]);
  });
  topology.rings.offsets = std::move(counts);
  return topology;
}

std::vector<double> EpsilonSquaredOn(const Mesh& reference, const AdaptiveEpsilonOptions& options,
                                     const RuleTopology& topology, AdaptiveEpsilonSummary* summary);

}  // namespace

std::vector<double> AdaptiveEpsilonSquared(const Mesh& reference, const AdaptiveEpsilonOptions& options,
                                           AdaptiveEpsilonSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  options.Check();
  CheckFaces(reference);
  std::vector<double> epsilon_squared = EpsilonSquaredOn(reference, options, MakeRuleTopology(reference), summary);
  if (summary != nullptr) {
    summary->time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return epsilon_squared;
}

namespace {

// Step 0: area-weighted averages of the face normals over the faces sharing a vertex, `passes` times. The
// total turning of a surface survives averaging (a smoothly curved region keeps the gradient of its normal
// field) while the facets and small creases of a pre-smoothed scan, and noise, average out.
void AverageNormals(const Mesh& reference, const std::vector<char>& valid, const Adjacency& rings, int passes,
                    std::vector<Eigen::Vector3d>* normals) {
  const int nf = reference.num_faces();
  std::vector<Eigen::Vector3d>& normal = *normals;
  std::vector<double> area(static_cast<size_t>(nf), 0.0);
  for (int f = 0; f < nf; ++f) {
    if (!valid[static_cast<size_t>(f)]) continue;
    const Eigen::Vector3d pa = reference.V.row(reference.F(f, 0)).transpose();
    area[static_cast<size_t>(f)] = (reference.V.row(reference.F(f, 1)).transpose() - pa)
                                       .cross(reference.V.row(reference.F(f, 2)).transpose() - pa)
                                       .norm();
  }
  std::vector<Eigen::Vector3d> next(static_cast<size_t>(nf));
  for (int iteration = 0; iteration < passes; ++iteration) {
    tbb::parallel_for(tbb::blocked_range<int>(0, nf, 2048), [&](const tbb::blocked_range<int>& r) {
      for (int f = r.begin(); f != r.end(); ++f) {
        next[static_cast<size_t>(f)] = normal[static_cast<size_t>(f)];
        if (!valid[static_cast<size_t>(f)]) continue;
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        for (const int* g = rings.begin(f); g != rings.end(f); ++g) {
          if (!valid[static_cast<size_t>(*g)]) continue;
          sum += area[static_cast<size_t>(*g)] * normal[static_cast<size_t>(*g)];
        }
        const double length = sum.norm();
        if (length > 0) next[static_cast<size_t>(f)] = sum / length;
      }
    });
    normal.swap(next);
  }
}

// Step 1: per face the mean normal difference d to its edge neighbours (typical; has_value where it has one),
// and the pairs whose raw normals differ by more than protect_normal_difference (crease pairs).
struct PairDifferences {
  std::vector<double> typical;
  std::vector<char> has_value;
  std::vector<Eigen::Index> crease_pairs;
};

PairDifferences MeanPairDifferences(int nf, const IndexPairs& pairs, const std::vector<Eigen::Vector3d>& normal,
                                    const std::vector<char>& valid, const std::vector<Eigen::Vector3d>& crease_normal,
                                    const std::vector<char>& crease_valid, const AdaptiveEpsilonOptions& options) {
  PairDifferences out;
  std::vector<Eigen::Index>& crease_pairs = out.crease_pairs;
  // Per face the d of its valid pairs, in pair order (a CSR list: offsets, then values).
  std::vector<int> offsets(static_cast<size_t>(nf) + 1, 0);
  std::vector<double> pair_d(static_cast<size_t>(pairs.rows()), -1.0);
  std::vector<char> is_crease(static_cast<size_t>(pairs.rows()), 0);
  tbb::parallel_for(
      tbb::blocked_range<Eigen::Index>(0, pairs.rows(), 8192), [&](const tbb::blocked_range<Eigen::Index>& r) {
        for (Eigen::Index p = r.begin(); p != r.end(); ++p) {
          const int s = pairs(p, 0), t = pairs(p, 1);
          is_crease[static_cast<size_t>(p)] =
              crease_valid[static_cast<size_t>(s)] && crease_valid[static_cast<size_t>(t)] &&
              (crease_normal[static_cast<size_t>(s)] - crease_normal[static_cast<size_t>(t)]).norm() >
                  options.protect_normal_difference;
          if (!valid[static_cast<size_t>(s)] || !valid[static_cast<size_t>(t)]) continue;
          pair_d[static_cast<size_t>(p)] = (normal[static_cast<size_t>(s)] - normal[static_cast<size_t>(t)]).norm();
        }
      });
  for (Eigen::Index p = 0; p < pairs.rows(); ++p) {
    if (is_crease[static_cast<size_t>(p)]) crease_pairs.push_back(p);
    if (pair_d[static_cast<size_t>(p)] < 0) continue;
    ++offsets[static_cast<size_t>(pairs(p, 0)) + 1];
    ++offsets[static_cast<size_t>(pairs(p, 1)) + 1];
  }
  for (int f = 0; f < nf; ++f) offsets[static_cast<size_t>(f) + 1] += offsets[static_cast<size_t>(f)];
  std::vector<double> differences(static_cast<size_t>(offsets.back()));
  {
    std::vector<int> fill(offsets.begin(), offsets.end() - 1);
    for (Eigen::Index p = 0; p < pairs.rows(); ++p) {
      const double d = pair_d[static_cast<size_t>(p)];
      if (d < 0) continue;
      differences[static_cast<size_t>(fill[static_cast<size_t>(pairs(p, 0))]++)] = d;
      differences[static_cast<size_t>(fill[static_cast<size_t>(pairs(p, 1))]++)] = d;
    }
  }
  std::vector<double>().swap(pair_d);
  std::vector<double>& typical = out.typical;
  std::vector<char>& has_value = out.has_value;
  typical.assign(static_cast<size_t>(nf), 0.0);
  has_value.assign(static_cast<size_t>(nf), 0);
  tbb::parallel_for(tbb::blocked_range<int>(0, nf, 4096), [&](const tbb::blocked_range<int>& r) {
    for (int f = r.begin(); f != r.end(); ++f) {
      const int begin = offsets[static_cast<size_t>(f)], end = offsets[static_cast<size_t>(f) + 1];
      if (begin == end) continue;
      double sum = 0;
      for (int i = begin; i < end; ++i) sum += differences[static_cast<size_t>(i)];
      typical[static_cast<size_t>(f)] = sum / static_cast<double>(end - begin);
      has_value[static_cast<size_t>(f)] = 1;
    }
  });
  std::vector<double>().swap(differences);
  return out;
}

// Step 2: the truncated mean over the faces sharing a vertex (each face once), ring_iterations times.
void RingMeans(int nf, const Adjacency& rings, const std::vector<char>& has_value, const AdaptiveEpsilonOptions& options,
               std::vector<double>* typical_values) {
  std::vector<double>& typical = *typical_values;
  std::vector<double> next(static_cast<size_t>(nf));
  for (int iteration = 0; iteration < options.ring_iterations; ++iteration) {
    tbb::parallel_for(tbb::blocked_range<int>(0, nf, 2048), [&](const tbb::blocked_range<int>& r) {
      std::vector<double> window;
      for (int f = r.begin(); f != r.end(); ++f) {
        next[static_cast<size_t>(f)] = typical[static_cast<size_t>(f)];
        if (!has_value[static_cast<size_t>(f)]) continue;
        window.clear();
        for (const int* g = rings.begin(f); g != rings.end(f); ++g) {
          if (has_value[static_cast<size_t>(*g)]) window.push_back(typical[static_cast<size_t>(*g)]);
        }
        double sum = 0;
        int count = 0;
        for (double x : window) {
          if (x > options.truncate_normal_difference) continue;
          sum += x;
          ++count;
        }
        next[static_cast<size_t>(f)] = count > 0 ? sum / count : 0.0;
      }
    });
    typical.swap(next);
  }
}

// Crease protection: the faces of crease pairs (on crease lines when asked), grown by protect_rings rings;
// none when protect_rings < 0.
std::vector<char> ProtectedFaces(const Mesh& reference, const IndexPairs& pairs,
                                 const std::vector<Eigen::Index>& crease_pairs, const Adjacency& vertex_faces,
                                 const AdaptiveEpsilonOptions& options) {
  const int nf = reference.num_faces(), nv = reference.num_vertices();
  std::vector<char> crease(static_cast<size_t>(nf), 0);
  if (options.protect_rings < 0) return crease;
  std::vector<std::array<int, 2>> crease_edges(crease_pairs.size(), {-1, -1});
  std::vector<int> crease_degree(static_cast<size_t>(nv), 0);
  for (size_t e = 0; e < crease_pairs.size(); ++e) {
    const int s = pairs(crease_pairs[e], 0), t = pairs(crease_pairs[e], 1);
    int found = 0;
    for (int a = 0; a < 3 && found < 2; ++a) {
      for (int b = 0; b < 3; ++b) {
        if (reference.F(s, a) == reference.F(t, b)) {
          crease_edges[e][static_cast<size_t>(found++)] = reference.F(s, a);
          break;
        }
      }
    }
    if (found < 2) continue;
    ++crease_degree[static_cast<size_t>(crease_edges[e][0])];
    ++crease_degree[static_cast<size_t>(crease_edges[e][1])];
  }
  for (size_t e = 0; e < crease_pairs.size(); ++e) {
    if (options.protect_min_crease_degree > 0 &&
        (crease_edges[e][1] < 0 ||
         crease_degree[static_cast<size_t>(crease_edges[e][0])] < options.protect_min_crease_degree ||
         crease_degree[static_cast<size_t>(crease_edges[e][1])] < options.protect_min_crease_degree)) {
      continue;
    }
    crease[static_cast<size_t>(pairs(crease_pairs[e], 0))] = 1;
    crease[static_cast<size_t>(pairs(crease_pairs[e], 1))] = 1;
  }
  for (int ring = 0; ring < options.protect_rings; ++ring) {
    std::vector<char> grown = crease;
    for (int f = 0; f < nf; ++f) {
      if (!crease[static_cast<size_t>(f)]) continue;
      for (int k = 0; k < 3; ++k) {
        const int v = reference.F(f, k);
        for (const int* g = vertex_faces.begin(v); g != vertex_faces.end(v); ++g) grown[static_cast<size_t>(*g)] = 1;
      }
    }
    crease.swap(grown);
  }
  return crease;
}

std::vector<double> EpsilonSquaredOn(const Mesh& reference, const AdaptiveEpsilonOptions& options,
                                     const RuleTopology& topology, AdaptiveEpsilonSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  const int nf = reference.num_faces();
  std::vector<Eigen::Vector3d> normal;
  std::vector<char> valid;
  FaceNormals(reference, &normal, &valid);
  // Crease protection reads the raw normals (before step 0).
  const std::vector<Eigen::Vector3d> crease_normal = normal;
  if (options.normal_smoothing_rings > 0) {
    AverageNormals(reference, valid, topology.rings, options.normal_smoothing_rings, &normal);
  }
  PairDifferences differences =
      MeanPairDifferences(nf, topology.pairs, normal, valid, crease_normal, valid, options);
  std::vector<double>& typical = differences.typical;
  const std::vector<char>& has_value = differences.has_value;
  RingMeans(nf, topology.rings, has_value, options, &typical);
  const std::vector<char> crease =
      ProtectedFaces(reference, topology.pairs, differences.crease_pairs, topology.vertex_faces, options);

  // Step 3: ε² = c · (m² − d₀²), clamped.
  std::vector<double> epsilon_squared(static_cast<size_t>(nf), options.min_epsilon_squared);
  const double floor2 = options.floor_normal_difference * options.floor_normal_difference;
  int at_minimum = 0;
  for (int f = 0; f < nf; ++f) {
    if (has_value[static_cast<size_t>(f)] && !crease[static_cast<size_t>(f)]) {
      const double m = typical[static_cast<size_t>(f)];
      epsilon_squared[static_cast<size_t>(f)] = std::clamp(options.scale * std::max(0.0, m * m - floor2),
                                                           options.min_epsilon_squared, options.max_epsilon_squared);
    }
    if (epsilon_squared[static_cast<size_t>(f)] <= options.min_epsilon_squared) ++at_minimum;
  }

  if (summary != nullptr) {
    AdaptiveEpsilonSummary s;
    s.faces_at_minimum = at_minimum;
    if (nf > 0) {
      std::vector<double> sorted = epsilon_squared;
      auto quantile = [&](double q) {
        const auto at = sorted.begin() + static_cast<std::ptrdiff_t>(q * static_cast<double>(sorted.size() - 1) + 0.5);
        std::nth_element(sorted.begin(), at, sorted.end());
        return *at;
      };
      s.p10_epsilon_squared = quantile(0.1);
      s.median_epsilon_squared = quantile(0.5);
      s.p90_epsilon_squared = quantile(0.9);
    }
    s.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    *summary = s;
  }
  return epsilon_squared;
}

}  // namespace

AdaptiveEpsilonOptions ScanAdaptiveEpsilonOptions() { return AdaptiveEpsilonOptions{}; }

std::vector<double> AdaptiveEpsilonFromPrepass(const NoisyMesh& noisy, const SmoothOptions& options,
                                               const AdaptiveEpsilonOptions& rule, AdaptiveEpsilonSummary* summary) {
  RB_CHECK(options.potential == nullptr && options.prior == PriorKind::kSqrt,
           "adaptive epsilon: needs the square-root prior (--prior sqrt)");
  rule.Check();
  const auto start = std::chrono::steady_clock::now();
  const Mesh smoothed = Smooth(noisy, FastPrepassOptions(options, 0));
  std::vector<double> epsilon_squared = AdaptiveEpsilonSquared(smoothed, rule, summary);
  if (summary != nullptr) {
    summary->time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return epsilon_squared;
}

AdaptiveEpsilonOptions DetailAdaptiveEpsilonOptions() {
  AdaptiveEpsilonOptions options;
  options.truncate_normal_difference = 2.0;  // nothing truncated (d ≤ 2 always); ring_iterations 0 anyway
  options.normal_smoothing_rings = 4;
  options.ring_iterations = 0;
  options.scale = 24.0;
  options.max_epsilon_squared = 1.0;
  options.protect_rings = -1;  // no crease protection
  options.protect_normal_difference = 0.5;
  options.protect_min_crease_degree = 0;
  return options;
}

void AutoAdaptiveEpsilonOptions::Check() const {
  gate.Check();
  detail.Check();
  RB_CHECK(min_gate_median_epsilon_squared > 0 && min_gate_median_epsilon_squared <= 4,
           "adaptive epsilon: min_gate_median_epsilon_squared ", min_gate_median_epsilon_squared, " is outside (0, 4]");
  RB_CHECK(prepass_max_iterations >= 0 && prepass_max_iterations <= 10000000,
           "adaptive epsilon: prepass_max_iterations ", prepass_max_iterations, " is outside [0, 1e7]");
  RB_CHECK(prepass_early_iterations >= 0 &&
               (prepass_max_iterations == 0 || prepass_early_iterations <= prepass_max_iterations),
           "adaptive epsilon: prepass_early_iterations ", prepass_early_iterations, " is outside [0, ",
           prepass_max_iterations, "]");
  RB_CHECK(early_curved_gate_median_epsilon_squared > 0 && early_curved_gate_median_epsilon_squared <= 4,
           "adaptive epsilon: early_curved_gate_median_epsilon_squared ", early_curved_gate_median_epsilon_squared,
           " is outside (0, 4]");
}

std::vector<double> AdaptiveEpsilonAuto(const NoisyMesh& noisy, const SmoothOptions& options,
                                        const AutoAdaptiveEpsilonOptions& rule, AdaptiveEpsilonSummary* summary,
                                        Mesh* prepass_result) {
  RB_CHECK(options.potential == nullptr && options.prior == PriorKind::kSqrt,
           "adaptive epsilon: needs the square-root prior (--prior sqrt)");
  rule.Check();
  const auto start = std::chrono::steady_clock::now();
  const bool early = rule.prepass_early_iterations > 0 && rule.prepass_early_iterations != rule.prepass_max_iterations;
  SmoothOptions pre = FastPrepassOptions(options, early ? rule.prepass_early_iterations : rule.prepass_max_iterations);
  pre.energy_tolerance = 0;
  pre.initial_positions = nullptr;
  SmoothSummary pre_summary;
  Mesh smoothed = Smooth(noisy, pre, &pre_summary);
  int prepass_iterations = pre_summary.iterations, prepass_evaluations = pre_summary.evaluations;
  double prepass_time_s = pre_summary.time_s;

  // Smooth() has checked the face indices; the gate and the detail rule share one topology. The rules run on
  // options.num_threads threads like the solver (their result does not depend on it).
  tbb::task_arena arena(options.num_threads > 0 ? options.num_threads : tbb::task_arena::automatic);
  RuleTopology topology;
  AdaptiveEpsilonSummary gate_summary;
  arena.execute([&] {
    topology = MakeRuleTopology(noisy.mesh);
    EpsilonSquaredOn(smoothed, rule.gate, topology, &gate_summary);
  });
  bool curved = gate_summary.median_epsilon_squared >= rule.early_curved_gate_median_epsilon_squared;
  if (early && !curved && pre_summary.termination == SmoothTermination::kMaxIterations) {
    // Undecided: continue the same pre-pass (same energy, CG restarted) to the full cap.
    const int cap = rule.prepass_max_iterations > 0 ? rule.prepass_max_iterations : 300;
    pre.max_iterations = std::max(1, cap - pre_summary.iterations);
    const Vertices start_positions = smoothed.V;
    pre.initial_positions = &start_positions;
    smoothed = Smooth(noisy, pre, &pre_summary);
    prepass_iterations += pre_summary.iterations;
    prepass_evaluations += pre_summary.evaluations;
    prepass_time_s += pre_summary.time_s;
    arena.execute([&] { EpsilonSquaredOn(smoothed, rule.gate, topology, &gate_summary); });
  }
  if (!curved) curved = gate_summary.median_epsilon_squared >= rule.min_gate_median_epsilon_squared;
  std::vector<double> epsilon_squared;
  AdaptiveEpsilonSummary s = gate_summary;
  s.per_face = curved;
  if (s.per_face) {
    // The global ε² (the user's --eps2) stays the floor, so a flat face is treated as without the rule.
    AdaptiveEpsilonOptions detail = rule.detail;
    detail.min_epsilon_squared = options.sqrt_epsilon_squared;
    detail.max_epsilon_squared = std::max(detail.max_epsilon_squared, detail.min_epsilon_squared);
    detail.Check();
    arena.execute([&] { epsilon_squared = EpsilonSquaredOn(smoothed, detail, topology, &s); });
    s.per_face = true;
  }
  s.gate_median_epsilon_squared = gate_summary.median_epsilon_squared;
  s.prepass_iterations = prepass_iterations;
  s.prepass_evaluations = prepass_evaluations;
  s.prepass_time_s = prepass_time_s;
  s.time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (summary != nullptr) *summary = s;
  if (prepass_result != nullptr) *prepass_result = std::move(smoothed);
  return epsilon_squared;
}

Mesh SmoothAdaptiveEpsilon(const NoisyMesh& noisy, const SmoothOptions& options, const AutoAdaptiveEpsilonOptions& rule,
                           AdaptiveEpsilonSummary* summary, SmoothSummary* smooth_summary) {
  Mesh prepass;
  SmoothOptions final_options = options;
  final_options.initial_positions = nullptr;
  final_options.adaptive_epsilon = false;
  final_options.face_epsilon_squared = AdaptiveEpsilonAuto(noisy, options, rule, summary, &prepass);
  const bool curved = !final_options.face_epsilon_squared.empty();
  if (curved && rule.final_from_prepass) final_options.initial_positions = &prepass.V;
  return Smooth(noisy, final_options, smooth_summary);
}

}  // namespace rangebayes
