#include "bayes/decimation/decimate_geometry.h"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <queue>
#include <tuple>
#include <unordered_map>

#include "core/error.h"
#include "core/topology.h"

namespace rangebayes {
namespace {

struct Neighbour {
  int vertex;
  int faces;
  int patch;
  bool patches_differ;
  bool feature() const { return faces == 1 || patches_differ; }
};

// The chain vertices removed on each straightened chain edge, by edge key: open addressing with linear
// probing (a std::unordered_map's node per edge was a tenth of a stereo mesh's reduction), lists pooled.
class EdgeLists {
 public:
  const std::vector<int>* Find(long long key) const {
    const long long slot = Slot(key);
    return slot >= 0 && keys_[static_cast<size_t>(slot)] == key ? &pool_[values_[static_cast<size_t>(slot)]] : nullptr;
  }
  void Erase(long long key) {
    const long long slot = Slot(key);
    if (slot < 0 || keys_[static_cast<size_t>(slot)] != key) return;
    keys_[static_cast<size_t>(slot)] = kTombstone;
    free_.push_back(values_[static_cast<size_t>(slot)]);
    --used_;
    ++tombstones_;
  }
  void Set(long long key, const std::vector<int>& list) {
    if (2 * (used_ + tombstones_ + 1) > keys_.size()) Rehash(std::max<size_t>(64, 4 * (used_ + 1)));
    const size_t mask = keys_.size() - 1;
    size_t i = Hash(key) & mask;
    long long first_free = -1;
    for (;; i = (i + 1) & mask) {
      if (keys_[i] == key) {
        pool_[values_[i]] = list;
        return;
      }
      if (keys_[i] == kTombstone && first_free < 0) first_free = static_cast<long long>(i);
      if (keys_[i] == kEmpty) break;
    }
    if (first_free >= 0) {
      i = static_cast<size_t>(first_free);
      --tombstones_;
    }
    int value;
    if (!free_.empty()) {
      value = free_.back();
      free_.pop_back();
    } else {
      value = static_cast<int>(pool_.size());
      pool_.emplace_back();
    }
    keys_[i] = key;
    values_[i] = value;
    pool_[value] = list;
    ++used_;
  }

 private:
  static constexpr long long kEmpty = -1, kTombstone = -2;
  static size_t Hash(long long key) { return static_cast<size_t>((static_cast<unsigned long long>(key) * 0x9E3779B97F4A7C15ull) >> 20); }
  // The slot holding key, else the empty slot that ends its probe; −1 when the table is empty.
  long long Slot(long long key) const {
    if (keys_.empty()) return -1;
    const size_t mask = keys_.size() - 1;
    for (size_t i = Hash(key) & mask;; i = (i + 1) & mask) {
      if (keys_[i] == key || keys_[i] == kEmpty) return static_cast<long long>(i);
    }
  }
  void Rehash(size_t min_size) {
    size_t size = 64;
    while (size < min_size) size *= 2;
    std::vector<long long> keys(size, kEmpty);
    std::vector<int> values(size, 0);
    for (size_t j = 0; j < keys_.size(); ++j) {
      if (keys_[j] < 0) continue;
      size_t i = Hash(keys_[j]) & (size - 1);
      while (keys[i] != kEmpty) i = (i + 1) & (size - 1);
      keys[i] = keys_[j];
      values[i] = values_[j];
    }
    keys_ = std::move(keys);
    values_ = std::move(values);
    tombstones_ = 0;
  }

  std::vector<long long> keys_;
  std::vector<int> values_;
  std::vector<std::vector<int>> pool_;
  std::vector<int> free_;
  size_t used_ = 0, tombstones_ = 0;
};

// Per vertex, the faces around it, in one pooled array (a std::vector per vertex meant about a million
// allocations per reduction of a 526k-face stereo mesh, its lists scattered over the heap). A list that outgrows its slot
// moves to the end of the pool with twice the room; the order within a list is as with std::vector.
class StarLists {
 public:
  struct Star {
    const int* first;
    int count;
    const int* begin() const { return first; }
    const int* end() const { return first + count; }
    size_t size() const { return static_cast<size_t>(count); }
    bool empty() const { return count == 0; }
  };

  // F's faces around each of nv vertices, in face order.
  StarLists(int nv, const Faces& F) : start_(nv), size_(nv, 0), capacity_(nv, 0) {
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
      for (int k = 0; k < 3; ++k) ++capacity_[F(f, k)];
    }
    size_t total = 0;
    for (int v = 0; v < nv; ++v) {
      start_[v] = total;
      total += static_cast<size_t>(capacity_[v]);
    }
    pool_.resize(total + total / 2);
    used_ = total;
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
      for (int k = 0; k < 3; ++k) {
        const int v = F(f, k);
        pool_[start_[v] + size_[v]++] = static_cast<int>(f);
      }
    }
  }

  size_t size() const { return size_.size(); }
  Star operator[](int v) const { return {pool_.data() + start_[v], size_[v]}; }

  void PushBack(int v, int f) {
    if (size_[v] == capacity_[v]) {
      const int capacity = std::max(4, 2 * capacity_[v]);
      const size_t needed = used_ + static_cast<size_t>(capacity);
      if (needed > pool_.size()) pool_.resize(2 * needed);
      std::copy_n(pool_.begin() + static_cast<std::ptrdiff_t>(start_[v]), size_[v],
                  pool_.begin() + static_cast<std::ptrdiff_t>(used_));
      start_[v] = used_;
      capacity_[v] = capacity;
      used_ += static_cast<size_t>(capacity);
    }
    pool_[start_[v] + size_[v]++] = f;
  }

  // Removes f (a member) from v's list, keeping the order of the others.
  void Erase(int v, int f) {
    int* first = pool_.data() + start_[v];
    int* last = first + size_[v];
    int* at = std::find(first, last, f);
    std::copy(at + 1, last, at);
    --size_[v];
  }

  void Clear(int v) { size_[v] = 0; }

 private:
  std::vector<size_t> start_;
  std::vector<int> size_, capacity_;
  std::vector<int> pool_;
  size_t used_ = 0;
};

class Reducer {
 public:
  Reducer(const std::vector<const Vertices*>& poses, const Faces& F, const std::vector<int>& face_patch,
          int num_patches, const std::vector<int>& weld_group, const PatchTriangulationOptions& options,
          const std::vector<char>& boundary_vertex)
      : poses_(poses), patch_(face_patch), options_(options), vf_(static_cast<int>(poses[0]->rows()), F) {
    const int nv = static_cast<int>(poses[0]->rows());
    const int nf = static_cast<int>(F.rows());
    T_.resize(nf);
    alive_face_.assign(nf, 1);
    patch_count_.assign(num_patches, 0);
    for (int f = 0; f < nf; ++f) {
      for (int k = 0; k < 3; ++k) {
        T_[f][k] = F(f, k);
      }
      ++patch_count_[face_patch[f]];
    }
    // Patch cone axes per pose (dense corner normals where a patch has none), and a scale for "zero area".
    patch_normal_.resize(poses.size());
    vertex_normal_.resize(poses.size());
    double diag2 = 0.0;
    for (size_t m = 0; m < poses.size(); ++m) {
      const Vertices& V = *poses[m];
      patch_normal_[m] = PatchConeAxes(V, F, face_patch, num_patches);
      const bool every_patch_has_an_axis = std::none_of(patch_normal_[m].begin(), patch_normal_[m].end(),
                                                        [](const Eigen::Vector3d& n) { return n.isZero(0.0); });
      if (!every_patch_has_an_axis) vertex_normal_[m] = DenseVertexNormals(V, F);
      if (V.rows() > 0) {
        const Eigen::Vector3d lo = V.colwise().minCoeff().transpose(), hi = V.colwise().maxCoeff().transpose();
        diag2 = std::max(diag2, (hi - lo).squaredNorm());
      }
    }
    area_eps_ = 1e-14 * diag2;
    diag_ = std::sqrt(diag2);
    alive_count_ = nf;
    chain_tolerance_ = options.chain_tolerance_rel * std::sqrt(diag2);
    if (static_cast<int>(boundary_vertex.size()) == nv) {
      boundary_ = boundary_vertex;
    } else {
      Mesh mesh;
      mesh.V = *poses[0];
      mesh.F = F;
      const EdgeTopology topology = ComputeEdgeTopology(mesh);
      boundary_.assign(nv, 0);
      for (int e = 0; e < topology.edge_faces.rows(); ++e) {
        if (topology.edge_faces.size(e) == 1) {
          boundary_[topology.edges(e, 0)] = 1;
          boundary_[topology.edges(e, 1)] = 1;
        }
      }
    }
    stamp_.assign(nv, 0);
    work_mark_.assign(nv, 0);
    nb_mark_.assign(nv, 0);
    nb_slot_.assign(nv, 0);
    version_.assign(nv, 0);
    kept_.assign(nv, 0);
    collapsed_to_.assign(nv, -1);
    weld_group_.assign(nv, -1);
    if (!weld_group.empty()) {
      RB_CHECK(static_cast<int>(weld_group.size()) == nv, "decimation: weld_group has ", weld_group.size(),
               " entries for ", nv, " vertices");
      weld_group_ = weld_group;
    }
    for (int v = 0; v < nv; ++v) {
      if (weld_group_[v] >= 0) {
        kept_[v] = 1;
        copies_[weld_group_[v]].push_back(v);
      }
    }
    Classify();
  }

  PatchTriangulation Run() {
    const int nv = static_cast<int>(vf_.size());
    using Entry = std::tuple<double, int, int>;  // cost, vertex, version
    std::vector<Entry> seed;
    seed.reserve(static_cast<size_t>(nv));
    for (int v = 0; v < nv; ++v) {
      if (!kept_[v] && !vf_[v].empty()) seed.emplace_back(Cost(v), v, version_[v]);
    }
    // Heapify once (linear) instead of nv pushes.
    std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue(std::greater<Entry>(), std::move(seed));
    std::vector<int> blocked_version(nv, -1);
    std::vector<int> targets;
    while (true) {
      while (!queue.empty()) {
        const auto [cost, v, version] = queue.top();
        queue.pop();
        ++pops_;
        if (vf_[v].empty() || kept_[v]) continue;
        // Shortest edge first, lazily: a vertex whose neighbourhood changed is re-queued only when its
        // shortest edge grew well past the next candidate's (found before sorting its targets).
        const double now = Cost(v);
        if (version != version_[v] && std::isfinite(now) && !queue.empty() && now > 2.0 * std::get<0>(queue.top())) {
          queue.emplace(now, v, version_[v]);
          continue;
        }
        Targets(v, &targets);
        bool done = false;
        for (int u : targets) {
          if (TryCollapse(v, u)) {
            done = true;
            break;
          }
        }
        if (!done) blocked_version[v] = version_[v];
      }
      // Retry blocked vertices whose neighbourhood changed since they were refused.
      for (int v = 0; v < nv; ++v) {
        if (!vf_[v].empty() && !kept_[v] && blocked_version[v] >= 0 && blocked_version[v] != version_[v]) {
          blocked_version[v] = -1;
          queue.emplace(Cost(v), v, version_[v]);
        }
      }
      if (queue.empty()) break;
    }
    PatchTriangulation recorded;
    bool has_recorded = false;
    if (options_.target_faces > 0) {
      BudgetedChainPass(options_.target_faces, options_.record_faces, &recorded, &has_recorded);
    }
    PatchTriangulation out = Emit();
    if (has_recorded) out.recorded.push_back(std::move(recorded));
    return out;
  }

 private:
  // The current state as output.
  PatchTriangulation Emit() {
    const int nv = static_cast<int>(vf_.size());
    PatchTriangulation out;
    int count = 0;
    for (char a : alive_face_) count += a;
    out.F.resize(count, 3);
    out.face_patch.reserve(count);
    int row = 0;
    for (size_t f = 0; f < T_.size(); ++f) {
      if (!alive_face_[f]) continue;
      out.F.row(row++) << T_[f][0], T_[f][1], T_[f][2];
      out.face_patch.push_back(patch_[f]);
    }
    for (int v = 0; v < nv; ++v) {
      if (vf_[v].empty()) continue;
      if (kept_[v]) {
        ++out.kept_corner_vertices;
      } else {
        ++out.blocked_vertices;
      }
    }
    out.max_chain_error_rel = diag_ > 0.0 ? max_chain_error_ / diag_ : 0.0;
    out.unconditional = kept_;
    out.representative.assign(nv, -1);
    for (int v = 0; v < nv; ++v) {
      int r = v;
      while (collapsed_to_[r] >= 0) r = collapsed_to_[r];
      if (!vf_[r].empty()) out.representative[v] = r;
      // Path compression: the chains of collapses are walked once.
      for (int x = v; collapsed_to_[x] >= 0;) {
        const int next = collapsed_to_[x];
        collapsed_to_[x] = r;
        x = next;
      }
    }
    out.collapses = collapses_;
    out.collapse_attempts = attempts_;
    out.pops = pops_;
    return out;
  }

  static Eigen::Vector3d FaceCross(const Vertices& V, const std::array<int, 3>& t) {
    const Eigen::Vector3d a = V.row(t[0]).transpose(), b = V.row(t[1]).transpose(), c = V.row(t[2]).transpose();
    return (b - a).cross(c - a);
  }

  void Neighbourhood(int v, std::vector<Neighbour>* out) {
    scratch_of_ = out == &scratch_ ? v : -1;
    out->clear();
    ++nb_stamp_;
    for (int f : vf_[v]) {
      for (int k = 0; k < 3; ++k) {
        const int x = T_[f][k];
        if (x == v) continue;
        if (nb_mark_[x] != nb_stamp_) {
          nb_mark_[x] = nb_stamp_;
          nb_slot_[x] = static_cast<int>(out->size());
          out->push_back({x, 1, patch_[f], false});
        } else {
          Neighbour& n = (*out)[nb_slot_[x]];
          ++n.faces;
          if (n.patch != patch_[f]) n.patches_differ = true;
        }
      }
    }
  }

  int FeatureCount(int v) {
    Neighbourhood(v, &scratch_);
    int count = 0;
    for (const Neighbour& n : scratch_) count += n.feature() ? 1 : 0;
    return count;
  }

  // Collapse targets of v, shortest edge first: any neighbour for a vertex inside a patch, the two chain
  // neighbours for a vertex on a chain, none otherwise.
  void Targets(int v, std::vector<int>* targets) {
    targets->clear();
    if (scratch_of_ != v) Neighbourhood(v, &scratch_);
    int features = 0;
    for (const Neighbour& n : scratch_) features += n.feature() ? 1 : 0;
    if (features != 0 && features != 2) return;
    const Vertices& V = *poses_[0];
    by_length_.clear();
    for (const Neighbour& n : scratch_) {
      if (features == 0 || n.feature()) by_length_.emplace_back((V.row(n.vertex) - V.row(v)).squaredNorm(), n.vertex);
    }
    std::sort(by_length_.begin(), by_length_.end());
    for (const auto& [length2, x] : by_length_) targets->push_back(x);
  }

  // The squared length of v's shortest collapse edge (the first of Targets), without sorting them all.
  double Cost(int v) {
    Neighbourhood(v, &scratch_);
    int features = 0;
    for (const Neighbour& n : scratch_) features += n.feature() ? 1 : 0;
    if (features != 0 && features != 2) return std::numeric_limits<double>::infinity();
    const Vertices& V = *poses_[0];
    double best = std::numeric_limits<double>::infinity();
    for (const Neighbour& n : scratch_) {
      if (features == 0 || n.feature()) best = std::min(best, (V.row(n.vertex) - V.row(v)).squaredNorm());
    }
    return best;
  }

  void Classify() {
    const int nv = static_cast<int>(vf_.size());
    std::vector<int> features(nv, 0);
    for (int v = 0; v < nv; ++v) {
      if (vf_[v].empty()) continue;
      features[v] = FeatureCount(v);
      if (features[v] != 0 && features[v] != 2) kept_[v] = 1;
    }
    // Closed chains without a kept vertex keep three of their vertices.
    std::vector<char> visited(nv, 0);
    std::vector<int> chain;
    for (int start = 0; start < nv; ++start) {
      if (vf_[start].empty() || kept_[start] || features[start] != 2 || visited[start]) continue;
      chain.clear();
      int prev = -1, cur = start;
      bool closed = false;
      while (true) {
        visited[cur] = 1;
        chain.push_back(cur);
        Neighbourhood(cur, &scratch_);
        int next = -1;
        for (const Neighbour& n : scratch_) {
          if (n.feature() && n.vertex != prev) {
            next = n.vertex;
            break;
          }
        }
        if (next < 0 || kept_[next] || features[next] != 2) break;
        if (next == start) {
          closed = true;
          break;
        }
        if (visited[next]) break;
        prev = cur;
        cur = next;
      }
      if (closed) {
        // Three anchors spread over the loop: the vertex farthest from the loop's centroid, the one farthest
        // from it, and the one farthest from the line through both (a square keeps three of its corners).
        const Vertices& V = *poses_[0];
        Eigen::Vector3d centre = Eigen::Vector3d::Zero();
        for (int x : chain) centre += V.row(x).transpose();
        centre /= static_cast<double>(chain.size());
        auto farthest = [&](auto&& dist) {
          int best = chain[0];
          double best_d = -1.0;
          for (int x : chain) {
            const double d = dist(Eigen::Vector3d(V.row(x).transpose()));
            if (d > best_d) {
              best_d = d;
              best = x;
            }
          }
          return best;
        };
        const int a = farthest([&](const Eigen::Vector3d& p) { return (p - centre).squaredNorm(); });
        const Eigen::Vector3d pa = V.row(a).transpose();
        const int b = farthest([&](const Eigen::Vector3d& p) { return (p - pa).squaredNorm(); });
        const Eigen::Vector3d pb = V.row(b).transpose();
        const int c = farthest([&](const Eigen::Vector3d& p) {
          const Eigen::Vector3d ab = pb - pa;
          return ab.squaredNorm() > 0.0 ? (p - pa).cross(ab).squaredNorm() / ab.squaredNorm() : (p - pa).squaredNorm();
        });
        kept_[a] = 1;
        kept_[b] = 1;
        kept_[c] = 1;
        if (a == b || b == c || a == c) {
          kept_[chain[0]] = kept_[chain[chain.size() / 3]] = kept_[chain[(2 * chain.size()) / 3]] = 1;
        }
      }
    }
  }

  static long long EdgeKey(int a, int b) {
    if (a > b) std::swap(a, b);
    return (static_cast<long long>(a) << 32) | static_cast<unsigned>(b);
  }

  static double SegmentDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
    const Eigen::Vector3d ab = b - a;
    const double len2 = ab.squaredNorm();
    const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    return (a + t * ab - p).norm();
  }

  // For a chain vertex v collapsing onto chain neighbour u: the other chain neighbour w and whether every
  // chain vertex removed so far between u and w (and v) stays within the tolerance of segment uw.
  bool ChainKeepsShape(int v, int u, int* w_out) {
    // Callers try the targets Targets(v) just listed: the neighbourhood is usually still in scratch_.
    if (scratch_of_ != v) Neighbourhood(v, &scratch_);
    int w = -1, features = 0;
    for (const Neighbour& n : scratch_) {
      if (!n.feature()) continue;
      ++features;
      if (n.vertex != u) w = n.vertex;
    }
    *w_out = w;
    if (features == 0) return true;
    if (features != 2 || w < 0) return false;
    chain_points_.clear();
    chain_points_.push_back(v);
    for (long long key : {EdgeKey(u, v), EdgeKey(v, w)}) {
      if (const std::vector<int>* list = removed_on_edge_.Find(key)) {
        chain_points_.insert(chain_points_.end(), list->begin(), list->end());
      }
    }
    for (const Vertices* V : poses_) {
      const Eigen::Vector3d a = V->row(u).transpose(), b = V->row(w).transpose();
      for (int x : chain_points_) {
        if (SegmentDistance(V->row(x).transpose(), a, b) > chain_tolerance_) return false;
      }
    }
    return true;
  }

  // The chain error of removing chain vertex v: the largest distance (over poses) of v and the chain vertices
  // already removed next to it from the straightened segment between its two chain neighbours; infinity when
  // v is not a chain vertex.
  double ChainError(int v) {
    Neighbourhood(v, &scratch_);
    int ends[2] = {-1, -1}, features = 0;
    for (const Neighbour& n : scratch_) {
      if (!n.feature()) continue;
      if (features < 2) ends[features] = n.vertex;
      ++features;
    }
    if (features != 2) return std::numeric_limits<double>::infinity();
    const int u = ends[0], w = ends[1];
    double error = 0.0;
    for (const Vertices* V : poses_) {
      const Eigen::Vector3d a = V->row(u).transpose(), b = V->row(w).transpose();
      error = std::max(error, SegmentDistance(V->row(v).transpose(), a, b));
      for (long long key : {EdgeKey(u, v), EdgeKey(v, w)}) {
        const std::vector<int>* list = removed_on_edge_.Find(key);
        if (list == nullptr) continue;
        for (int x : *list) error = std::max(error, SegmentDistance(V->row(x).transpose(), a, b));
      }
    }
    return error;
  }

  // Removes chain vertices, least chain error first, until at most `target` faces are alive. Interior
  // vertices next to a removed one are retried at once (their stars changed; most become removable).
  void BudgetedChainPass(int target, int record_faces, PatchTriangulation* recorded, bool* has_recorded) {
    chain_tolerance_ = std::numeric_limits<double>::infinity();
    auto record = [&] {
      if (record_faces > target && !*has_recorded && alive_count_ <= record_faces) {
        *recorded = Emit();
        *has_recorded = true;
      }
    };
    record();
    using Entry = std::tuple<double, int, int>;  // chain error, vertex, version
    std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> queue;
    const int nv = static_cast<int>(vf_.size());
    queue_seed_.clear();
    for (int v = 0; v < nv; ++v) {
      if (vf_[v].empty() || kept_[v]) continue;
      const double e = ChainError(v);
      if (std::isfinite(e)) queue_seed_.emplace_back(e, v, version_[v]);
    }
    queue = decltype(queue)(std::greater<Entry>(), queue_seed_);
    // Chain vertices stay chain vertices and interior ones interior (collapses never cross a patch), so the
    // class is found once. A collapse changes the chain error of the two chain neighbours only; the other
    // vertices of the star are revisited only when their collapse was refused before (chain vertices) or
    // blocked (interior vertices, whose stars changed; most become removable).
    // A chain error depends only on the chain's vertices (interior collapses never change a chain), so it is
    // cached and recomputed only for the chain neighbours of a chain collapse.
    std::vector<char> chain(nv, 0), refused(nv, 0);
    std::vector<double> error_of(nv, std::numeric_limits<double>::infinity());
    for (const auto& [e, v, version] : queue_seed_) {
      chain[v] = 1;
      error_of[v] = e;
    }
    std::vector<int> targets, inner;
    while (!queue.empty() && alive_count_ > target) {
      auto [error, v, version] = queue.top();
      queue.pop();
      ++pops_;
      if (vf_[v].empty() || kept_[v]) continue;
      if (version != version_[v]) {
        error = error_of[v];
        if (!std::isfinite(error)) continue;
        if (!queue.empty() && error > std::get<0>(queue.top())) {
          queue.emplace(error, v, version_[v]);
          continue;
        }
      }
      Targets(v, &targets);
      int onto = -1;
      for (int u : targets) {
        if (TryCollapse(v, u)) {
          onto = u;
          break;
        }
      }
      if (onto < 0) {
        refused[v] = 1;  // retried when a collapse next to it changes its star
        continue;
      }
      max_chain_error_ = std::max(max_chain_error_, error);
      record();
      for (int x : targets) {
        if (vf_[x].empty() || kept_[x]) continue;
        error_of[x] = ChainError(x);
        if (std::isfinite(error_of[x])) queue.emplace(error_of[x], x, version_[x]);
        refused[x] = 0;
      }
      // A refused collapse of x can become possible only when x's own star changes (the stars of its
      // neighbours only grow stricter for it), so only the ring of the collapse is revisited, and in turn the
      // ring of every interior collapse that then succeeds.
      ++work_round_;
      work_.clear();
      auto push_ring = [&] {
        for (int x : ring_) {
          if (work_mark_[x] == work_round_) continue;
          work_mark_[x] = work_round_;
          work_.push_back(x);
        }
      };
      push_ring();
      for (size_t i = 0; i < work_.size(); ++i) {
        const int x = work_[i];
        if (x == onto || kept_[x] || vf_[x].empty()) continue;
        if (chain[x]) {
          if (refused[x]) {
            refused[x] = 0;
            if (std::isfinite(error_of[x])) queue.emplace(error_of[x], x, version_[x]);
          }
        } else if (alive_count_ > target) {
          Targets(x, &inner);
          for (int u : inner) {
            if (TryCollapse(x, u)) {
              record();
              push_ring();
              break;
            }
          }
        }
      }
    }
  }

  bool TryCollapse(int v, int u) {
    ++attempts_;
    if (vf_[u].empty()) return false;
    int w = -1;
    if (!ChainKeepsShape(v, u, &w)) return false;
    if (boundary_[v] && !boundary_[u]) return false;
    SplitStar(v, u);
    if (deleted_.empty()) return false;
    if (boundary_[v] && boundary_[u] && deleted_.size() != 1) return false;
    int apex_stamp = 0;
    if (!LinkConditionHolds(v, u, &apex_stamp)) return false;
    if (weld_group_[u] >= 0 && JoinsLockedVertices(v, u, apex_stamp)) return false;
    if (GivesCopiesACommonNeighbour(v, u, apex_stamp)) return false;
    if (!EveryPatchKeepsAFace()) return false;
    if (!MovedFacesStayValid(v, u, apex_stamp)) return false;
    ApplyCollapse(v, u, w);
    MarkChangedStars(v, u);
    return true;
  }

  // v's faces: those on edge uv into deleted_, the others into moved_.
  void SplitStar(int v, int u) {
    deleted_.clear();
    moved_.clear();
    for (int f : vf_[v]) {
      const auto& t = T_[f];
      if (t[0] == u || t[1] == u || t[2] == u) {
        deleted_.push_back(f);
      } else {
        moved_.push_back(f);
      }
    }
  }

  // Link condition: common neighbours of u and v are exactly the apexes of the faces on edge uv. The apexes
  // keep the stamp *apex_stamp, for MovedFacesStayValid.
  bool LinkConditionHolds(int v, int u, int* apex_stamp) {
    ++current_stamp_;
    for (int f : deleted_) {
      for (int x : T_[f]) {
        if (x != u && x != v) stamp_[x] = current_stamp_;
      }
    }
    *apex_stamp = current_stamp_;
    ++current_stamp_;
    for (int f : vf_[v]) {
      for (int x : T_[f]) {
        if (x != u && x != v && stamp_[x] != *apex_stamp) stamp_[x] = current_stamp_;
      }
    }
    return !SharesNeighbourOffEdge(v, u, current_stamp_);
  }

  // A common neighbour off the edge breaks the link condition. Scan whichever side is cheaper: u's star, or
  // the stars of v's (few) neighbours looking for u; u is often a hub that has absorbed many collapses.
  bool SharesNeighbourOffEdge(int v, int u, int v_stamp) const {
    size_t cost_v_side = 0;
    for (int f : moved_) cost_v_side += vf_[T_[f][0]].size() + vf_[T_[f][1]].size() + vf_[T_[f][2]].size();
    if (vf_[u].size() <= cost_v_side) {
      for (int f : vf_[u]) {
        for (int x : T_[f]) {
          if (x != u && x != v && stamp_[x] == v_stamp) return true;
        }
      }
    } else {
      for (int f : moved_) {
        for (int x : T_[f]) {
          if (x == v || stamp_[x] != v_stamp) continue;
          for (int g : vf_[x]) {
            const auto& t = T_[g];
            if (t[0] == u || t[1] == u || t[2] == u) return true;
          }
        }
      }
    }
    return false;
  }

  // Whether moving v onto locked u makes u a neighbour of another locked vertex: with the link condition
  // holding, v's neighbours off the edge's apexes are not u's neighbours yet. Locked vertices never collapse, so
  // the edges between them stay those of the input.
  bool JoinsLockedVertices(int v, int u, int apex_stamp) const {
    for (int f : moved_) {
      for (int x : T_[f]) {
        if (x != v && x != u && weld_group_[x] >= 0 && stamp_[x] != apex_stamp) return true;
      }
    }
    return false;
  }

  // Whether moving v onto u gives two copies of one weld group a common neighbour (conservatively: any copy
  // that v neighbours already counts as one). Welded, their two edges to it would become one, shared by the
  // faces of both sheets: two boundary edges merge (a hole closes) or an edge gets more than two faces.
  bool GivesCopiesACommonNeighbour(int v, int u, int apex_stamp) const {
    if (copies_.empty()) return false;
    for (int f : moved_) {
      for (int x : T_[f]) {
        if (x == v || x == u || stamp_[x] == apex_stamp) continue;  // x: a new neighbour of u
        if (weld_group_[x] >= 0) {
          for (int other : copies_.at(weld_group_[x])) {
            if (other != x && (Adjacent(other, u) || Adjacent(other, v))) return true;
          }
        }
        if (weld_group_[u] >= 0) {
          for (int other : copies_.at(weld_group_[u])) {
            if (other != u && Adjacent(other, x)) return true;
          }
        }
      }
    }
    return false;
  }

  bool Adjacent(int a, int b) const {
    for (int f : vf_[a]) {
      const auto& t = T_[f];
      if (t[0] == b || t[1] == b || t[2] == b) return true;
    }
    return false;
  }

  // Every patch keeps at least one face.
  bool EveryPatchKeepsAFace() const {
    for (int f : deleted_) {
      int same = 0;
      for (int g : deleted_) same += patch_[g] == patch_[f] ? 1 : 0;
      if (patch_count_[patch_[f]] - same < 1) return false;
    }
    return true;
  }

  // No duplicate faces, no flips, no zero areas.
  bool MovedFacesStayValid(int v, int u, int apex_stamp) const {
    for (int f : moved_) {
      std::array<int, 3> t = T_[f];
      for (int& x : t) {
        if (x == v) x = u;
      }
      if (DuplicatesAFace(t, u, apex_stamp)) return false;
      if (!KeepsAreaAndOrientation(f, t)) return false;
    }
    return true;
  }

  // With the link condition holding, a duplicate of (u, x, y) can only exist when x and y are both apexes
  // of edge uv (the last collapse of a tetrahedron); refuse that case.
  bool DuplicatesAFace(const std::array<int, 3>& t, int u, int apex_stamp) const {
    int apexes = 0;
    for (int x : t) apexes += (x != u && stamp_[x] == apex_stamp) ? 1 : 0;
    if (apexes == 2) {
      for (int g : vf_[u]) {
        const auto& s = T_[g];
        int shared = 0;
        for (int x : t) shared += (s[0] == x || s[1] == x || s[2] == x) ? 1 : 0;
        if (shared == 3) return true;
      }
    }
    return false;
  }

  // Face f as t (v moved onto u), in every pose: not of zero area, not flipped, close enough to its patch's normal.
  bool KeepsAreaAndOrientation(int f, const std::array<int, 3>& t) const {
    const int k = patch_[f];
    for (size_t m = 0; m < poses_.size(); ++m) {
      const Eigen::Vector3d now = FaceCross(*poses_[m], t);
      const Eigen::Vector3d before = FaceCross(*poses_[m], T_[f]);
      const double len = now.norm();
      if (len <= area_eps_) return false;
      if (before.squaredNorm() > area_eps_ * area_eps_ && now.dot(before) <= 0.0) return false;
      if (!InPatchCone(now, patch_normal_[m][k], t, vertex_normal_[m], options_.min_cos_to_patch_normal)) return false;
    }
    return true;
  }

  // Apply: v onto u, with w v's other chain neighbour (−1: v is inside a patch).
  void ApplyCollapse(int v, int u, int w) {
    scratch_of_ = -1;
    if (w >= 0) {
      removed_on_edge_.Erase(EdgeKey(u, v));
      removed_on_edge_.Erase(EdgeKey(v, w));
      removed_on_edge_.Set(EdgeKey(u, w), chain_points_);
    }
    alive_count_ -= static_cast<int>(deleted_.size());
    for (int f : deleted_) {
      alive_face_[f] = 0;
      --patch_count_[patch_[f]];
      for (int x : T_[f]) {
        if (x == v) continue;
        vf_.Erase(x, f);
      }
    }
    for (int f : moved_) {
      for (int& x : T_[f]) {
        if (x == v) x = u;
      }
      vf_.PushBack(u, f);
    }
    vf_.Clear(v);
    collapsed_to_[v] = u;
    ++collapses_;
  }

  // Only u and v's former neighbours see their stars change.
  void MarkChangedStars(int v, int u) {
    ring_.clear();
    ++current_stamp_;
    for (const std::vector<int>* faces : {&deleted_, &moved_}) {
      for (int f : *faces) {
        for (int x : T_[f]) {
          if (x == v || stamp_[x] == current_stamp_) continue;
          stamp_[x] = current_stamp_;
          ring_.push_back(x);
        }
      }
    }
    ++version_[u];
    for (int f : moved_) {
      for (int x : T_[f]) ++version_[x];
    }
    for (int f : deleted_) {
      for (int x : T_[f]) ++version_[x];
    }
  }

  const std::vector<const Vertices*>& poses_;
  const std::vector<int>& patch_;
  PatchTriangulationOptions options_;
  std::vector<std::array<int, 3>> T_;
  std::vector<char> alive_face_;
  StarLists vf_;
  std::vector<int> patch_count_;
  std::vector<std::vector<Eigen::Vector3d>> patch_normal_;   // per pose, per patch: PatchConeAxes
  std::vector<std::vector<Eigen::Vector3d>> vertex_normal_;  // per pose: DenseVertexNormals, where a patch has no axis
  std::vector<char> boundary_, kept_;
  std::vector<int> weld_group_;  // per vertex, TriangulatePatches' weld_group (−1: none; the others are kept_)
  std::unordered_map<int, std::vector<int>> copies_;  // per weld group, its vertices
  std::vector<int> stamp_, version_;
  std::vector<int> collapsed_to_;
  std::vector<int> nb_mark_, nb_slot_;
  int nb_stamp_ = 0;
  int current_stamp_ = 0;
  double area_eps_ = 0.0;
  int collapses_ = 0;
  long long attempts_ = 0, pops_ = 0;
  std::vector<Neighbour> scratch_;
  int scratch_of_ = -1;  // the vertex whose neighbourhood scratch_ holds (−1: none, or stale)
  std::vector<std::pair<double, int>> by_length_;
  std::vector<int> deleted_, moved_;
  std::vector<int> chain_points_;
  std::vector<int> ring_;              // after a collapse: u and the former neighbours of v, whose stars changed
  std::vector<int> work_, work_mark_;  // BudgetedChainPass: vertices to revisit after a chain collapse
  int work_round_ = 0;
  std::vector<std::tuple<double, int, int>> queue_seed_;
  EdgeLists removed_on_edge_;
  double chain_tolerance_ = 0.0;
  double diag_ = 0.0;
  double max_chain_error_ = 0.0;
  int alive_count_ = 0;
};

}  // namespace

std::vector<Eigen::Vector3d> PatchConeAxes(const Vertices& V, const Faces& F, const std::vector<int>& face_patch,
                                           int num_patches) {
  std::vector<Eigen::Vector3d> sum(std::max(num_patches, 0), Eigen::Vector3d::Zero());
  std::vector<double> area(sum.size(), 0.0);
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const int k = face_patch[f];
    if (k < 0 || k >= num_patches) continue;
    const Eigen::Vector3d a = V.row(F(f, 0)).transpose();
    const Eigen::Vector3d cross = (V.row(F(f, 1)).transpose() - a).cross(V.row(F(f, 2)).transpose() - a);
    sum[k] += cross;
    area[k] += cross.norm();
  }
  for (size_t k = 0; k < sum.size(); ++k) {
    const double len = sum[k].norm();
    sum[k] = len > 0.0 && len >= kMinPatchNormalCoherence * area[k] ? Eigen::Vector3d(sum[k] / len)
                                                                    : Eigen::Vector3d::Zero();
  }
  return sum;
}

std::vector<Eigen::Vector3d> DenseVertexNormals(const Vertices& V, const Faces& F) {
  std::vector<Eigen::Vector3d> normal(V.rows(), Eigen::Vector3d::Zero());
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    const Eigen::Vector3d a = V.row(F(f, 0)).transpose();
    const Eigen::Vector3d cross = (V.row(F(f, 1)).transpose() - a).cross(V.row(F(f, 2)).transpose() - a);
    for (int k = 0; k < 3; ++k) normal[F(f, k)] += cross;
  }
  for (auto& n : normal) {
    const double len = n.norm();
    n = len > 0.0 ? Eigen::Vector3d(n / len) : Eigen::Vector3d::Zero();
  }
  return normal;
}

bool InPatchCone(const Eigen::Vector3d& cross, const Eigen::Vector3d& axis, const std::array<int, 3>& corners,
                 const std::vector<Eigen::Vector3d>& vertex_normal, double min_cos) {
  const double len = cross.norm();
  if (!axis.isZero(0.0)) return cross.dot(axis) >= min_cos * len;
  for (int x : corners) {
    if (cross.dot(vertex_normal[x]) < min_cos * len) return false;
  }
  return true;
}

PatchTriangulation TriangulatePatches(const std::vector<const Vertices*>& poses, const Faces& F,
                                      const std::vector<int>& face_patch, int num_patches,
                                      const std::vector<int>& weld_group, const PatchTriangulationOptions& options,
                                      const std::vector<char>& boundary_vertex) {
  RB_CHECK(!poses.empty(), "decimation: no poses");
  RB_CHECK(static_cast<int>(face_patch.size()) == F.rows(), "decimation: face_patch has ", face_patch.size(),
           " entries for ", F.rows(), " faces");
  RB_CHECK(options.min_cos_to_patch_normal >= 0.0 && options.min_cos_to_patch_normal < 1.0,
           "decimation: min_cos_to_patch_normal must be in [0, 1)");
  for (const Vertices* V : poses) {
    RB_CHECK(V != nullptr && V->rows() == poses[0]->rows(), "decimation: poses differ in vertex count");
  }
  Reducer reducer(poses, F, face_patch, num_patches, weld_group, options, boundary_vertex);
  return reducer.Run();
}

Eigen::Vector3d PatchNormalField::Evaluate(const Eigen::Vector3d& p) const {
  const Eigen::Vector3d n = mean + gradient * (basis * (p - center));
  const double len = n.norm();
  if (len > 1e-6) return n / len;
  const double mlen = mean.norm();
  return mlen > 0.0 ? Eigen::Vector3d(mean / mlen) : Eigen::Vector3d::UnitZ();
}

std::vector<PatchNormalField> FitPatchNormalFields(const Vertices& V, const Faces& F,
                                                   const std::vector<double>& face_weight,
                                                   const std::vector<int>& face_patch, int num_patches,
                                                   double regularisation) {
  const int nf = static_cast<int>(F.rows());
  std::vector<Eigen::Vector3d> centroid(nf), normal(nf);
  std::vector<double> wsum(num_patches, 0.0);
  std::vector<Eigen::Vector3d> csum(num_patches, Eigen::Vector3d::Zero()), nsum(num_patches, Eigen::Vector3d::Zero());
  std::vector<int> count(num_patches, 0);
  for (int f = 0; f < nf; ++f) {
    const Eigen::Vector3d a = V.row(F(f, 0)).transpose(), b = V.row(F(f, 1)).transpose(),
                          c = V.row(F(f, 2)).transpose();
    centroid[f] = (a + b + c) / 3.0;
    const Eigen::Vector3d cr = (b - a).cross(c - a);
    const double len = cr.norm();
    normal[f] = len > 0.0 ? Eigen::Vector3d(cr / len) : Eigen::Vector3d::Zero();
    const int k = face_patch[f];
    // Centroid weights fall back to 1 so that all-zero-weight patches still get a centre.
    const double w = face_weight[f];
    wsum[k] += w;
    csum[k] += (w > 0.0 ? w : 1e-12) * centroid[f];
    nsum[k] += w * normal[f];
    ++count[k];
  }
  std::vector<PatchNormalField> fields(num_patches);
  std::vector<double> cw(num_patches, 0.0);
  for (int f = 0; f < nf; ++f) cw[face_patch[f]] += face_weight[f] > 0.0 ? face_weight[f] : 1e-12;
  for (int k = 0; k < num_patches; ++k) {
    PatchNormalField& field = fields[k];
    field.center = cw[k] > 0.0 ? Eigen::Vector3d(csum[k] / cw[k]) : Eigen::Vector3d::Zero();
    field.mean = wsum[k] > 0.0 ? Eigen::Vector3d(nsum[k] / wsum[k]) : Eigen::Vector3d::UnitZ();
    Eigen::Vector3d n = field.mean.norm() > 1e-12 ? field.mean.normalized() : Eigen::Vector3d::UnitZ();
    Eigen::Vector3d e1 = n.unitOrthogonal();
    Eigen::Vector3d e2 = n.cross(e1);
    field.basis.row(0) = e1.transpose();
    field.basis.row(1) = e2.transpose();
  }
  // Normal equations per patch: M = Σ w t tᵀ (2×2), R = Σ w (u − a) tᵀ (3×2).
  std::vector<Eigen::Matrix2d> M(num_patches, Eigen::Matrix2d::Zero());
  std::vector<Eigen::Matrix<double, 3, 2>> R(num_patches, Eigen::Matrix<double, 3, 2>::Zero());
  for (int f = 0; f < nf; ++f) {
    const int k = face_patch[f];
    const double w = face_weight[f];
    if (w <= 0.0) continue;
    const Eigen::Vector2d t = fields[k].basis * (centroid[f] - fields[k].center);
    M[k] += w * t * t.transpose();
    R[k] += w * (normal[f] - fields[k].mean) * t.transpose();
  }
  for (int k = 0; k < num_patches; ++k) {
    if (count[k] < 3 || wsum[k] <= 0.0) continue;
    const double spread = M[k].trace();
    if (!(spread > 0.0)) continue;
    const Eigen::Matrix2d A = M[k] + (regularisation * spread + 1e-12 * spread) * Eigen::Matrix2d::Identity();
    fields[k].gradient = R[k] * A.inverse();
  }
  return fields;
}

}  // namespace rangebayes
