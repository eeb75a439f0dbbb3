#include "bayes/learning/synth_meshes.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <set>
#include <unordered_map>

#include "bayes/noise_model.h"
#include "core/error.h"
#include "core/topology.h"

namespace rangebayes {
namespace {

// splitmix64 + Box–Muller: the same numbers on every platform (std distributions differ between libraries).
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(seed) {}
  std::uint64_t Next() {
    std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  double Uniform() { return (Next() >> 11) * (1.0 / 9007199254740992.0); }  // [0, 1)
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  int Int(int lo, int hi) { return lo + static_cast<int>(Next() % static_cast<std::uint64_t>(hi - lo + 1)); }
  double Gaussian() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u1 = Uniform();
    while (u1 <= 0.0) u1 = Uniform();
    const double u2 = Uniform();
    const double r = std::sqrt(-2.0 * std::log(u1));
    spare_ = r * std::sin(2.0 * M_PI * u2);
    has_spare_ = true;
    return r * std::cos(2.0 * M_PI * u2);
  }

 private:
  std::uint64_t state_;
  bool has_spare_ = false;
  double spare_ = 0.0;
};

std::uint64_t MixSeed(std::uint64_t seed, std::uint64_t index) {
  Rng rng(seed * 0x100000001b3ULL + index * 0x9e3779b97f4a7c15ULL + 0x5851f42d4c957f2dULL);
  rng.Next();
  return rng.Next();
}

struct VoxelShape {
  std::array<int, 3> size{};
  std::function<bool(int, int, int)> inside;
  std::vector<int> signature;  // shape kind and its dimensions: equal signatures = the same object
};

VoxelShape DrawShape(const RightAngledObjectOptions& options, Rng& rng) {
  const int lo = options.min_cells;
  const int hi = options.max_cells;
  VoxelShape s;
  switch (options.shape) {
    case RightAngledShape::kBox: {
      const int a = rng.Int(lo, hi), b = rng.Int(lo, hi), c = rng.Int(lo, hi);
      s.size = {a, b, c};
      s.inside = [](int, int, int) { return true; };
      s.signature = {0, a, b, c};
      break;
    }
    case RightAngledShape::kStairs: {
      const int steps = rng.Int(2, 3);
      const int depth = std::max(2, rng.Int(lo, hi) / steps);
      const int height = std::max(2, rng.Int(lo, hi) / steps);
      const int width = rng.Int(lo, hi);
      s.size = {steps * depth, width, steps * height};
      s.inside = [=](int x, int, int z) { return z < height * (steps - x / depth); };
      s.signature = {1, steps, depth, height, width};
      break;
    }
    case RightAngledShape::kLShape: {
      const int x_size = rng.Int(lo, hi), y_size = rng.Int(lo, hi), z_size = rng.Int(lo, hi);
      const int tx = rng.Int(2, std::max(2, x_size / 2));
      const int tz = rng.Int(2, std::max(2, z_size / 2));
      s.size = {x_size, y_size, z_size};
      s.inside = [=](int x, int, int z) { return z < tz || x < tx; };
      s.signature = {2, x_size, y_size, z_size, tx, tz};
      break;
    }
    case RightAngledShape::kSlottedBlock: {
      const int x_size = rng.Int(std::max(lo, 6), std::max(hi, 6));
      const int y_size = rng.Int(lo, hi);
      const int z_size = rng.Int(std::max(lo, 4), std::max(hi, 4));
      const int width = rng.Int(2, std::max(2, x_size / 3));
      const int depth = rng.Int(2, z_size - 2);
      const int x0 = (x_size - width) / 2 + rng.Int(-1, 1);
      s.size = {x_size, y_size, z_size};
      s.inside = [=](int x, int, int z) { return !(x >= x0 && x < x0 + width && z >= z_size - depth); };
      s.signature = {3, x_size, y_size, z_size, width, depth, x0};
      break;
    }
  }
  return s;
}

// Boundary of the voxel set as unit squares cut into triangles; vertex positions on the integer grid.
Mesh Surface(const VoxelShape& shape, std::vector<std::array<int, 3>>* face_normal_code) {
  const auto& n = shape.size;
  auto in = [&](int x, int y, int z) {
    if (x < 0 || y < 0 || z < 0 || x >= n[0] || y >= n[1] || z >= n[2]) return false;
    return shape.inside(x, y, z);
  };
  std::unordered_map<std::int64_t, int> index;
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> faces;
  auto vertex = [&](const std::array<int, 3>& p) {
    const std::int64_t key = (static_cast<std::int64_t>(p[0]) * 4096 + p[1]) * 4096 + p[2];
    auto [it, inserted] = index.emplace(key, static_cast<int>(vertices.size()));
    if (inserted) vertices.emplace_back(p[0], p[1], p[2]);
    return it->second;
  };
  for (int x = 0; x < n[0]; ++x) {
    for (int y = 0; y < n[1]; ++y) {
      for (int z = 0; z < n[2]; ++z) {
        if (!in(x, y, z)) continue;
        const std::array<int, 3> cell{x, y, z};
        for (int axis = 0; axis < 3; ++axis) {
          for (int sign : {-1, 1}) {
            std::array<int, 3> next = cell;
            next[axis] += sign;
            if (in(next[0], next[1], next[2])) continue;
            const int u = (axis + 1) % 3;
            const int v = (axis + 2) % 3;
            std::array<int, 4> corner{};
            const int offsets[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
            for (int c = 0; c < 4; ++c) {
              std::array<int, 3> p = cell;
              if (sign > 0) p[axis] += 1;
              p[u] += offsets[c][0];
              p[v] += offsets[c][1];
              corner[c] = vertex(p);
            }
            // e_u × e_v = e_axis, so this order faces +axis; reverse it for −axis.
            if (sign < 0) std::swap(corner[1], corner[3]);
            const int code = 2 * axis + (sign > 0 ? 1 : 0);
            if ((x + y + z) % 2 == 0) {
              faces.emplace_back(corner[0], corner[1], corner[2]);
              faces.emplace_back(corner[0], corner[2], corner[3]);
            } else {
              faces.emplace_back(corner[0], corner[1], corner[3]);
              faces.emplace_back(corner[1], corner[2], corner[3]);
            }
            face_normal_code->push_back({code, 0, 0});
            face_normal_code->push_back({code, 0, 0});
          }
        }
      }
    }
  }
  Mesh mesh;
  mesh.V.resize(static_cast<int>(vertices.size()), 3);
  for (size_t i = 0; i < vertices.size(); ++i) mesh.V.row(static_cast<int>(i)) = vertices[i].transpose();
  mesh.F.resize(static_cast<int>(faces.size()), 3);
  for (size_t f = 0; f < faces.size(); ++f) mesh.F.row(static_cast<int>(f)) = faces[f].transpose();
  return mesh;
}

// Moves vertices within their plane (or along their edge line) so the triangulation is irregular but the
// surface is unchanged; corners stay.
void Jitter(Mesh* mesh, const std::vector<std::array<int, 3>>& face_code, double amount, Rng& rng) {
  const int nv = mesh->num_vertices();
  std::vector<int> axis_mask(nv, 0);
  std::vector<std::set<int>> codes(nv);
  for (int f = 0; f < mesh->num_faces(); ++f) {
    for (int k = 0; k < 3; ++k) codes[mesh->F(f, k)].insert(face_code[f][0]);
  }
  for (int i = 0; i < nv; ++i) {
    int normal_axes = 0;
    for (int code : codes[i]) normal_axes |= 1 << (code / 2);
    const double dx = rng.Uniform(-amount, amount);
    const double dy = rng.Uniform(-amount, amount);
    const double dz = rng.Uniform(-amount, amount);
    if (codes[i].size() >= 3) continue;
    const double delta[3] = {dx, dy, dz};
    for (int a = 0; a < 3; ++a) {
      if ((normal_axes & (1 << a)) == 0) mesh->V(i, a) += delta[a];
    }
  }
}

Eigen::Matrix3d RandomRotation(Rng& rng) {
  Eigen::Quaterniond q(rng.Gaussian(), rng.Gaussian(), rng.Gaussian(), rng.Gaussian());
  q.normalize();
  return q.toRotationMatrix();
}

Mesh BuildObject(const RightAngledObjectOptions& options, std::uint64_t seed, std::vector<int>* signature) {
  options.Check();
  Rng rng(seed);
  const VoxelShape shape = DrawShape(options, rng);
  if (signature != nullptr) *signature = shape.signature;
  std::vector<std::array<int, 3>> codes;
  Mesh mesh = Surface(shape, &codes);
  Jitter(&mesh, codes, options.jitter, rng);
  const Eigen::RowVector3d centre = mesh.V.colwise().mean();
  mesh.V.rowwise() -= centre;
  mesh.V *= options.edge_length;
  if (options.random_rotation) {
    const Eigen::Matrix3d r = RandomRotation(rng);
    mesh.V = (mesh.V * r.transpose()).eval();
  }
  return mesh;
}

}  // namespace

std::string RightAngledShapeName(RightAngledShape shape) {
  switch (shape) {
    case RightAngledShape::kBox:
      return "box";
    case RightAngledShape::kStairs:
      return "stairs";
    case RightAngledShape::kLShape:
      return "lshape";
    case RightAngledShape::kSlottedBlock:
      return "slotted";
  }
  return "?";
}

std::string SynthNoiseName(SynthNoise noise) { return noise == SynthNoise::kNormal ? "normal" : "scanner"; }

void RightAngledObjectOptions::Check() const {
  RB_CHECK(edge_length > 0 && edge_length <= 1e6, "synth meshes: edge_length must be in (0, 1e6], got ", edge_length);
  RB_CHECK(min_cells >= 4 && min_cells <= 200, "synth meshes: min_cells must be in [4, 200], got ", min_cells);
  RB_CHECK(max_cells >= min_cells && max_cells <= 200, "synth meshes: max_cells must be in [min_cells, 200], got ",
           max_cells);
  RB_CHECK(jitter >= 0 && jitter <= 0.25, "synth meshes: jitter must be in [0, 0.25], got ", jitter);
}

void SynthNoiseOptions::Check() const {
  // Noise-free pairs teach nothing, and a training set of them was refused later by learn-prior.
  RB_CHECK(k > 0 && k <= 5, "synth meshes: noise k must be in (0, 5], got ", k);
}

void SynthMeshSetOptions::Check() const {
  RB_CHECK(num_train >= 0 && num_train <= 10000, "synth meshes: num_train must be in [0, 10000], got ", num_train);
  RB_CHECK(num_test >= 0 && num_test <= 10000, "synth meshes: num_test must be in [0, 10000], got ", num_test);
  RB_CHECK(num_validation >= 0 && num_validation <= 10000, "synth meshes: num_validation must be in [0, 10000], got ",
           num_validation);
  RB_CHECK(copies >= 1 && copies <= 100, "synth meshes: copies must be in [1, 100], got ", copies);
  RB_CHECK(num_train + num_test + num_validation > 0,
           "synth meshes: nothing to make: num_train, num_test and num_validation are all 0");
  noise.Check();
  object.Check();
  RB_CHECK(noise_k_max >= 0 && noise_k_max <= 5, "synth meshes: noise_k_max must be in [0, 5], got ", noise_k_max);
}

Mesh MakeRightAngledObject(const RightAngledObjectOptions& options, std::uint64_t seed) {
  return BuildObject(options, seed, nullptr);
}

NoisyMesh AddSynthNoise(const Mesh& clean, const SynthNoiseOptions& options, std::uint64_t seed) {
  options.Check();
  Rng rng(seed);
  const double sigma = options.k * MeanEdgeLength(clean);
  NoisyMesh noisy;
  noisy.mesh.V = clean.V;
  noisy.mesh.F = clean.F;
  const int nv = clean.num_vertices();
  if (options.kind == SynthNoise::kNormal) {
    Vertices normals = Vertices::Zero(nv, 3);
    for (int f = 0; f < clean.num_faces(); ++f) {
      const Eigen::Vector3d a = clean.V.row(clean.F(f, 0));
      const Eigen::Vector3d b = clean.V.row(clean.F(f, 1));
      const Eigen::Vector3d c = clean.V.row(clean.F(f, 2));
      const Eigen::RowVector3d area_normal = (b - a).cross(c - a).transpose();  // twice the area
      for (int k = 0; k < 3; ++k) normals.row(clean.F(f, k)) += area_normal;
    }
    for (int i = 0; i < nv; ++i) {
      const double length = normals.row(i).norm();
      if (length > 0) noisy.mesh.V.row(i) += sigma * rng.Gaussian() * normals.row(i) / length;
    }
    return noisy;
  }
  // Ray-aligned noise from a virtual camera far outside the object (docs/design.md §2): σ_ray along the ray,
  // σ_ray / 10 across it, the typical ratio of a stereo scanner.
  Eigen::Vector3d view(rng.Gaussian(), rng.Gaussian(), rng.Gaussian());
  view.normalize();
  const Eigen::Vector3d centre = clean.V.colwise().mean().transpose();
  const double diagonal = BoundingBoxExtent(clean.V).norm();
  const Eigen::Vector3d camera = centre - 5.0 * std::max(diagonal, 1e-9) * view;
  const double sigma_lat = sigma / 10.0;
  noisy.covariance.resize(nv);
  for (int i = 0; i < nv; ++i) {
    const Eigen::Vector3d p = clean.V.row(i).transpose();
    const Eigen::Vector3d r = (p - camera).normalized();
    const Eigen::Vector3d t1 = r.unitOrthogonal();
    const Eigen::Vector3d t2 = r.cross(t1);
    const Eigen::Vector3d offset = sigma * rng.Gaussian() * r + sigma_lat * (rng.Gaussian() * t1 + rng.Gaussian() * t2);
    noisy.mesh.V.row(i) += offset.transpose();
    const Eigen::Matrix3d rr = r * r.transpose();
    // A zero-noise request still needs an invertible covariance for the smoother.
    const double s_ray = std::max(sigma, 1e-9), s_lat = std::max(sigma_lat, 1e-10);
    noisy.covariance[i] = s_ray * s_ray * rr + s_lat * s_lat * (Eigen::Matrix3d::Identity() - rr);
  }
  return noisy;
}

SynthMeshSet MakeSynthMeshSet(const SynthMeshSetOptions& options) {
  options.Check();
  SynthMeshSet set;
  std::set<std::vector<int>> train_objects;
  std::uint64_t draw = 0;
  const bool mixture = options.noise_k_max > options.noise.k;
  int pair_index = 0;  // over train and test separately (reset below), for the mixture's level sequence
  std::set<std::vector<int>> test_objects;
  // is_test: a held-out (true) or validation object; neither equals an earlier set's object.
  auto add = [&](const std::string& prefix, int index, bool is_test, std::vector<SynthPair>* out) {
    const bool is_validation = prefix == "validation";
    RightAngledObjectOptions object = options.object;
    object.shape = static_cast<RightAngledShape>(index % 4);
    Mesh clean;
    std::vector<int> signature;
    // A held-out object whose kind and dimensions equal a training object's is drawn again.
    for (int attempt = 0; attempt < 1000; ++attempt) {
      clean = BuildObject(object, MixSeed(options.seed, draw++), &signature);
      if (!is_test || (train_objects.count(signature) == 0 && (!is_validation || test_objects.count(signature) == 0))) {
        break;
      }
    }
    if (!is_test) train_objects.insert(signature);
    if (is_test && !is_validation) test_objects.insert(signature);
    for (int c = 0; c < options.copies; ++c) {
      SynthPair pair;
      char name[96];
      std::snprintf(name, sizeof(name), "%s_%02d_%s_c%d", prefix.c_str(), index,
                    RightAngledShapeName(object.shape).c_str(), c);
      pair.name = name;
      pair.clean = clean;
      SynthNoiseOptions noise = options.noise;
      if (mixture) {
        // Golden-ratio sequence: evenly spread levels, uncorrelated with the shape cycle (index % 4).
        const double fraction = std::fmod(0.5 + 0.6180339887498949 * pair_index, 1.0);
        noise.k = options.noise.k + fraction * (options.noise_k_max - options.noise.k);
      }
      ++pair_index;
      pair.k = noise.k;
      pair.noisy = AddSynthNoise(clean, noise, MixSeed(options.seed ^ 0xabcdefULL, draw * 131 + c));
      if (mixture && !pair.noisy.has_covariance()) {
        GenericNoiseOptions generic;
        generic.noise_edge_multiple = std::max(noise.k, 1e-6);
        pair.noisy.covariance = MakeGenericNoisyMesh(pair.noisy.mesh, generic).covariance;
      }
      out->push_back(std::move(pair));
    }
  };
  for (int i = 0; i < options.num_train; ++i) add("train", i, false, &set.train);
  pair_index = 0;
  for (int i = 0; i < options.num_test; ++i) add("test", i, true, &set.test);
  pair_index = 0;
  for (int i = 0; i < options.num_validation; ++i) add("validation", i, true, &set.validation);
  return set;
}

}  // namespace rangebayes
