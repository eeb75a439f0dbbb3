// Per-face ε² for the square-root prior φ(d) = sqrt(d² + ε²) (DESIGN §4, last paragraph): one global ε cannot
// serve both sharp CAD shapes (small ε keeps creases) and smooth, finely detailed scans (a larger ε makes φ
// quadratic for the normal differences that gentle curvature produces, so it is not flattened into facets).
//
//   std::vector<double> e2 = AdaptiveEpsilonSquared(reference, {}, &summary);
//   SmoothOptions options;  options.face_epsilon_squared = e2;   // a pair uses sqrt(d² + ½(ε_s² + ε_t²))
//
// The rule reads the local shape of a reference mesh with the faces of the mesh to smooth (the ground truth in
// an oracle experiment, or a pre-smoothed copy of the noisy input):
//   1. per face t, a_t = the median of d = ‖n_t − n_s‖ over its edge neighbours s (at a crease one of the three
//      is large and the median ignores it; in a curved region all three are similar);
//   2. m_t = a_t median-filtered `ring_iterations` times over the faces that share a vertex with t (a crease
//      line is a minority of any neighbourhood, so m stays near 0 beside it; a curved region keeps its
//      typical d);
//   3. ε_t² = clamp(scale · max(0, m_t² − floor_normal_difference²), min, max).
// Cost: O(#F · ring_iterations · 13 log 13), a few tens of ms at 100k faces.
//
// Measured (BENCHMARKS.md "Adaptive ε"): with the ground truth as reference (an upper bound of what any
// per-face ε can do) igea 0.3 reaches 9.72° and child 0.3 6.76° while the CAD cases keep their numbers; with a
// pre-smoothed noisy input as reference the gain mostly vanishes (the pre-pass has already flattened the
// detail this rule would need to see), so Smooth() does not use this rule by default.
#pragma once

#include <vector>

#include "bayes/smooth.h"
#include "core/mesh.h"

namespace rangebayes {

// How a face's typical normal difference m_t is gathered (see the rule above).
enum class AdaptiveEpsilonStatistic {
  kMedian,         // median over the edge neighbours, then vertex-ring medians (made for a clean reference)
  kTruncatedMean,  // mean over the edge neighbours, then vertex-ring means of the values ≤ truncate (creases
                   // left out); sees the small, scattered creases a pre-smoothed curved surface is made of
};

struct AdaptiveEpsilonOptions {
  AdaptiveEpsilonStatistic statistic = AdaptiveEpsilonStatistic::kMedian;
  int ring_iterations = 3;               // vertex-ring passes, [0, 20]; 3 ≈ a three-ring neighbourhood
  double scale = 4.0;                    // c in ε² = c · m², [0, 1e4]; 4 measured best with the ground truth
  double truncate_normal_difference = 0.3;  // kTruncatedMean: ring values above it are left out, (0, 2]
  // Faces within protect_rings vertex rings of a pair with d > protect_normal_difference get the minimum ε²
  // (a crease of the reference keeps the paper's sharp prior). protect_rings = -1: off. d in (0, 2], rings
  // [-1, 10].
  double protect_normal_difference = 0.5;
  int protect_rings = -1;
  // Only crease edges whose two end vertices each touch at least this many crease edges protect (2: parts of
  // crease lines; isolated sharp pairs, as a detailed scan's pre-pass has many, do not). 0: every crease pair.
  // [0, 10].
  int protect_min_crease_degree = 0;
  double floor_normal_difference = 0.0;  // d₀ subtracted in quadrature (a noise floor of the reference), [0, 2]
  double min_epsilon_squared = 1e-4;     // lower clamp, (0, 4]; 1e-4 is the paper's global value
  double max_epsilon_squared = 0.2;      // upper clamp, [min_epsilon_squared, 4]
  void Check() const;
};

struct AdaptiveEpsilonSummary {
  double median_epsilon_squared = 0;  // over faces
  double p10_epsilon_squared = 0;
  double p90_epsilon_squared = 0;
  int faces_at_minimum = 0;           // faces clamped to min_epsilon_squared (flat or beside a crease)
  double time_s = 0;                 // the whole call (with the pre-pass for AdaptiveEpsilonFromPrepass)
};

// One ε² per face of `reference` (#F values in [min, max]). Faces without a normal (zero area, repeated
// index) and faces without edge neighbours get min_epsilon_squared and are skipped as neighbours. Throws
// Error on bad face indices or options.
std::vector<double> AdaptiveEpsilonSquared(const Mesh& reference, const AdaptiveEpsilonOptions& options = {},
                                           AdaptiveEpsilonSummary* summary = nullptr);

// The rule for smooth, finely detailed scans (opt-in: `rangebayes smooth --adaptive-eps`): truncated mean,
// scale 8, three rings, no crease protection. Measured with a pre-pass reference (BENCHMARKS.md "Adaptive ε"):
// child 0.3 8.38 → 7.38°, igea 0.3 → 10.15°, but sharp CAD shapes get worse (fandisk 0.3 2.10 → 2.67°), so it is
// not the default.
AdaptiveEpsilonOptions ScanAdaptiveEpsilonOptions();

// ε² per face of `noisy` from a pre-pass: Smooth(noisy, options) with the fast tolerance and the global ε²
// (options.face_epsilon_squared ignored), then AdaptiveEpsilonSquared on its result. Costs one fast smoothing
// run (≈ 0.5–1× the main run). `options` must use the square-root prior (Error otherwise).
std::vector<double> AdaptiveEpsilonFromPrepass(const NoisyMesh& noisy, const SmoothOptions& options,
                                               const AdaptiveEpsilonOptions& rule,
                                               AdaptiveEpsilonSummary* summary = nullptr);

}  // namespace rangebayes
