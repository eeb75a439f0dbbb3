// The generic noise model for meshes that did not come from our cameras (docs/design.md §3.2): per vertex a
// covariance with standard deviation σ along the mean of the adjacent face normals and σ / across_ratio across
// it, σ = k · l_e (l_e the mean edge length) given as k, as σ in model units, or estimated from the mesh.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "core/mesh.h"

namespace rangebayes {

struct GenericNoiseOptions {
  // k: σ as a multiple of the mean edge length, (0, 10]. Not given: use sigma, or estimate k from the mesh.
  std::optional<double> noise_edge_multiple = std::nullopt;
  // σ in model units, > 0. Takes precedence over noise_edge_multiple.
  std::optional<double> sigma = std::nullopt;
  // σ_normal / σ_tangent, [1, 100]. Scanner noise is mostly along the surface normal, but the normal of a
  // noisy mesh is itself uncertain: measured on the benchmark meshes (noise along the true normals), ratio 2
  // was worse than 1 everywhere (fandisk 0.3: 2.38 vs 2.30°, block 0.4: 4.36 vs 4.10°), so the default is
  // isotropic. Stereo meshes bring their own ray-aligned covariances instead.
  double across_ratio = 1.0;
  void Check() const;
};

// What EstimateNoiseLevel read from the mesh.
struct NoiseEstimateDetails {
  double one_ring = 0;           // the one-ring residual scale (÷ l_e): the estimate for white Gaussian noise
  double growth = 0;             // the two-ring residual over the one-ring's (0: no one-ring residual)
  double tail = 0;               // NoiseResidualTailRatio
  bool raised_to_floor = false;  // heavy-tailed residuals: the real-sensor floor set the estimate
};

struct GenericNoiseSummary {
  double mean_edge_length = 0;       // l_e, model units
  double noise_edge_multiple = 0;    // k used
  double sigma = 0;                  // σ along the normal, model units
  bool estimated = false;            // k came from EstimateNoiseLevel
  NoiseEstimateDetails estimate;     // when estimated
  double across_ratio = 1.0;         // the options' across_ratio (σ across the normal is σ / across_ratio)
};

// Estimate of k = σ / l_e (l_e of this, noisy, mesh), the level smoothing should assume: per vertex, the
// distance of the vertex from the plane through its one-ring centroid whose normal is the least-squares normal
// of its two-ring; a robust scale (median absolute value) of those distances, times a constant calibrated on
// two meshes with known Gaussian noise (see BENCHMARKS.md). When the same residual at ring size 2 rises by more
// than white noise gives (spatially correlated noise, as real scanners have), the estimate is raised by a power
// of that rise (NoiseResidualProfile). When the residuals are heavy-tailed, as a real sensor's are
// (NoiseResidualTailRatio above 4.5, Gaussian noise gives 3.8), the estimate is at least 0.4. Rule and constants:
// BENCHMARKS.md "Real sensor noise". In [0, 10]; 0 for a mesh without vertices of valence ≥ 3. `details`, when
// given, receives what the estimate was made from.
double EstimateNoiseLevel(const Mesh& mesh, NoiseEstimateDetails* details = nullptr);

// The same robust residual scale (÷ l_e, with the same constants) for ring sizes r = 1 … max_ring: the distance
// of each vertex from the plane through its r-disc's centroid (vertices 1 … r edges away) whose normal is the
// least-squares normal of its (r+1)-disc. Element r−1 is ring r; element 0 is the one-ring estimate above.
// White noise gives a flat profile, spatially correlated noise (and curvature) a rising one. max_ring in [1, 16].
std::vector<double> NoiseResidualProfile(const Mesh& mesh, int max_ring);

// The one-ring residuals' 99th percentile over their median: about 3.8 for Gaussian noise, more for heavy-tailed
// noise (a real sensor's mismatches) and for a noise-free surface's curvature. 0 with fewer than 1000 residuals
// or a zero median.
double NoiseResidualTailRatio(const Mesh& mesh);

// The mesh with the generic covariance per vertex (isolated vertices get the isotropic σ²·I).
NoisyMesh MakeGenericNoisyMesh(const Mesh& mesh, const GenericNoiseOptions& options = {},
                               GenericNoiseSummary* summary = nullptr);

// Which noise model smoothing uses for a mesh as read from a file (what `rangebayes smooth` does).
enum class CovarianceSource {
  kAuto,     // the file's covariances when it has them and no noise level is given, else the generic model
  kGeneric,  // always the generic model (the file's covariances, if any, are replaced)
};

struct NoiseModelChoice {
  bool from_file = false;          // the input's own covariances were kept
  bool replaced_file = false;      // the input had covariances and they were replaced by the generic model
  GenericNoiseSummary generic;     // when !from_file

  // One line: where the covariances came from; for the generic model k, l_e, σ, whether k was estimated.
  std::string BriefReport() const;
};

// The NoisyMesh to smooth: `input` itself when it has covariances, source is kAuto and neither
// options.noise_edge_multiple nor options.sigma is given; else MakeGenericNoisyMesh(input.mesh, options).
NoisyMesh ChooseNoiseModel(const NoisyMesh& input, const GenericNoiseOptions& options = {},
                           CovarianceSource source = CovarianceSource::kAuto, NoiseModelChoice* choice = nullptr);

}  // namespace rangebayes
