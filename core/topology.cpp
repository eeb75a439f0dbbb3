#include "core/topology.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>

#include "core/error.h"

namespace rangebayes {
namespace {

void CheckIndices(const Mesh& mesh) {
  const int n = mesh.num_vertices();
  for (int f = 0; f < mesh.num_faces(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int v = mesh.F(f, k);
      RB_CHECK(v >= 0 && v < n, "face ", f, " refers to vertex ", v, ", but the mesh has ", n, " vertices");
    }
  }
}

// Union-find with path halving.
int Find(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}
void Unite(std::vector<int>& parent, int a, int b) {
  a = Find(parent, a);
  b = Find(parent, b);
  if (a != b) parent[std::max(a, b)] = std::min(a, b);
}

Adjacency BuildAdjacency(int rows, const std::vector<std::pair<int, int>>& sorted_pairs) {
  Adjacency adjacency;
  adjacency.offsets.assign(rows + 1, 0);
  for (const auto& [row, item] : sorted_pairs) ++adjacency.offsets[row + 1];
  std::partial_sum(adjacency.offsets.begin(), adjacency.offsets.end(), adjacency.offsets.begin());
  adjacency.items.reserve(sorted_pairs.size());
  for (const auto& [row, item] : sorted_pairs) adjacency.items.push_back(item);
  return adjacency;
}

}  // namespace

EdgeTopology ComputeEdgeTopology(const Mesh& mesh) {
  CheckIndices(mesh);
  const int num_faces = mesh.num_faces();
  // Key each directed half-edge by its sorted vertex pair; sorting groups the halves of one edge.
  struct HalfEdge {
    std::uint64_t key;
    int face;
    int corner;
  };
  // Ordered by (key, face, corner): bucketed by the smaller vertex (a counting sort, linear; a comparison sort
  // of every half-edge was most of this function on large meshes), each bucket filled in (face, corner) order
  // and then sorted stably by the larger vertex.
  std::vector<int> bucket_start(static_cast<size_t>(mesh.num_vertices()) + 1, 0);
  for (int f = 0; f < num_faces; ++f) {
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.F(f, k), b = mesh.F(f, (k + 1) % 3);
      if (a != b) ++bucket_start[static_cast<size_t>(std::min(a, b)) + 1];
    }
  }
  for (size_t v = 1; v < bucket_start.size(); ++v) bucket_start[v] += bucket_start[v - 1];
  std::vector<HalfEdge> halves(static_cast<size_t>(bucket_start.back()));
  {
    std::vector<int> fill(bucket_start.begin(), bucket_start.end() - 1);
    for (int f = 0; f < num_faces; ++f) {
      for (int k = 0; k < 3; ++k) {
        int a = mesh.F(f, k);
        int b = mesh.F(f, (k + 1) % 3);
        if (a == b) continue;
        if (a > b) std::swap(a, b);
        const std::uint64_t key = (static_cast<std::uint64_t>(a) << 32) | static_cast<std::uint32_t>(b);
        halves[static_cast<size_t>(fill[a]++)] = {key, f, k};
      }
    }
  }
  for (size_t v = 0; v + 1 < bucket_start.size(); ++v) {
    // A bucket holds a vertex's edges to larger vertices, usually a handful: insertion sort, stable.
    if (bucket_start[v + 1] - bucket_start[v] > 32) {
      std::stable_sort(halves.begin() + bucket_start[v], halves.begin() + bucket_start[v + 1],
                       [](const HalfEdge& x, const HalfEdge& y) { return x.key < y.key; });
      continue;
    }
    for (int i = bucket_start[v] + 1; i < bucket_start[v + 1]; ++i) {
      const HalfEdge h = halves[static_cast<size_t>(i)];
      int j = i;
      for (; j > bucket_start[v] && halves[static_cast<size_t>(j - 1)].key > h.key; --j) {
        halves[static_cast<size_t>(j)] = halves[static_cast<size_t>(j - 1)];
      }
      halves[static_cast<size_t>(j)] = h;
    }
  }

  EdgeTopology topology;
  topology.face_edges.setConstant(num_faces, 3, -1);
  std::vector<std::uint64_t> keys;
  std::vector<std::pair<int, int>> edge_face;
  edge_face.reserve(halves.size());
  for (const HalfEdge& h : halves) {
    if (keys.empty() || keys.back() != h.key) keys.push_back(h.key);
    const int e = static_cast<int>(keys.size()) - 1;
    topology.face_edges(h.face, h.corner) = e;
    // A face listing the same edge twice (a degenerate fold) is incident to it once.
    if (edge_face.empty() || edge_face.back() != std::make_pair(e, h.face)) edge_face.emplace_back(e, h.face);
  }
  topology.edges.resize(static_cast<Eigen::Index>(keys.size()), 2);
  for (size_t e = 0; e < keys.size(); ++e) {
    topology.edges(static_cast<Eigen::Index>(e), 0) = static_cast<int>(keys[e] >> 32);
    topology.edges(static_cast<Eigen::Index>(e), 1) = static_cast<int>(keys[e] & 0xffffffffu);
  }
  topology.edge_faces = BuildAdjacency(static_cast<int>(keys.size()), edge_face);
  return topology;
}

IndexPairs ComputeFacePairs(const EdgeTopology& topology) {
  std::vector<std::pair<int, int>> pairs;
  const Adjacency& ef = topology.edge_faces;
  pairs.reserve(ef.items.size());
  for (int e = 0; e < ef.rows(); ++e) {
    for (const int* s = ef.begin(e); s != ef.end(e); ++s) {
      for (const int* t = s + 1; t != ef.end(e); ++t) pairs.emplace_back(std::min(*s, *t), std::max(*s, *t));
    }
  }
  std::sort(pairs.begin(), pairs.end());
  // Two faces sharing two edges (a fold) still form one pair.
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  IndexPairs out(static_cast<Eigen::Index>(pairs.size()), 2);
  for (size_t i = 0; i < pairs.size(); ++i) {
    out(static_cast<Eigen::Index>(i), 0) = pairs[i].first;
    out(static_cast<Eigen::Index>(i), 1) = pairs[i].second;
  }
  return out;
}

IndexPairs ComputeFacePairs(const Mesh& mesh) { return ComputeFacePairs(ComputeEdgeTopology(mesh)); }

std::vector<std::vector<int>> ComputeBoundaryLoops(const Mesh& mesh, const EdgeTopology& topology) {
  // Directed boundary half-edges in the orientation of their face, so loops follow the face winding.
  std::vector<std::pair<int, int>> next_of;  // (from, to)
  for (int f = 0; f < mesh.num_faces(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int e = topology.face_edges(f, k);
      if (e >= 0 && topology.edge_faces.size(e) == 1) next_of.emplace_back(mesh.F(f, k), mesh.F(f, (k + 1) % 3));
    }
  }
  std::sort(next_of.begin(), next_of.end());
  std::vector<char> used(next_of.size(), 0);
  auto find_unused_from = [&](int v) -> int {
    auto it = std::lower_bound(next_of.begin(), next_of.end(), std::make_pair(v, -1));
    for (; it != next_of.end() && it->first == v; ++it) {
      const size_t i = static_cast<size_t>(it - next_of.begin());
      if (!used[i]) return static_cast<int>(i);
    }
    return -1;
  };
  std::vector<std::vector<int>> loops;
  for (size_t start = 0; start < next_of.size(); ++start) {
    if (used[start]) continue;
    std::vector<int> loop;
    int i = static_cast<int>(start);
    const int first = next_of[start].first;
    while (i >= 0) {
      used[static_cast<size_t>(i)] = 1;
      loop.push_back(next_of[static_cast<size_t>(i)].first);
      const int to = next_of[static_cast<size_t>(i)].second;
      if (to == first) break;
      i = find_unused_from(to);
    }
    loops.push_back(std::move(loop));
  }
  return loops;
}

Adjacency ComputeVertexNeighbours(const Mesh& mesh, const EdgeTopology& topology) {
  std::vector<std::pair<int, int>> pairs;
  pairs.reserve(static_cast<size_t>(topology.edges.rows()) * 2);
  for (Eigen::Index e = 0; e < topology.edges.rows(); ++e) {
    pairs.emplace_back(topology.edges(e, 0), topology.edges(e, 1));
    pairs.emplace_back(topology.edges(e, 1), topology.edges(e, 0));
  }
  std::sort(pairs.begin(), pairs.end());
  return BuildAdjacency(mesh.num_vertices(), pairs);
}

Adjacency ComputeVertexFaces(const Mesh& mesh) {
  CheckIndices(mesh);
  // A counting sort: faces ascending per vertex, a corner that repeats an earlier corner's vertex skipped.
  const int nf = mesh.num_faces(), nv = mesh.num_vertices();
  auto repeated = [&](int f, int k) {
    return (k >= 1 && mesh.F(f, k) == mesh.F(f, 0)) || (k == 2 && mesh.F(f, 2) == mesh.F(f, 1));
  };
  Adjacency adjacency;
  adjacency.offsets.assign(static_cast<size_t>(nv) + 1, 0);
  for (int f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      if (!repeated(f, k)) ++adjacency.offsets[static_cast<size_t>(mesh.F(f, k)) + 1];
    }
  }
  for (int v = 0; v < nv; ++v) {
    adjacency.offsets[static_cast<size_t>(v) + 1] += adjacency.offsets[static_cast<size_t>(v)];
  }
  adjacency.items.resize(static_cast<size_t>(adjacency.offsets.back()));
  std::vector<int> fill(adjacency.offsets.begin(), adjacency.offsets.end() - 1);
  for (int f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      if (!repeated(f, k)) adjacency.items[static_cast<size_t>(fill[static_cast<size_t>(mesh.F(f, k))]++)] = f;
    }
  }
  return adjacency;
}

IndexPairs ComputeFacePairs(const Mesh& mesh, const Adjacency& vertex_faces) {
  const int nf = mesh.num_faces();
  std::vector<int> flat;
  flat.reserve(static_cast<size_t>(nf) * 3);
  std::vector<int> partners;
  for (int s = 0; s < nf; ++s) {
    partners.clear();
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.F(s, k), b = mesh.F(s, (k + 1) % 3);
      if (a == b) continue;
      for (const int* t = vertex_faces.begin(a); t != vertex_faces.end(a); ++t) {
        if (*t <= s) continue;
        if (mesh.F(*t, 0) == b || mesh.F(*t, 1) == b || mesh.F(*t, 2) == b) partners.push_back(*t);
      }
    }
    std::sort(partners.begin(), partners.end());
    partners.erase(std::unique(partners.begin(), partners.end()), partners.end());
    for (int t : partners) {
      flat.push_back(s);
      flat.push_back(t);
    }
  }
  IndexPairs pairs(static_cast<Eigen::Index>(flat.size() / 2), 2);
  std::copy(flat.begin(), flat.end(), pairs.data());
  return pairs;
}

Components ComputeComponents(const Mesh& mesh, Connectivity connectivity) {
  const int num_faces = mesh.num_faces();
  std::vector<int> parent(static_cast<size_t>(num_faces));
  std::iota(parent.begin(), parent.end(), 0);
  if (connectivity == Connectivity::kSharedEdge) {
    const EdgeTopology topology = ComputeEdgeTopology(mesh);
    for (int e = 0; e < topology.edge_faces.rows(); ++e) {
      const int* first = topology.edge_faces.begin(e);
      for (const int* f = first + 1; f != topology.edge_faces.end(e); ++f) Unite(parent, *first, *f);
    }
  } else {
    const Adjacency vf = ComputeVertexFaces(mesh);
    for (int v = 0; v < vf.rows(); ++v) {
      if (vf.size(v) == 0) continue;
      const int* first = vf.begin(v);
      for (const int* f = first + 1; f != vf.end(v); ++f) Unite(parent, *first, *f);
    }
  }
  Components components;
  components.face_label.assign(static_cast<size_t>(num_faces), -1);
  std::vector<int> label_of_root(static_cast<size_t>(num_faces), -1);
  for (int f = 0; f < num_faces; ++f) {
    const int root = Find(parent, f);
    if (label_of_root[static_cast<size_t>(root)] < 0) label_of_root[static_cast<size_t>(root)] = components.count++;
    components.face_label[static_cast<size_t>(f)] = label_of_root[static_cast<size_t>(root)];
  }
  return components;
}

double MeanEdgeLength(const Mesh& mesh, const EdgeTopology& topology) {
  if (topology.edges.rows() == 0) return 0.0;
  const auto n = static_cast<double>(topology.edges.rows());
  auto length = [&](Eigen::Index e) {
    const Eigen::RowVector3d d = mesh.V.row(topology.edges(e, 0)) - mesh.V.row(topology.edges(e, 1));
    const double plain = d.norm();
    // The squares of lengths beyond about 1e±154 overflow or underflow; stableNorm scales first.
    return plain > 1e-150 && plain < 1e150 ? plain : d.stableNorm();
  };
  double sum = 0.0;
  for (Eigen::Index e = 0; e < topology.edges.rows(); ++e) sum += length(e);
  if (std::isfinite(sum) || std::isnan(sum)) return sum / n;
  sum = 0.0;  // the sum overflowed: lengths near the largest double; the mean of the shares does not
  for (Eigen::Index e = 0; e < topology.edges.rows(); ++e) sum += length(e) / n;
  return sum;
}

double MeanEdgeLength(const Mesh& mesh) { return MeanEdgeLength(mesh, ComputeEdgeTopology(mesh)); }

}  // namespace rangebayes
