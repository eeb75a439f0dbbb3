// Synthetic right-angled training data for learned priors (paper §5, Fig. 6): clean closed meshes of boxes,
// stairs, L-shapes and slotted blocks, and noisy copies of them.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/mesh.h"

namespace rangebayes {

enum class RightAngledShape { kBox, kStairs, kLShape, kSlottedBlock };
std::string RightAngledShapeName(RightAngledShape shape);

enum class SynthNoise {
  kNormal,   // Gaussian along the (area-weighted) vertex normals, σ = k·l_e; no covariance stored
  kScanner,  // ray-aligned: σ_ray = k·l_e along the ray from a virtual camera, σ_ray/10 across; covariance stored
};
std::string SynthNoiseName(SynthNoise noise);

struct RightAngledObjectOptions {
  RightAngledShape shape = RightAngledShape::kBox;
  double edge_length = 1.0;     // side of the grid squares the faces are cut into, model units; (0, 1e6]
  int min_cells = 6;            // smallest overall extent in grid cells; [4, 200]
  int max_cells = 14;           // largest overall extent in grid cells; [min_cells, 200]
  double jitter = 0.2;          // in-plane vertex jitter, fraction of edge_length, so the triangulation is
                                // irregular while the surface stays exact; [0, 0.25]
  bool random_rotation = true;  // rotate the object uniformly at random
  void Check() const;
};

// A closed 2-manifold triangle mesh of the shape with random dimensions drawn from `seed`, triangulated by
// squares of side edge_length cut into two triangles (diagonals alternating), counter-clockwise outside.
Mesh MakeRightAngledObject(const RightAngledObjectOptions& options, std::uint64_t seed);

struct SynthNoiseOptions {
  SynthNoise kind = SynthNoise::kNormal;
  double k = 0.3;  // noise σ in units of the clean mesh's mean edge length l_e; (0, 5]
  void Check() const;
};

// A noisy copy of `clean` (same vertex order and faces), deterministic for `seed`.
NoisyMesh AddSynthNoise(const Mesh& clean, const SynthNoiseOptions& options, std::uint64_t seed);

struct SynthMeshSetOptions {
  std::uint64_t seed = 1;
  int num_train = 8;  // training objects; [0, 10000]
  int num_test = 4;   // held-out objects (never among the training objects); [0, 10000]; not all three counts 0
  // Validation objects, for choosing hyper-parameters: drawn after the training and held-out objects (so those
  // stay the same draws whatever this is) and equal to none of them. [0, 10000]
  int num_validation = 0;
  int copies = 1;  // noisy copies per object; [1, 100]
  SynthNoiseOptions noise;
  // A mixture of noise levels when above noise.k: the noisy copies' k are spread evenly over
  // [noise.k, noise_k_max] (a low-discrepancy sequence over the pairs in order, so that any prefix of the set
  // covers the range) and every noisy mesh carries the covariance of its own level (the generic isotropic
  // σ²·I for normal noise, σ = k·l_e of the noisy mesh as `rangebayes smooth --noise k` would use).
  // 0 or ≤ noise.k: every copy at noise.k. [0, 5]
  double noise_k_max = 0;
  RightAngledObjectOptions object;  // shape is cycled over all four kinds
  void Check() const;
};

struct SynthPair {
  std::string name;  // "train_03_stairs_c0"
  double k = 0;      // the noise level of this copy (σ / l_e)
  Mesh clean;
  NoisyMesh noisy;
};

struct SynthMeshSet {
  std::vector<SynthPair> train;
  std::vector<SynthPair> test;
  std::vector<SynthPair> validation;
};

// Objects are drawn from independent per-object seeds; train, test and validation objects are distinct draws, so
// the three sets share no object.
SynthMeshSet MakeSynthMeshSet(const SynthMeshSetOptions& options);

}  // namespace rangebayes
