#include "bayes/decimation/decimate_partition.h"

#include <algorithm>
#include <cmath>
#include <queue>

#include <tbb/parallel_for.h>

#include "core/error.h"

namespace rangebayes {
namespace {

// One candidate move in a priority queue. Entries are lazy: they remember the versions of the patches they
// were computed for and are re-evaluated when popped stale.
struct FuseEntry {
  double gain;
  int a, b;
  int version_a, version_b;
  bool operator<(const FuseEntry& o) const {
    if (gain != o.gain) return gain < o.gain;
    if (a != o.a) return a > o.a;
    return b > o.b;
  }
};

struct FaceEntry {
  double gain;
  int face;
  int source, target;  // target −1: split the face off into a new patch
  int version_source, version_target;
  bool operator<(const FaceEntry& o) const {
    if (gain != o.gain) return gain < o.gain;
    if (face != o.face) return face > o.face;
    return target > o.target;
  }
};

class Climber {
 public:
  Climber(const DecimationProblem& problem, double lambda, const std::vector<int>* initial)
      : p_(problem), lambda_(lambda), d_(problem.dim), eps_(1e-9 * lambda) {
    const int nf = p_.num_faces();
    g_.resize(nf);
    next_.assign(nf, -1);
    prev_.assign(nf, -1);
    mark_.assign(nf, 0);
    if (initial != nullptr && !initial->empty()) {
      int num = 0;
      for (int k : *initial) num = std::max(num, k + 1);
      W_.reserve(static_cast<size_t>(num));
      for (int k = 0; k < num; ++k) NewPatch();
      for (int f = nf - 1; f >= 0; --f) {
        const int k = (*initial)[static_cast<size_t>(f)];
        g_[f] = k;
        next_[f] = head_[k];
        if (head_[k] >= 0) prev_[head_[k]] = f;
        head_[k] = f;
        ++size_[k];
        AddFaceSums(k, f, +1.0);
      }
      for (int k = 0; k < num; ++k) alive_[k] = size_[k] > 0 ? 1 : 0;
      return;
    }
    for (int f = 0; f < nf; ++f) {
      const int k = NewPatch();
      g_[f] = k;
      head_[k] = f;
      size_[k] = 1;
      AddFaceSums(k, f, +1.0);
    }
  }

  std::vector<int> Run(const PartitionOptions& options, PartitionStats* stats) {
    PartitionStats local;
    PartitionStats& s = stats != nullptr ? *stats : local;
    s = PartitionStats{};
    stats_ = &s;
    dirty_.assign(W_.size(), 1);
    for (int round = 0; round < options.max_rounds; ++round) {
      s.rounds = round + 1;
      // Only candidates that touch a patch changed in the last round can have changed their gain.
      seed_dirty_.swap(dirty_);
      dirty_.assign(W_.size(), 0);
      const std::int64_t moves = FusePhase() + FacePhase();
      if (options.progress) {
        options.progress(std::min(0.95, 0.5 + 0.05 * round), "partition");
      }
      if (moves == 0) {
        s.converged = true;
        break;
      }
    }
    // Dense ids in order of first face.
    std::vector<int> remap(W_.size(), -1);
    std::vector<int> out(g_.size());
    int count = 0;
    for (size_t f = 0; f < g_.size(); ++f) {
      int& r = remap[static_cast<size_t>(g_[f])];
      if (r < 0) r = count++;
      out[f] = r;
    }
    s.num_patches = count;
    s.energy = PartitionEnergy(p_, out, lambda_, &s.data_energy);
    return out;
  }

 private:
  int NewPatch() {
    const int k = static_cast<int>(W_.size());
    W_.push_back(0.0);
    Q_.push_back(0.0);
    S_.resize(S_.size() + static_cast<size_t>(d_), 0.0);
    size_.push_back(0);
    version_.push_back(0);
    alive_.push_back(1);
    alias_.push_back(k);
    head_.push_back(-1);
    dirty_.push_back(1);
    additions_.push_back(0);
    return k;
  }

  const double* U(int f) const { return p_.normals.data() + static_cast<size_t>(f) * d_; }
  double* Sum(int k) { return S_.data() + static_cast<size_t>(k) * d_; }
  const double* Sum(int k) const { return S_.data() + static_cast<size_t>(k) * d_; }

  void AddFaceSums(int k, int f, double sign) {
    const double w = p_.weight[f];
    const double* u = U(f);
    double* s = Sum(k);
    double q = 0.0;
    for (int c = 0; c < d_; ++c) {
      s[c] += sign * w * u[c];
      q += u[c] * u[c];
    }
    W_[k] += sign * w;
    Q_[k] += sign * w * q;
  }

  // E = Q − ‖S‖²/W for a set with weight sum W (0 for an empty or zero-weight set).
  static double SetEnergy(double w, double q, double s2) { return w > 1e-300 ? std::max(0.0, q - s2 / w) : 0.0; }
  double Norm2(const double* s) const {
    double r = 0.0;
    for (int c = 0; c < d_; ++c) r += s[c] * s[c];
    return r;
  }
  double PatchEnergy(int k) const { return SetEnergy(W_[k], Q_[k], Norm2(Sum(k))); }

  double FuseGain(int a, int b) const {
    const double* sa = Sum(a);
    const double* sb = Sum(b);
    double s2 = 0.0;
    for (int c = 0; c < d_; ++c) s2 += (sa[c] + sb[c]) * (sa[c] + sb[c]);
    const double merged = SetEnergy(W_[a] + W_[b], Q_[a] + Q_[b], s2);
    return lambda_ - (merged - PatchEnergy(a) - PatchEnergy(b));
  }

  // Energy of patch k with face f (a member) removed, and of patch j with f added.
  double EnergyWithout(int k, int f) const {
    const double w = p_.weight[f];
    const double* u = U(f);
    const double* s = Sum(k);
    double s2 = 0.0, q = 0.0;
    for (int c = 0; c < d_; ++c) {
      const double v = s[c] - w * u[c];
      s2 += v * v;
      q += u[c] * u[c];
    }
    return SetEnergy(W_[k] - w, Q_[k] - w * q, s2);
  }
  double EnergyWith(int j, int f) const {
    const double w = p_.weight[f];
    const double* u = U(f);
    const double* s = Sum(j);
    double s2 = 0.0, q = 0.0;
    for (int c = 0; c < d_; ++c) {
      const double v = s[c] + w * u[c];
      s2 += v * v;
      q += u[c] * u[c];
    }
    return SetEnergy(W_[j] + w, Q_[j] + w * q, s2);
  }

  // Changed in the previous round (or created since, which counts as changed).
  bool Dirty(int k) const { return k >= static_cast<int>(seed_dirty_.size()) || seed_dirty_[k] || dirty_[k]; }

  int Find(int k) {
    while (alias_[k] != k) {
      alias_[k] = alias_[alias_[k]];
      k = alias_[k];
    }
    return k;
  }

  // The entries `emit(f, &list)` appends for every face, in face order, where emit appends nothing for a face
  // unless it or an edge neighbour lies in a dirty patch (Dirty). Late in a climb few patches are dirty: then
  // only their faces and those faces' neighbours are visited (sorted, so the order is the same). The faces
  // are scanned in parallel in fixed blocks (emit only reads the climber's state), so the list is the same as
  // a serial scan's.
  template <typename Entry, typename Emit>
  std::vector<Entry> CollectByFace(const Emit& emit) {
    constexpr int kBlock = 8192;
    const int nf = p_.num_faces();
    long long dirty_faces = 0;
    for (size_t k = 0; k < W_.size(); ++k) {
      if (Dirty(static_cast<int>(k))) dirty_faces += size_[k];
    }
    const bool all = 4 * dirty_faces > nf;
    if (!all) {
      if (static_cast<int>(candidate_stamp_.size()) != nf) candidate_stamp_.assign(nf, 0);
      ++candidate_round_;
      candidates_.clear();
      auto add = [&](int f) {
        if (candidate_stamp_[f] == candidate_round_) return;
        candidate_stamp_[f] = candidate_round_;
        candidates_.push_back(f);
      };
      for (size_t k = 0; k < W_.size(); ++k) {
        if (!Dirty(static_cast<int>(k))) continue;
        for (int f = head_[k]; f >= 0; f = next_[f]) {
          add(f);
          for (int h : p_.neighbours[f]) {
            if (h >= 0) add(h);
          }
        }
      }
      std::sort(candidates_.begin(), candidates_.end());
    }
    const int count = all ? nf : static_cast<int>(candidates_.size());
    const int blocks = (count + kBlock - 1) / kBlock;
    std::vector<std::vector<Entry>> parts(static_cast<size_t>(blocks));
    tbb::parallel_for(0, blocks, [&](int b) {
      std::vector<Entry>& part = parts[static_cast<size_t>(b)];
      for (int i = b * kBlock, end = std::min(count, i + kBlock); i < end; ++i) emit(all ? i : candidates_[i], &part);
    });
    size_t total = 0;
    for (const auto& part : parts) total += part.size();
    std::vector<Entry> out;
    out.reserve(total);
    for (const auto& part : parts) out.insert(out.end(), part.begin(), part.end());
    return out;
  }

  // ---- fuse phase -------------------------------------------------------------------------------------
  std::int64_t FusePhase() {
    std::priority_queue<FuseEntry> queue;
    {
      std::vector<FuseEntry> seed = CollectByFace<FuseEntry>([&](int f, std::vector<FuseEntry>* out) {
        for (int e = 0; e < 3; ++e) {
          const int h = p_.neighbours[f][e];
          if (h < 0 || h < f) continue;
          int a = g_[f], b = g_[h];
          if (a == b || !(Dirty(a) || Dirty(b))) continue;
          if (a > b) std::swap(a, b);
          const double gain = FuseGain(a, b);
          if (gain > eps_) out->push_back({gain, a, b, version_[a], version_[b]});
        }
      });
      std::sort(seed.begin(), seed.end(), [](const FuseEntry& x, const FuseEntry& y) {
        return x.a != y.a ? x.a < y.a : x.b < y.b;
      });
      seed.erase(std::unique(seed.begin(), seed.end(),
                             [](const FuseEntry& x, const FuseEntry& y) { return x.a == y.a && x.b == y.b; }),
                 seed.end());
      // The seed is consumed in sorted order (one cache-friendly sort instead of a heap pop per candidate);
      // refreshed candidates go to a heap that is merged with it on the fly. Same order as one heap.
      std::sort(seed.begin(), seed.end(), [](const FuseEntry& x, const FuseEntry& y) { return y < x; });
      seed_ = std::move(seed);
    }
    size_t next = 0;
    auto empty = [&] { return next >= seed_.size() && queue.empty(); };
    auto top = [&]() -> const FuseEntry& {
      if (next >= seed_.size()) return queue.top();
      if (queue.empty() || queue.top() < seed_[next]) return seed_[next];
      return queue.top();
    };
    auto pop = [&] {
      if (next < seed_.size() && (queue.empty() || queue.top() < seed_[next])) {
        ++next;
      } else {
        queue.pop();
      }
    };
    std::int64_t applied = 0;
    while (!empty()) {
      FuseEntry e = top();
      pop();
      const int a = Find(e.a), b = Find(e.b);
      if (a == b) continue;
      if (a != e.a || b != e.b || version_[a] != e.version_a || version_[b] != e.version_b) {
        // Lazy greedy: a refreshed gain that still beats (nearly) everything left is taken at once instead of
        // re-queued; a big patch absorbing small ones would otherwise re-queue its whole rim on every fuse.
        const double gain = FuseGain(a, b);
        if (gain <= eps_) continue;
        if (!empty() && gain < top().gain - 0.1 * std::abs(top().gain)) {
          queue.push({gain, a, b, version_[a], version_[b]});
          continue;
        }
      }
      Fuse(a, b);
      ++applied;
    }
    stats_->fuses += applied;
    return applied;
  }

  void Fuse(int a, int b) {
    // Relabel the smaller patch.
    int keep = a, gone = b;
    if (size_[a] < size_[b]) std::swap(keep, gone);
    int last = -1;
    for (int f = head_[gone]; f >= 0; f = next_[f]) {
      g_[f] = keep;
      last = f;
    }
    // Splice gone's list in front of keep's.
    if (last >= 0) {
      next_[last] = head_[keep];
      if (head_[keep] >= 0) prev_[head_[keep]] = last;
      head_[keep] = head_[gone];
    }
    head_[gone] = -1;
    W_[keep] += W_[gone];
    Q_[keep] += Q_[gone];
    double* sk = Sum(keep);
    const double* sg = Sum(gone);
    for (int c = 0; c < d_; ++c) sk[c] += sg[c];
    size_[keep] += size_[gone];
    size_[gone] = 0;
    alive_[gone] = 0;
    alias_[gone] = keep;
    ++additions_[keep];
    ++version_[keep];
    ++version_[gone];
    dirty_[keep] = 1;
  }

  // ---- split / swap phase -----------------------------------------------------------------------------
  // The best split or swap for face f, or gain ≤ eps when none improves.
  FaceEntry BestFaceMove(int f) const {
    const int k = g_[f];
    FaceEntry best{-1.0, f, k, -1, version_[k], 0};
    if (size_[k] < 2) return best;
    const double ek = PatchEnergy(k);
    const double without = EnergyWithout(k, f);
    const double split_gain = ek - without - lambda_;
    if (split_gain > best.gain) best.gain = split_gain;
    int seen[3] = {-1, -1, -1};
    for (int e = 0; e < 3; ++e) {
      const int h = p_.neighbours[f][e];
      if (h < 0) continue;
      const int j = g_[h];
      if (j == k || j == seen[0] || j == seen[1]) continue;
      seen[e] = j;
      const double gain = ek + PatchEnergy(j) - without - EnergyWith(j, f);
      if (gain > best.gain) {
        best.gain = gain;
        best.target = j;
        best.version_target = version_[j];
      }
    }
    return best;
  }

  void PushFace(std::priority_queue<FaceEntry>& queue, int f) const {
    const FaceEntry e = BestFaceMove(f);
    if (e.gain > eps_) queue.push(e);
  }

  std::int64_t FacePhase() {
    std::priority_queue<FaceEntry> queue;
    {
      std::vector<FaceEntry> seed = CollectByFace<FaceEntry>([&](int f, std::vector<FaceEntry>* out) {
        bool touched = Dirty(g_[f]);
        for (int h : p_.neighbours[f]) touched = touched || (h >= 0 && Dirty(g_[h]));
        if (!touched) return;
        const FaceEntry e = BestFaceMove(f);
        if (e.gain > eps_) out->push_back(e);
      });
      queue = std::priority_queue<FaceEntry>(std::less<FaceEntry>(), std::move(seed));
    }
    std::int64_t applied = 0;
    while (!queue.empty()) {
      const FaceEntry e = queue.top();
      queue.pop();
      const int f = e.face;
      const int k = g_[f];
      if (k != e.source || version_[k] != e.version_source ||
          (e.target >= 0 && version_[e.target] != e.version_target)) {
        PushFace(queue, f);
        continue;
      }
      if (!RemovalKeepsContiguous(f)) {
        ++stats_->rejected_disconnecting;
        RememberDisconnecting(f);
        continue;
      }
      int target = e.target;
      if (target < 0) {
        target = NewPatch();
        ++stats_->splits;
      } else {
        ++stats_->swaps;
      }
      MoveFace(f, k, target);
      ++applied;
      for (int h : p_.neighbours[f]) {
        if (h >= 0) PushFace(queue, h);
      }
    }
    return applied;
  }

  void MoveFace(int f, int from, int to) {
    // Unlink from `from`.
    if (prev_[f] >= 0) {
      next_[prev_[f]] = next_[f];
    } else {
      head_[from] = next_[f];
    }
    if (next_[f] >= 0) prev_[next_[f]] = prev_[f];
    // Push at the front of `to`.
    prev_[f] = -1;
    next_[f] = head_[to];
    if (head_[to] >= 0) prev_[head_[to]] = f;
    head_[to] = f;
    AddFaceSums(from, f, -1.0);
    AddFaceSums(to, f, +1.0);
    --size_[from];
    ++size_[to];
    g_[f] = to;
    ++additions_[to];
    ++version_[from];
    ++version_[to];
    dirty_[from] = 1;
    dirty_[to] = 1;
  }

  // Walks the fan around vertex v from `start` (away from the removed face f) and reports whether it reaches
  // `goal` through faces of patch k only.
  bool FanConnects(int f, int start, int goal, int v, int k) const {
    int prev = f, cur = start;
    for (int step = 0; step < 64; ++step) {
      if (cur == goal) return true;
      const auto& c = p_.corners[cur];
      int corner = -1;
      for (int i = 0; i < 3; ++i) {
        if (c[i] == v) corner = i;
      }
      if (corner < 0) return false;
      const int n1 = p_.neighbours[cur][corner];
      const int n2 = p_.neighbours[cur][(corner + 2) % 3];
      const int next = n1 == prev ? n2 : n1;
      if (next < 0 || next == f || next == prev || g_[next] != k) return false;
      prev = cur;
      cur = next;
    }
    return false;
  }

  // Interleaved BFS from a and b inside patch k without face f: true when they meet. Stops as soon as the
  // smaller side is exhausted, so a cut-off sliver costs only its own size.
  bool BfsConnects(int f, int a, int b, int k) {
    ++stats_->bfs_fallbacks;
    stamp_ += 2;
    const int mark_a = stamp_, mark_b = stamp_ + 1;
    std::vector<int>& qa = bfs_a_;
    std::vector<int>& qb = bfs_b_;
    qa.assign(1, a);
    qb.assign(1, b);
    size_t ia = 0, ib = 0;
    mark_[a] = mark_a;
    mark_[b] = mark_b;
    auto step = [&](std::vector<int>& q, size_t& i, int mine, int other) -> int {
      // Returns 1 on meeting, −1 when exhausted, 0 otherwise.
      if (i >= q.size()) return -1;
      const int x = q[i++];
      for (int h : p_.neighbours[x]) {
        if (h < 0 || h == f || g_[h] != k) continue;
        if (mark_[h] == other) return 1;
        if (mark_[h] != mine) {
          mark_[h] = mine;
          q.push_back(h);
        }
      }
      return 0;
    };
    while (true) {
      const int ra = step(qa, ia, mark_a, mark_b);
      if (ra != 0) return ra > 0;
      const int rb = step(qb, ib, mark_b, mark_a);
      if (rb != 0) return rb > 0;
    }
  }

  // Which of f's edge neighbours lie in f's patch, one bit per edge.
  int InPatchMask(int f) const {
    int mask = 0;
    for (int e = 0; e < 3; ++e) {
      const int h = p_.neighbours[f][e];
      if (h >= 0 && g_[h] == g_[f]) mask |= 1 << e;
    }
    return mask;
  }

  // A removal found disconnecting stays so while its patch gains no face and keeps f's in-patch neighbours:
  // the patch without f is then a subgraph of what it was, so the neighbours stay apart.
  void RememberDisconnecting(int f) {
    if (disconnecting_.empty()) disconnecting_.assign(g_.size(), DisconnectingRemoval{});
    disconnecting_[f] = {g_[f], additions_[g_[f]], InPatchMask(f)};
  }

  bool KnownDisconnecting(int f) const {
    if (disconnecting_.empty()) return false;
    const DisconnectingRemoval& known = disconnecting_[f];
    return known.patch == g_[f] && known.additions == additions_[g_[f]] && known.in_patch_mask == InPatchMask(f);
  }

  bool RemovalKeepsContiguous(int f) {
    const int k = g_[f];
    const auto& nb = p_.neighbours[f];
    const auto& c = p_.corners[f];
    int in[3];
    int count = 0;
    for (int e = 0; e < 3; ++e) {
      in[e] = (nb[e] >= 0 && g_[nb[e]] == k) ? 1 : 0;
      count += in[e];
    }
    if (count <= 1) return true;
    if (KnownDisconnecting(f)) return false;
    // Union-find over the (up to) three in-patch neighbours; neighbours e and e+1 share corner e+1.
    int parent[3] = {0, 1, 2};
    auto find = [&](int x) {
      while (parent[x] != x) x = parent[x];
      return x;
    };
    for (int e = 0; e < 3; ++e) {
      const int e2 = (e + 1) % 3;
      if (!in[e] || !in[e2]) continue;
      if (find(e) == find(e2)) continue;
      if (FanConnects(f, nb[e], nb[e2], c[e2], k)) parent[find(e)] = find(e2);
    }
    int reps[3], nrep = 0;
    for (int e = 0; e < 3; ++e) {
      if (in[e] && find(e) == e) reps[nrep++] = e;
    }
    for (int r = 1; r < nrep; ++r) {
      if (!BfsConnects(f, nb[reps[0]], nb[reps[r]], k)) return false;
    }
    return true;
  }

  const DecimationProblem& p_;
  double lambda_;
  int d_;
  double eps_;
  PartitionStats* stats_ = nullptr;
  std::vector<int> g_;
  std::vector<double> W_, Q_, S_;
  std::vector<int> size_, version_, alias_, head_;
  std::vector<char> alive_;
  std::vector<char> dirty_, seed_dirty_;
  std::vector<int> candidate_stamp_, candidates_;  // CollectByFace's faces to visit
  int candidate_round_ = 0;
  std::vector<int> next_, prev_;
  std::vector<int> mark_;
  std::vector<int> bfs_a_, bfs_b_;  // BfsConnects' queues, kept between calls
  std::vector<int> additions_;       // per patch, faces it has gained (moves in, fuses)
  // Per face, the last removal found disconnecting (patch -1: none); allocated on the first one.
  struct DisconnectingRemoval {
    int patch = -1;
    int additions = 0;      // the patch's additions_ then
    int in_patch_mask = 0;  // InPatchMask then
  };
  std::vector<DisconnectingRemoval> disconnecting_;
  int stamp_ = 0;
  std::vector<FuseEntry> seed_;  // the fuse phase's sorted seed candidates
};

}  // namespace

std::vector<int> HillClimbPartition(const DecimationProblem& problem, double lambda,
                                    const PartitionOptions& options, PartitionStats* stats) {
  RB_CHECK(lambda > 0.0 && std::isfinite(lambda), "decimation: lambda must be positive and finite, got ", lambda);
  RB_CHECK(options.max_rounds >= 1, "decimation: max_rounds must be at least 1");
  const int nf = problem.num_faces();
  RB_CHECK(problem.dim > 0 && problem.normals.size() == static_cast<size_t>(nf) * problem.dim &&
               problem.neighbours.size() == static_cast<size_t>(nf) && problem.corners.size() == static_cast<size_t>(nf),
           "decimation: inconsistent problem sizes");
  if (options.initial != nullptr && !options.initial->empty()) {
    RB_CHECK(options.initial->size() == static_cast<size_t>(nf), "decimation: initial partition has ",
             options.initial->size(), " entries for ", nf, " faces");
    for (int k : *options.initial) {
      RB_CHECK(k >= 0 && k < nf, "decimation: initial partition id ", k, " out of [0, ", nf, ")");
    }
  }
  Climber climber(problem, lambda, options.initial);
  return climber.Run(options, stats);
}

double PartitionEnergy(const DecimationProblem& problem, const std::vector<int>& face_patch, double lambda,
                       double* data_energy) {
  const int d = problem.dim;
  int num = 0;
  for (int k : face_patch) num = std::max(num, k + 1);
  std::vector<double> w(num, 0.0), s(static_cast<size_t>(num) * d, 0.0);
  std::vector<char> used(num, 0);
  for (int f = 0; f < problem.num_faces(); ++f) {
    const int k = face_patch[f];
    used[k] = 1;
    w[k] += problem.weight[f];
    for (int c = 0; c < d; ++c) s[static_cast<size_t>(k) * d + c] += problem.weight[f] * problem.normals[static_cast<size_t>(f) * d + c];
  }
  double data = 0.0;
  for (int f = 0; f < problem.num_faces(); ++f) {
    const int k = face_patch[f];
    if (w[k] <= 1e-300) continue;
    double r = 0.0;
    for (int c = 0; c < d; ++c) {
      const double v = problem.normals[static_cast<size_t>(f) * d + c] - s[static_cast<size_t>(k) * d + c] / w[k];
      r += v * v;
    }
    data += problem.weight[f] * r;
  }
  int patches = 0;
  for (char u : used) patches += u;
  if (data_energy != nullptr) *data_energy = data;
  return lambda * patches + data;
}

bool PartitionIsContiguous(const DecimationProblem& problem, const std::vector<int>& face_patch) {
  const int nf = problem.num_faces();
  int num = 0;
  for (int k : face_patch) num = std::max(num, k + 1);
  std::vector<char> seen_patch(num, 0), visited(nf, 0);
  for (int f = 0; f < nf; ++f) {
    if (visited[f]) continue;
    const int k = face_patch[f];
    if (seen_patch[k]) return false;  // a second component of patch k
    seen_patch[k] = 1;
    std::vector<int> stack{f};
    visited[f] = 1;
    while (!stack.empty()) {
      const int x = stack.back();
      stack.pop_back();
      for (int h : problem.neighbours[x]) {
        if (h >= 0 && !visited[h] && face_patch[h] == k) {
          visited[h] = 1;
          stack.push_back(h);
        }
      }
    }
  }
  return true;
}

}  // namespace rangebayes
