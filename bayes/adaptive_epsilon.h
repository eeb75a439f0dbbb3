// Per-face ε² for the square-root prior φ(d) = sqrt(d² + ε²) (docs/design.md §4, last paragraph): one global ε cannot
// serve both sharp CAD shapes (small ε keeps creases) and smooth, finely detailed scans (a larger ε makes φ
// quadratic for the normal differences that gentle curvature produces, so it is not flattened into facets).
//
//   std::vector<double> e2 = AdaptiveEpsilonSquared(reference, {}, &summary);
//   SmoothOptions options;  options.face_epsilon_squared = e2;   // a pair uses sqrt(d² + ½(ε_s² + ε_t²))
//
// The rule reads the local shape of a reference mesh with the faces of the mesh to smooth (the ground truth in
// an oracle experiment, or the noisy input after a fast default pre-pass):
//   0. optionally (normal_smoothing_rings > 0) the face normals are first averaged, area weighted, over the faces
//      sharing a vertex, that many times (crease protection still reads the raw normals);
//   1. per face t, a_t = the mean of d = ‖n_t − n_s‖ over its edge neighbours s;
//   2. m_t = a_t filtered `ring_iterations` times over the faces that share a vertex with t: the mean of the
//      values ≤ truncate_normal_difference (a crease line is a minority of any neighbourhood and is left out, so
//      m stays near 0 beside it; a curved region keeps its typical d);
//   3. ε_t² = clamp(scale · max(0, m_t² − floor_normal_difference²), min, max), and the minimum on and
//      protect_rings around crease pairs (d > protect_normal_difference) when protection is on.
// Cost: O(#F · ring_iterations · 13 log 13), ≈ 10–50 ms at 100k faces, plus the pre-pass when there is one.
//
// What `rangebayes smooth` uses (its default for the square-root prior): SmoothAdaptiveEpsilon below — a fast
// pre-pass of 40–80 iterations, a gate that tells a curved mesh from a piecewise-flat one, on curved meshes the
// detail rule (the pre-pass's normals averaged over 4 rings before d is read) and a final solve started from the
// pre-pass. Measured (BENCHMARKS.md "Adaptive ε"): every issue target met with the true noise
// level (igea 0.3 9.89°, child 0.3 6.84°, CAD cases identical to the global ε²), within 10% with the level
// estimated; on child 166 evaluations in all against 276 for the global ε² alone. The library's Smooth() and the
// pipeline keep the global ε² (the live path has a time budget).
//
// The rules measured and rejected on the way (a median statistic made for a clean reference, a second pass,
// crease protection read from another mesh) are in docs/journal/adaptive-epsilon.md.
#pragma once

#include <vector>

#include "bayes/smooth.h"
#include "core/mesh.h"

namespace rangebayes {

// The defaults are the scan rule (ScanAdaptiveEpsilonOptions, the gate of AdaptiveEpsilonAuto).
struct AdaptiveEpsilonOptions {
  // Area-weighted averaging passes of the reference's face normals over the faces sharing a vertex before d is
  // read, [0, 50]; 0: the raw normals. Crease protection always reads the raw normals.
  int normal_smoothing_rings = 0;
  int ring_iterations = 3;                  // vertex-ring passes, [0, 20]; 3 ≈ a three-ring neighbourhood
  double scale = 8.0;                       // c in ε² = c · m², [0, 1e4]
  double truncate_normal_difference = 0.3;  // ring values above it are left out, (0, 2]
  // Faces within protect_rings vertex rings of a pair with d > protect_normal_difference get the minimum ε²
  // (a crease of the reference keeps the paper's sharp prior). protect_rings = -1: off. d in (0, 2], rings
  // [-1, 10].
  double protect_normal_difference = 0.7;
  int protect_rings = 1;
  // Only crease edges whose two end vertices each touch at least this many crease edges protect (2: parts of
  // crease lines; isolated sharp pairs, as a detailed scan's pre-pass has many, do not). 0: every crease pair.
  // [0, 10].
  int protect_min_crease_degree = 2;
  double floor_normal_difference = 0.0;  // d₀ subtracted in quadrature (a noise floor of the reference), [0, 2]
  double min_epsilon_squared = 1e-4;     // lower clamp, (0, 4]; 1e-4 is the paper's global value
  double max_epsilon_squared = 0.2;      // upper clamp, [min_epsilon_squared, 4]
  void Check() const;
};

// AdaptiveEpsilonSummary is declared in bayes/smooth.h (SmoothSummary carries one).

// One ε² per face of `reference` (#F values in [min, max]). Faces without a normal (zero area, repeated
// index) and faces without edge neighbours get min_epsilon_squared and are skipped as neighbours. Throws
// Error on bad face indices or options.
std::vector<double> AdaptiveEpsilonSquared(const Mesh& reference, const AdaptiveEpsilonOptions& options = {},
                                           AdaptiveEpsilonSummary* summary = nullptr);

// The scan rule, AdaptiveEpsilonOptions{} (the gate of AdaptiveEpsilonAuto): truncated mean (≤ 0.3), scale 8,
// three rings, crease lines of d > 0.7 protected with one ring. Chosen on the
// whole benchmark table, not per mesh (BENCHMARKS.md "Adaptive ε"). Alone: child 0.3 7.44°, igea 0.3 10.22°,
// fandisk 0.3 2.31°, but block 0.4 4.05° and trim-star 0.3 5.49° miss their targets.
AdaptiveEpsilonOptions ScanAdaptiveEpsilonOptions();

// ε² per face of `noisy` from a pre-pass: Smooth(noisy, options) with the fast tolerance and the global ε²
// (options.face_epsilon_squared ignored), then AdaptiveEpsilonSquared on its result. Costs one fast smoothing
// run (≈ 0.5–1× the main run). `options` must use the square-root prior (Error otherwise).
std::vector<double> AdaptiveEpsilonFromPrepass(const NoisyMesh& noisy, const SmoothOptions& options,
                                               const AdaptiveEpsilonOptions& rule,
                                               AdaptiveEpsilonSummary* summary = nullptr);

// The detail rule of AdaptiveEpsilonAuto: the pre-pass's face normals averaged over 4 vertex rings (area
// weighted), per face the mean of d over its edge neighbours, no ring filter, scale 24, ε² in [1e-4, 1], no
// crease protection. Why: the default pre-pass turns a gently curved surface into facets and small creases, but
// the total turning survives, so the averaged normal field's d is the curvature at the face scale (igea 0.3:
// 9.92° with it against 10.90° with the global ε²); the median of raw d (the ground-truth rule) reads ≈ 0 there.
// It blurs CAD creases into bands (fandisk 0.3: 6.1°), hence the gate.
AdaptiveEpsilonOptions DetailAdaptiveEpsilonOptions();

struct AutoAdaptiveEpsilonOptions {
  AdaptiveEpsilonOptions gate = ScanAdaptiveEpsilonOptions();      // read for its median ε² only
  AdaptiveEpsilonOptions detail = DetailAdaptiveEpsilonOptions();  // the per-face ε² of a curved mesh
  // Per-face ε² only when the gate rule's median ε² on the pre-pass is at least this, (0, 4]. Measured on the
  // benchmark meshes (BENCHMARKS.md "Adaptive ε"): CAD shapes 1.4e-4–1.0e-3, scans 9.7e-3–1.8e-2, noise level
  // given or estimated; 3e-3 sits between them (a factor ≥ 3 from each side).
  double min_gate_median_epsilon_squared = 3e-3;
  // Iteration cap of the pre-pass (fast tolerance); 0: the preset's (300). [0, 1e7]. 80:
  // the gate only needs the noise creases of a CAD shape gone, not a converged pre-pass. Its median ε² falls fast
  // on CAD shapes while they resolve (fandisk 0.7: 9.7e-3 / 5.3e-3 / 7.9e-4 / 1.2e-4 at 30 / 40 / 80 / 227
  // iterations) and slowly on scans (child: 1.6e-2 / 1.3e-2 / 1.06e-2 / 9.7e-3 at 30 / 40 / 80 / 131); at 80
  // every benchmark CAD case is ≤ 1.1e-3 and every scan ≥ 1.06e-2 (noise level given or estimated), ≥ 2.8× from
  // the threshold on either side. At 40 alone CAD reached 5.9e-3 and at 20 2.2e-2: too early for the threshold.
  int prepass_max_iterations = 80;
  // Early decision: the gate is first read after this many pre-pass iterations, [0, prepass_max_iterations] (0:
  // not), and a median ε² ≥ early_curved_gate_median_epsilon_squared there ends the pre-pass as curved (the
  // detail rule reads a 40-iteration pre-pass as well as a converged one). Below it the pre-pass continues (from
  // where it stopped) to prepass_max_iterations and the threshold above decides. 1.2e-2 = 4× the threshold: at 40
  // iterations the benchmark CAD cases are ≤ 5.9e-3 (2× below), the scans 1.34e-2–2.9e-2 (a scan below it only
  // pays the longer pre-pass; the decision is then the 80-iteration one).
  int prepass_early_iterations = 40;
  double early_curved_gate_median_epsilon_squared = 1.2e-2;  // (0, 4]
  // SmoothAdaptiveEpsilon on a curved mesh: start the final solve from the pre-pass result instead of the
  // measurements (child 0.3: 53 instead of 82 iterations after a 40-iteration pre-pass, MAE within 0.05°). A
  // piecewise-flat mesh always gets the plain default solve (from the measurements: the same bytes as without
  // the rule).
  bool final_from_prepass = true;
  void Check() const;
};

// The ε² part of what `rangebayes smooth` uses for the square-root prior (its default; --no-adaptive-eps turns
// it off; the command calls SmoothAdaptiveEpsilon below): a fast pre-pass Smooth(noisy, options with the fast
// tolerance, the global ε² and at most rule.prepass_max_iterations iterations), then two O(#F) rules on its
// result. The gate rule (ScanAdaptiveEpsilonOptions) tells a piecewise-flat shape from a curved one: on a
// smoothed CAD shape nearly every face is flat (median ε² ≈ the minimum), on a smoothed scan the faces are
// small facets of a curved surface. Piecewise flat: returns an empty vector (keep the global ε², the paper's
// sharp prior: CAD results are those of the default); curved: the detail rule's ε² (#F values in [min(the
// global ε², 1), 1]). The pre-pass stops early as curved (see AutoAdaptiveEpsilonOptions); cost: 40–80 fast
// iterations plus two O(#F) rules (child: 72 evaluations, rules ≈ 0.1 s). `prepass_result` (optional) receives
// the pre-pass mesh. `options` must use the square-root prior (Error otherwise); options.face_epsilon_squared is
// ignored.
std::vector<double> AdaptiveEpsilonAuto(const NoisyMesh& noisy, const SmoothOptions& options,
                                        const AutoAdaptiveEpsilonOptions& rule = {},
                                        AdaptiveEpsilonSummary* summary = nullptr, Mesh* prepass_result = nullptr);

// The whole default of `rangebayes smooth` for the square-root prior: AdaptiveEpsilonAuto, then Smooth(noisy,
// options with its ε²) started from the pre-pass result when rule.final_from_prepass (same energy and minimum as
// a start from the measurements; fewer iterations). `smooth_summary` is the final solve's. options.
// face_epsilon_squared and options.initial_positions are ignored.
Mesh SmoothAdaptiveEpsilon(const NoisyMesh& noisy, const SmoothOptions& options,
                           const AutoAdaptiveEpsilonOptions& rule = {}, AdaptiveEpsilonSummary* summary = nullptr,
                           SmoothSummary* smooth_summary = nullptr);

}  // namespace rangebayes
