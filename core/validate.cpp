#include "core/validate.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>

#include "core/error.h"

namespace rangebayes {

void ValidateMeshOptions::Check() const {
  RB_CHECK(zero_area_relative >= 0 && zero_area_relative < 0.5, "zero_area_relative must be in [0, 0.5), got ",
           zero_area_relative);
}

bool MeshValidation::clean() const {
  return out_of_range_indices == 0 && degenerate_faces == 0 && zero_area_faces == 0 && duplicate_faces == 0 &&
         non_finite_vertices == 0 && out_of_scale_vertices == 0 && below_scale_extent == 0 &&
         unreferenced_vertices == 0 && non_manifold_edges == 0 && non_manifold_vertices == 0 && inconsistent_edges == 0;
}

namespace {

int Find(std::vector<int>& parent, int x) {
  while (parent[static_cast<size_t>(x)] != x) {
    parent[static_cast<size_t>(x)] = parent[static_cast<size_t>(parent[static_cast<size_t>(x)])];
    x = parent[static_cast<size_t>(x)];
  }
  return x;
}

void Unite(std::vector<int>& parent, int a, int b) {
  a = Find(parent, a);
  b = Find(parent, b);
  if (a != b) parent[static_cast<size_t>(std::max(a, b))] = std::min(a, b);
}

// Vertex and face counts; returns the faces fit for the edge-based checks (indices in range, three distinct
// vertices).
std::vector<int> CountVertexAndFaceProblems(const Mesh& mesh, const ValidateMeshOptions& options,
                                            MeshValidation* out) {
  MeshValidation& result = *out;
  const int64_t nv = mesh.V.rows();
  const int64_t nf = mesh.F.rows();
  std::vector<char> finite(static_cast<size_t>(nv), 1);
  for (int64_t v = 0; v < nv; ++v) {
    if (!mesh.V.row(v).allFinite()) {
      finite[static_cast<size_t>(v)] = 0;
      ++result.non_finite_vertices;
      continue;
    }
    if (mesh.V.row(v).cwiseAbs().maxCoeff() > kMaxCoordinate) ++result.out_of_scale_vertices;
  }
  Eigen::RowVector3d lo, hi;
  if (FiniteBoundingBox(mesh.V, &lo, &hi) && (lo.array() < hi.array()).any() && (hi - lo).stableNorm() < kMinExtent) {
    result.below_scale_extent = 1;
  }

  std::vector<int> good;
  good.reserve(static_cast<size_t>(nf));
  std::vector<char> used(static_cast<size_t>(nv), 0);
  std::vector<std::array<int, 3>> sorted_faces;
  sorted_faces.reserve(static_cast<size_t>(nf));
  for (int64_t f = 0; f < nf; ++f) {
    const int a = mesh.F(f, 0), b = mesh.F(f, 1), c = mesh.F(f, 2);
    int bad = 0;
    for (const int v : {a, b, c}) bad += (v < 0 || v >= nv) ? 1 : 0;
    if (bad > 0) {
      result.out_of_range_indices += bad;
      continue;
    }
    for (const int v : {a, b, c}) used[static_cast<size_t>(v)] = 1;
    std::array<int, 3> key = {a, b, c};
    std::sort(key.begin(), key.end());
    sorted_faces.push_back(key);
    if (a == b || b == c || a == c) {
      ++result.degenerate_faces;
      continue;
    }
    good.push_back(static_cast<int>(f));
    if (finite[static_cast<size_t>(a)] && finite[static_cast<size_t>(b)] && finite[static_cast<size_t>(c)]) {
      // Scaled by a power of two (exact) so that the products below neither overflow nor underflow.
      const double largest = std::max({mesh.V.row(a).cwiseAbs().maxCoeff(), mesh.V.row(b).cwiseAbs().maxCoeff(),
                                       mesh.V.row(c).cwiseAbs().maxCoeff()});
      const double scale = largest > 0 ? std::ldexp(1.0, -std::ilogb(largest)) : 1.0;
      const Eigen::RowVector3d pa = scale * mesh.V.row(a), pb = scale * mesh.V.row(b), pc = scale * mesh.V.row(c);
      const double area = 0.5 * (pb - pa).cross(pc - pa).norm();
      const double longest =
          std::max({(pb - pa).squaredNorm(), (pc - pb).squaredNorm(), (pa - pc).squaredNorm()});
      if (area <= options.zero_area_relative * longest) ++result.zero_area_faces;
    }
  }
  for (int64_t v = 0; v < nv; ++v) result.unreferenced_vertices += used[static_cast<size_t>(v)] ? 0 : 1;
  std::sort(sorted_faces.begin(), sorted_faces.end());
  result.duplicate_faces = static_cast<int64_t>(sorted_faces.size()) -
                           (std::unique(sorted_faces.begin(), sorted_faces.end()) - sorted_faces.begin());

  return good;
}

void CountEdgeProblems(const Mesh& mesh, const std::vector<int>& good, MeshValidation* out) {
  MeshValidation& result = *out;
  // Edges: one record per face side, (low, high) with the direction the face runs along it.
  struct Side {
    int low, high, face;
    bool forward;
  };
  std::vector<Side> sides;
  sides.reserve(3 * good.size());
  for (const int f : good) {
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.F(f, k), b = mesh.F(f, (k + 1) % 3);
      sides.push_back({std::min(a, b), std::max(a, b), f, a < b});
    }
  }
  std::sort(sides.begin(), sides.end(), [](const Side& s, const Side& t) {
    return s.low != t.low ? s.low < t.low : (s.high != t.high ? s.high < t.high : s.face < t.face);
  });
  for (size_t i = 0; i < sides.size();) {
    size_t j = i + 1;
    while (j < sides.size() && sides[j].low == sides[i].low && sides[j].high == sides[i].high) ++j;
    const size_t count = j - i;
    if (count == 1) {
      ++result.boundary_edges;
    } else if (count == 2) {
      if (sides[i].forward == sides[i + 1].forward) ++result.inconsistent_edges;
    } else {
      ++result.non_manifold_edges;
    }
    i = j;
  }
}

void CountBowTies(const Mesh& mesh, const std::vector<int>& good, MeshValidation* out) {
  MeshValidation& result = *out;
  // Fans: corners at the same vertex are joined when their faces share an edge through that vertex; a
  // vertex whose corners fall into more than one group is a bow tie.
  const size_t num_corners = 3 * good.size();
  std::vector<int> parent(num_corners);
  std::iota(parent.begin(), parent.end(), 0);
  struct Spoke {
    int vertex, other, corner;
  };
  std::vector<Spoke> spokes;
  spokes.reserve(2 * num_corners);
  for (size_t g = 0; g < good.size(); ++g) {
    const int f = good[g];
    for (int k = 0; k < 3; ++k) {
      const int corner = static_cast<int>(3 * g) + k;
      spokes.push_back({mesh.F(f, k), mesh.F(f, (k + 1) % 3), corner});
      spokes.push_back({mesh.F(f, k), mesh.F(f, (k + 2) % 3), corner});
    }
  }
  std::sort(spokes.begin(), spokes.end(), [](const Spoke& s, const Spoke& t) {
    return s.vertex != t.vertex ? s.vertex < t.vertex : s.other < t.other;
  });
  for (size_t i = 1; i < spokes.size(); ++i) {
    if (spokes[i].vertex == spokes[i - 1].vertex && spokes[i].other == spokes[i - 1].other) {
      Unite(parent, spokes[i].corner, spokes[i - 1].corner);
    }
  }
  std::vector<std::pair<int, int>> vertex_group;
  vertex_group.reserve(num_corners);
  for (size_t g = 0; g < good.size(); ++g) {
    for (int k = 0; k < 3; ++k) {
      const int corner = static_cast<int>(3 * g) + k;
      vertex_group.emplace_back(mesh.F(good[g], k), Find(parent, corner));
    }
  }
  std::sort(vertex_group.begin(), vertex_group.end());
  vertex_group.erase(std::unique(vertex_group.begin(), vertex_group.end()), vertex_group.end());
  for (size_t i = 1; i < vertex_group.size(); ++i) {
    // Count each bow-tie vertex once, at its second group.
    if (vertex_group[i].first == vertex_group[i - 1].first &&
        (i < 2 || vertex_group[i - 2].first != vertex_group[i].first)) {
      ++result.non_manifold_vertices;
    }
  }
}

}  // namespace

MeshValidation ValidateMesh(const Mesh& mesh, const ValidateMeshOptions& options) {
  options.Check();
  MeshValidation result;
  const std::vector<int> good = CountVertexAndFaceProblems(mesh, options, &result);
  CountEdgeProblems(mesh, good, &result);
  CountBowTies(mesh, good, &result);
  return result;
}

void CheckComputableScale(const Vertices& V, std::string_view what) {
  Eigen::Index first = -1, count = 0;
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    if (V.row(i).allFinite()) continue;
    if (first < 0) first = i;
    ++count;
  }
  RB_CHECK(count == 0, what, ": ", count, " of ", V.rows(), " vertices have non-finite coordinates (the first: vertex ",
           first, " at (", first < 0 ? 0.0 : V(first, 0), ", ", first < 0 ? 0.0 : V(first, 1), ", ",
           first < 0 ? 0.0 : V(first, 2), "))");
  for (Eigen::Index i = 0; i < V.rows(); ++i) {
    RB_CHECK(V.row(i).cwiseAbs().maxCoeff() <= kMaxCoordinate, what, ": vertex ", i, " lies at (", V(i, 0), ", ",
             V(i, 1), ", ", V(i, 2), "), beyond ±", kMaxCoordinate,
             ", where lengths squared and areas overflow: rescale the mesh (for example to metres)");
  }
  const Eigen::RowVector3d extent = BoundingBoxExtent(V);
  RB_CHECK(!(extent.array() > 0).any() || extent.stableNorm() >= kMinExtent, what, ": the mesh spans only ",
           extent.stableNorm(), ", below ", kMinExtent,
           ", where lengths squared and areas underflow: rescale the mesh (for example to millimetres)");
}

std::vector<std::string> DescribeFindings(const MeshValidation& v) {
  std::vector<std::string> lines;
  auto add = [&lines](int64_t count, const std::string& what) {
    if (count > 0) lines.push_back(StrCat(count, " ", what));
  };
  add(v.out_of_range_indices, "face indices out of range");
  add(v.degenerate_faces, "degenerate faces (a vertex used twice)");
  add(v.zero_area_faces, "zero-area faces");
  add(v.duplicate_faces, "duplicate faces");
  add(v.non_finite_vertices, "vertices with non-finite coordinates");
  add(v.out_of_scale_vertices,
      StrCat("vertices with a coordinate beyond ±", kMaxCoordinate, " (too large to compute with: rescale the mesh)"));
  if (v.below_scale_extent > 0) {
    lines.push_back(StrCat("an extent below ", kMinExtent, " (too small to compute with: rescale the mesh)"));
  }
  add(v.unreferenced_vertices, "unreferenced vertices");
  add(v.non_manifold_edges, "non-manifold edges (three or more faces)");
  add(v.non_manifold_vertices, "non-manifold vertices (more than one fan)");
  add(v.inconsistent_edges, "edges with inconsistent face orientation");
  return lines;
}

}  // namespace rangebayes
