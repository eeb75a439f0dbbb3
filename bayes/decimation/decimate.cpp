#include "bayes/decimation/decimate.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <Eigen/Dense>
#include <Eigen/Sparse>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <numeric>
#include <string>
#include <unordered_map>

#include "bayes/decimation/decimate_geometry.h"
#include "bayes/decimation/decimate_partition.h"
#include "bayes/decimation/decimate_refit.h"
#include "core/error.h"
#include "core/topology.h"
#include "core/validate.h"

namespace rangebayes {
namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

// The input made ready for the algorithm: faces that repeat a vertex dropped, non-manifold vertices and
// edges cut apart (each fan of faces around a vertex gets its own copy), unreferenced vertices dropped.
struct Prepared {
  Faces F;                         // faces over split vertex ids
  std::vector<int> kept_faces;     // per prepared face, its input face
  std::vector<int> split_source;   // per split vertex, its input vertex
  // Per split vertex: its input vertex where that has several copies (welded back after decimation), else −1.
  std::vector<int> weld_group;
  std::vector<char> locked;        // weld_group ≥ 0, as the refit's `fixed` takes it
  std::vector<Vertices> poses;     // per pose, positions of the split vertices
  EdgeTopology topology;           // of F
  std::vector<char> boundary_vertex;
  std::vector<std::string> notices;
  // Components of the input (faces joined through shared vertices) when the cut made pieces of some; 0: none cut.
  int input_components = 0;
};

int Find(std::vector<int>& parent, int i) {
  while (parent[i] != i) {
    parent[i] = parent[parent[i]];
    i = parent[i];
  }
  return i;
}

// Throws unless every pose has pose 1's connectivity and positions within the scale of CheckComputableScale.
void CheckPoses(const std::vector<Mesh>& poses) {
  for (size_t m = 0; m < poses.size(); ++m) {
    const std::string difference = ConnectivityDifference(poses[0], poses[m]);
    RB_CHECK(difference.empty(), "decimate: pose ", m + 1, " does not have the connectivity of pose 1: ", difference);
    CheckComputableScale(poses[m].V, StrCat("decimate: pose ", m + 1));
  }
}

// base without the faces that repeat a vertex (their input ids into out->kept_faces, a notice when any);
// throws on a face index outside [0, #V) or when no face is left.
Mesh DropRepeatingFaces(const Mesh& base, Prepared* out) {
  const int nv = base.num_vertices();
  RB_CHECK(base.num_faces() > 0, "decimate: the mesh has no faces");
  for (int f = 0; f < base.num_faces(); ++f) {
    for (int k = 0; k < 3; ++k) {
      RB_CHECK(base.F(f, k) >= 0 && base.F(f, k) < nv, "decimate: face ", f, " refers to vertex ", base.F(f, k),
               ", but the mesh has ", nv, " vertices");
    }
    if (base.F(f, 0) == base.F(f, 1) || base.F(f, 1) == base.F(f, 2) || base.F(f, 0) == base.F(f, 2)) continue;
    out->kept_faces.push_back(f);
  }
  const int dropped = base.num_faces() - static_cast<int>(out->kept_faces.size());
  if (dropped > 0) out->notices.push_back(StrCat(dropped, " faces repeat a vertex; they were dropped"));
  RB_CHECK(!out->kept_faces.empty(), "decimate: every face repeats a vertex");
  Mesh mesh;
  mesh.V = base.V;
  mesh.F.resize(static_cast<Eigen::Index>(out->kept_faces.size()), 3);
  for (size_t i = 0; i < out->kept_faces.size(); ++i) {
    mesh.F.row(static_cast<Eigen::Index>(i)) = base.F.row(out->kept_faces[i]);
  }
  return mesh;
}

// Union-find over the corners (3f + k) of mesh, joined across manifold, consistently oriented edges; counts
// the edges with more than two faces and those whose two faces disagree in orientation.
std::vector<int> JoinCorners(const Mesh& mesh, const EdgeTopology& topology, int* nonmanifold_edges,
                             int* flipped_edges) {
  const int nf = mesh.num_faces();
  std::vector<int> parent(static_cast<size_t>(nf) * 3);
  std::iota(parent.begin(), parent.end(), 0);
  for (int e = 0; e < topology.edge_faces.rows(); ++e) {
    const int count = topology.edge_faces.size(e);
    if (count > 2) ++*nonmanifold_edges;
    if (count != 2) continue;
    const int f = topology.edge_faces.begin(e)[0], g = topology.edge_faces.begin(e)[1];
    int kf = -1, kg = -1;
    for (int k = 0; k < 3; ++k) {
      if (topology.face_edges(f, k) == e) kf = k;
      if (topology.face_edges(g, k) == e) kg = k;
    }
    const int fa = mesh.F(f, kf), fb = mesh.F(f, (kf + 1) % 3);
    const int ga = mesh.F(g, kg), gb = mesh.F(g, (kg + 1) % 3);
    if (!(fa == gb && fb == ga)) {
      ++*flipped_edges;
      continue;
    }
    // corner kf of f holds fa = gb (corner kg+1 of g); corner kf+1 of f holds fb = ga (corner kg of g).
    auto unite = [&](int a, int b) {
      a = Find(parent, a);
      b = Find(parent, b);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    };
    unite(3 * f + kf, 3 * g + (kg + 1) % 3);
    unite(3 * f + (kf + 1) % 3, 3 * g + kg);
  }
  return parent;
}

// One split vertex per corner class, numbered in order of first corner: fills out->F and out->split_source.
void NumberSplitVertices(const Mesh& mesh, std::vector<int>& parent, Prepared* out) {
  const int nf = mesh.num_faces();
  // Corners of one input vertex with no shared manifold edge can still be one fan only through a chain of
  // corners; the union of JoinCorners already follows those chains.
  std::vector<int> class_id(static_cast<size_t>(nf) * 3, -1);
  out->F.resize(nf, 3);
  for (int f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      const int root = Find(parent, 3 * f + k);
      int& id = class_id[static_cast<size_t>(root)];
      if (id < 0) {
        id = static_cast<int>(out->split_source.size());
        out->split_source.push_back(mesh.F(f, k));
      }
      out->F(f, k) = id;
    }
  }
}

// Locks the split vertices whose input vertex has several copies; counts the input vertices with several
// copies and those with none.
void LockSharedCopies(int nv, Prepared* out, int* split_vertices, int* unreferenced) {
  const int ns = static_cast<int>(out->split_source.size());
  std::vector<int> copies(nv, 0);
  for (int s : out->split_source) ++copies[s];
  out->weld_group.assign(ns, -1);
  out->locked.assign(ns, 0);
  for (int s = 0; s < ns; ++s) {
    if (copies[out->split_source[s]] > 1) {
      out->weld_group[s] = out->split_source[s];
      out->locked[s] = 1;
    }
  }
  for (int v = 0; v < nv; ++v) {
    if (copies[v] > 1) ++*split_vertices;
    if (copies[v] == 0) ++*unreferenced;
  }
}

// The split mesh's poses, edge topology (reused from the input's when the split is the identity) and
// boundary vertices.
void FinishSplitMesh(const std::vector<Mesh>& poses, bool identity, const EdgeTopology& topology, Prepared* out) {
  const int ns = static_cast<int>(out->split_source.size());
  out->poses.resize(poses.size());
  for (size_t m = 0; m < poses.size(); ++m) {
    out->poses[m].resize(ns, 3);
    for (int s = 0; s < ns; ++s) out->poses[m].row(s) = poses[m].V.row(out->split_source[s]);
  }
  if (identity) {
    out->topology = topology;
  } else {
    Mesh split;
    split.V = out->poses[0];
    split.F = out->F;
    out->topology = ComputeEdgeTopology(split);
  }
  out->boundary_vertex.assign(ns, 0);
  for (int e = 0; e < out->topology.edge_faces.rows(); ++e) {
    if (out->topology.edge_faces.size(e) == 1) {
      out->boundary_vertex[out->topology.edges(e, 0)] = 1;
      out->boundary_vertex[out->topology.edges(e, 1)] = 1;
    }
  }
}

Prepared Prepare(const std::vector<Mesh>& poses) {
  Prepared out;
  CheckPoses(poses);
  const int nv = poses[0].num_vertices();
  const Mesh mesh = DropRepeatingFaces(poses[0], &out);

  // Corners joined across manifold, consistently oriented edges; each class becomes one split vertex.
  const EdgeTopology topology = ComputeEdgeTopology(mesh);
  int nonmanifold_edges = 0, flipped_edges = 0;
  std::vector<int> parent = JoinCorners(mesh, topology, &nonmanifold_edges, &flipped_edges);
  NumberSplitVertices(mesh, parent, &out);
  const int ns = static_cast<int>(out.split_source.size());
  int split_vertices = 0, unreferenced = 0;
  LockSharedCopies(nv, &out, &split_vertices, &unreferenced);
  if (nonmanifold_edges > 0 || flipped_edges > 0 || split_vertices > 0) {
    out.notices.push_back(StrCat("non-manifold input (", nonmanifold_edges, " edges with more than two faces, ",
                                 flipped_edges, " edges with inconsistent orientation, ", split_vertices,
                                 " vertices shared by separate fans): cut apart there, those vertices kept and "
                                 "welded back in the output"));
  }
  if (unreferenced > 0) out.notices.push_back(StrCat(unreferenced, " vertices are not used by any face; dropped"));
  // The common case, a manifold mesh with every vertex used: keep the input's vertex ids so that its edge
  // topology (a sort of all half-edges, the largest cost of this preparation) serves the split mesh too.
  const bool identity = split_vertices == 0 && unreferenced == 0 && ns == nv;
  if (identity) {
    out.F = mesh.F;
    std::iota(out.split_source.begin(), out.split_source.end(), 0);
  }
  if (split_vertices > 0) out.input_components = ComputeComponents(mesh, Connectivity::kSharedVertex).count;
  FinishSplitMesh(poses, identity, topology, &out);
  return out;
}

// Per component of a manifold mesh: Euler characteristic and number of boundary loops, sorted.
std::vector<std::pair<int, int>> TopologySignature(int num_vertices, const Faces& F, const EdgeTopology& topology) {
  const int nf = static_cast<int>(F.rows());
  std::vector<int> parent(nf);
  std::iota(parent.begin(), parent.end(), 0);
  for (int e = 0; e < topology.edge_faces.rows(); ++e) {
    const int* first = topology.edge_faces.begin(e);
    for (const int* f = first + 1; f != topology.edge_faces.end(e); ++f) {
      const int a = Find(parent, *first), b = Find(parent, *f);
      if (a != b) parent[std::max(a, b)] = std::min(a, b);
    }
  }
  std::vector<int> label(nf, -1), root_label(nf, -1);
  int count = 0;
  for (int f = 0; f < nf; ++f) {
    const int r = Find(parent, f);
    if (root_label[r] < 0) root_label[r] = count++;
    label[f] = root_label[r];
  }
  std::vector<int> chi(count, 0), loops(count, 0);
  std::vector<int> vertex_comp(num_vertices, -1);
  for (int f = 0; f < nf; ++f) {
    ++chi[label[f]];
    for (int k = 0; k < 3; ++k) vertex_comp[F(f, k)] = label[f];
  }
  for (int v = 0; v < num_vertices; ++v) {
    if (vertex_comp[v] >= 0) ++chi[vertex_comp[v]];
  }
  for (int e = 0; e < topology.edge_faces.rows(); ++e) --chi[label[topology.edge_faces.begin(e)[0]]];
  Mesh mesh;
  mesh.F = F;
  mesh.V.setZero(num_vertices, 3);
  for (const auto& loop : ComputeBoundaryLoops(mesh, topology)) ++loops[vertex_comp[loop[0]]];
  std::vector<std::pair<int, int>> sig;
  for (int c = 0; c < count; ++c) sig.emplace_back(chi[c], loops[c]);
  std::sort(sig.begin(), sig.end());
  return sig;
}

std::vector<std::pair<int, int>> TopologySignature(int num_vertices, const Faces& F) {
  Mesh mesh;
  mesh.V.setZero(num_vertices, 3);
  mesh.F = F;
  return TopologySignature(num_vertices, F, ComputeEdgeTopology(mesh));
}

bool IsManifold(const Faces& F, int num_vertices) {
  Mesh mesh;
  mesh.V.setZero(num_vertices, 3);
  mesh.F = F;
  const EdgeTopology topology = ComputeEdgeTopology(mesh);
  for (int e = 0; e < topology.edge_faces.rows(); ++e) {
    if (topology.edge_faces.size(e) > 2) return false;
  }
  // A vertex whose faces fall into more than one fan: the fans around it are joined through edges that
  // contain it; check by local union.
  std::vector<std::vector<int>> faces_of(num_vertices);
  for (int f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) faces_of[F(f, k)].push_back(f);
  }
  for (int v = 0; v < num_vertices; ++v) {
    const auto& fs = faces_of[v];
    if (fs.size() <= 1) continue;
    std::vector<int> local(fs.size());
    std::iota(local.begin(), local.end(), 0);
    auto lfind = [&](int i) {
      while (local[i] != i) i = local[i];
      return i;
    };
    for (size_t i = 0; i < fs.size(); ++i) {
      for (size_t j = i + 1; j < fs.size(); ++j) {
        int shared = 0;
        for (int a = 0; a < 3; ++a) {
          for (int b = 0; b < 3; ++b) shared += F(fs[i], a) == F(fs[j], b) ? 1 : 0;
        }
        if (shared >= 2) {
          const int ri = lfind(static_cast<int>(i)), rj = lfind(static_cast<int>(j));
          if (ri != rj) local[ri] = rj;
        }
      }
    }
    int roots = 0;
    for (size_t i = 0; i < fs.size(); ++i) roots += lfind(static_cast<int>(i)) == static_cast<int>(i) ? 1 : 0;
    if (roots != 1) return false;
  }
  return true;
}

struct Problem {
  DecimationProblem problem;
  std::vector<double> weight;  // same as problem.weight, for the shading fit
};

Problem BuildProblem(const Prepared& prep, DecimateWeighting weighting, std::vector<std::string>* notices) {
  Problem out;
  DecimationProblem& p = out.problem;
  const int nf = static_cast<int>(prep.F.rows());
  const int M = static_cast<int>(prep.poses.size());
  p.dim = 3 * M;
  p.normals.assign(static_cast<size_t>(nf) * p.dim, 0.0);
  std::vector<double> area(static_cast<size_t>(nf) * M, 0.0);
  double diag2 = 0.0;
  for (int m = 0; m < M; ++m) {
    const Vertices& V = prep.poses[m];
    diag2 = std::max(diag2, BoundingBoxExtent(V).squaredNorm());
  }
  int zero_area = 0;
  std::vector<char> degenerate(nf, 0);
  for (int f = 0; f < nf; ++f) {
    for (int m = 0; m < M; ++m) {
      const Vertices& V = prep.poses[m];
      const Eigen::Vector3d a = V.row(prep.F(f, 0)).transpose(), b = V.row(prep.F(f, 1)).transpose(),
                            c = V.row(prep.F(f, 2)).transpose();
      const Eigen::Vector3d cr = (b - a).cross(c - a);
      const double len = cr.norm();
      if (len <= 1e-14 * diag2) {
        degenerate[f] = 1;
        continue;
      }
      area[static_cast<size_t>(f) * M + m] = 0.5 * len;
      for (int c2 = 0; c2 < 3; ++c2) p.normals[static_cast<size_t>(f) * p.dim + 3 * m + c2] = cr[c2] / len;
    }
    zero_area += degenerate[f];
  }
  if (zero_area > 0) {
    notices->push_back(StrCat(zero_area, " faces have zero area (in some pose); they get weight 0 in the energy"));
  }
  p.weight.assign(nf, 0.0);
  std::vector<double> mean_area(M, 0.0);
  for (int f = 0; f < nf; ++f) {
    for (int m = 0; m < M; ++m) mean_area[m] += area[static_cast<size_t>(f) * M + m] / nf;
  }
  for (int f = 0; f < nf; ++f) {
    if (degenerate[f]) {
      // Its normal is undefined in some pose: zero it in all so that it carries no information.
      std::fill_n(p.normals.begin() + static_cast<std::ptrdiff_t>(f) * p.dim, p.dim, 0.0);
      continue;
    }
    if (weighting == DecimateWeighting::kUniform) {
      p.weight[f] = 1.0;
    } else {
      double w = 0.0;
      for (int m = 0; m < M; ++m) w += mean_area[m] > 0.0 ? area[static_cast<size_t>(f) * M + m] / mean_area[m] : 0.0;
      p.weight[f] = w / M;
    }
  }
  // Normalise to mean 1 over faces (area weights already are, up to the degenerate ones).
  const double total = std::accumulate(p.weight.begin(), p.weight.end(), 0.0);
  if (total > 0.0) {
    for (double& w : p.weight) w *= nf / total;
  }
  const EdgeTopology& topology = prep.topology;
  p.neighbours.assign(nf, {-1, -1, -1});
  p.corners.resize(nf);
  for (int f = 0; f < nf; ++f) {
    for (int k = 0; k < 3; ++k) {
      p.corners[f][k] = prep.F(f, k);
      const int e = topology.face_edges(f, k);
      if (e < 0 || topology.edge_faces.size(e) != 2) continue;
      const int a = topology.edge_faces.begin(e)[0], b = topology.edge_faces.begin(e)[1];
      p.neighbours[f][k] = a == f ? b : a;
    }
  }
  out.weight = p.weight;
  return out;
}

struct Attempt {
  std::vector<int> face_patch;  // per prepared face
  int num_patches = 0;
  PatchTriangulation triangulation;
  PartitionStats stats;
  bool fell_back = false;
  double seconds_partition = 0.0, seconds_geometry = 0.0;
};

// initial: a partition to coarsen (the result at a smaller λ), or null to start from single faces.
Attempt PartitionOnce(const Problem& problem, double lambda, const DecimateOptions& options,
                      const ProgressCallback& progress, const std::vector<int>* initial = nullptr) {
  Attempt a;
  const auto t0 = Clock::now();
  PartitionOptions popts;
  popts.max_rounds = options.max_rounds;
  popts.progress = progress;
  popts.initial = initial;
  a.face_patch = HillClimbPartition(problem.problem, lambda, popts, &a.stats);
  a.num_patches = a.stats.num_patches;
  a.seconds_partition = Seconds(t0);
  return a;
}

// The safety net: never hand out a mesh of another topology. The dense faces with their patches are valid.
void CheckTopology(const Prepared& prep, const std::vector<std::pair<int, int>>& signature, Attempt* a) {
  a->fell_back = false;
  const int ns = static_cast<int>(prep.split_source.size());
  // On the used vertices renumbered (unused ones count in neither check), so that the checks of a small
  // output cost its size, not the dense mesh's.
  std::vector<int> compact(ns, -1);
  Faces F(a->triangulation.F.rows(), 3);
  int used = 0;
  for (Eigen::Index f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      int& id = compact[a->triangulation.F(f, k)];
      if (id < 0) id = used++;
      F(f, k) = id;
    }
  }
  if (TopologySignature(used, F) != signature || !IsManifold(F, used)) {
    a->fell_back = true;
    a->triangulation.F = prep.F;
    a->triangulation.face_patch = a->face_patch;
    a->triangulation.representative.resize(ns);
    std::iota(a->triangulation.representative.begin(), a->triangulation.representative.end(), 0);
    a->triangulation.recorded.clear();
    a->triangulation.max_chain_error_rel = 0.0;
  }
}

// budget_faces > 0: chains are straightened by error down to that many faces (see DecimateOptions);
// record_faces > budget_faces: the triangulation at that many faces is kept too (PatchTriangulation::recorded).
void GeometryOnce(const Prepared& prep, const DecimateOptions& options, int budget_faces,
                  const std::vector<std::pair<int, int>>& signature, Attempt* a, int record_faces = 0) {
  const auto t1 = Clock::now();
  std::vector<const Vertices*> poses;
  for (const Vertices& V : prep.poses) poses.push_back(&V);
  PatchTriangulationOptions topts;
  topts.min_cos_to_patch_normal = options.min_cos_to_patch_normal;
  topts.chain_tolerance_rel = options.chain_tolerance_rel;
  if (budget_faces > 0) {
    // Only (numerically) straight chain runs go unconditionally; the budgeted pass decides the rest.
    topts.chain_tolerance_rel = std::min(options.chain_tolerance_rel, 1e-7);
    topts.target_faces = budget_faces;
    topts.record_faces = record_faces;
  }
  a->triangulation =
      TriangulatePatches(poses, prep.F, a->face_patch, a->num_patches, prep.weld_group, topts, prep.boundary_vertex);
  CheckTopology(prep, signature, a);
  a->seconds_geometry = Seconds(t1);
}

// The attempt's triangulation at the face count it recorded (GeometryOnce's record_faces), or a new run
// with that budget when it recorded none.
void UseRecorded(const Prepared& prep, const DecimateOptions& options, int faces,
                 const std::vector<std::pair<int, int>>& signature, Attempt* a) {
  if (a->triangulation.recorded.empty()) {
    GeometryOnce(prep, options, faces, signature, a);
    return;
  }
  PatchTriangulation recorded = std::move(a->triangulation.recorded.front());
  a->triangulation = std::move(recorded);
  CheckTopology(prep, signature, a);
}

std::vector<std::vector<int>> PatchPolygons(const Faces& F, const std::vector<int>& face_patch, int num_patches) {
  // Directed edges per patch whose reverse is not in the same patch form the patch's boundary.
  std::vector<std::vector<int>> faces_of(num_patches);
  for (int f = 0; f < F.rows(); ++f) faces_of[face_patch[f]].push_back(f);
  std::vector<std::vector<int>> polygons;
  for (int k = 0; k < num_patches; ++k) {
    std::map<std::pair<int, int>, int> directed;
    for (int f : faces_of[k]) {
      for (int c = 0; c < 3; ++c) directed[{F(f, c), F(f, (c + 1) % 3)}] = f;
    }
    std::unordered_map<int, int> next;
    bool simple = true;
    for (const auto& [edge, f] : directed) {
      if (directed.count({edge.second, edge.first})) continue;
      if (next.count(edge.first)) simple = false;
      next[edge.first] = edge.second;
    }
    std::vector<int> loop;
    if (simple && !next.empty()) {
      int v = next.begin()->first;
      const int start = v;
      do {
        loop.push_back(v);
        auto it = next.find(v);
        if (it == next.end()) {
          simple = false;
          break;
        }
        v = it->second;
      } while (v != start && loop.size() <= next.size());
      if (loop.size() != next.size()) simple = false;
    } else {
      simple = false;
    }
    if (simple && loop.size() >= 3) {
      polygons.push_back(std::move(loop));
    } else {
      for (int f : faces_of[k]) polygons.push_back({F(f, 0), F(f, 1), F(f, 2)});
    }
  }
  return polygons;
}

// Refits the per-corner shading normals (one per output vertex and patch) to the dense face normals, so that
// each dense face's normal is reproduced where the output surface stands in for it.
//
// Where: each dense face's centroid is projected onto the output faces around the output vertices its corners
// collapsed onto: the nearest face of its own patch, unless a face of another patch there is nearer and faces
// the dense normal at least as squarely (near a patch border on a smooth surface the neighbour's triangle is what
// covers the dense face; across a crease the orientation test keeps it on its own side).
//
// How: the corner normals minimise Σ_f w_f ρ(‖Σ_i b_i n_i − u_f‖) (b the barycentric coordinates of the
// projection, so a piecewise-linear field over each patch's triangles) plus a ridge of `ridge` times each
// normal's own weight towards its value from the patch field; then normalised. ρ is the distance itself (≈ the
// angle, the measure of shading error) rather than its square: iteratively reweighted least squares, each round
// weighting a face by 1 / max(its residual of the last round, kCornerResidualFloor), after a first round of plain
// least squares. Measured on the decimation benchmark meshes and eight others: a lower shading-normal error and
// rendering difference at 2% and 10% on every one (docs/journal/decimation.md, round 6).
constexpr int kCornerNormalRounds = 4;         // one least-squares round and three reweighted ones
constexpr double kCornerResidualFloor = 0.01;  // ≈ 0.6°: below it a face counts as fitted
void RefitCornerNormals(const Vertices& dense_V, const Faces& dense_F, const std::vector<int>& dense_patch,
                        const std::vector<double>& weight, const std::vector<int>& output_of_dense,
                        const Mesh& coarse, const std::vector<int>& coarse_patch, double ridge,
                        CornerNormals* corner) {
  const int nc = static_cast<int>(coarse.F.rows());
  const int nn = static_cast<int>(corner->normals.rows());
  std::vector<std::vector<int>> faces_of(coarse.num_vertices());
  for (int f = 0; f < nc; ++f) {
    for (int c = 0; c < 3; ++c) faces_of[coarse.F(f, c)].push_back(f);
  }
  // Unit normal of each output face, for the orientation test below.
  std::vector<Eigen::Vector3d> face_normal(nc);
  for (int g = 0; g < nc; ++g) {
    const Eigen::Vector3d x0 = coarse.V.row(coarse.F(g, 0)).transpose();
    face_normal[g] = (coarse.V.row(coarse.F(g, 1)).transpose() - x0)
                         .cross(coarse.V.row(coarse.F(g, 2)).transpose() - x0)
                         .normalized();
  }
  // Each dense face's projection in parallel (reads only), the system summed in face order afterwards.
  const int nd = static_cast<int>(dense_F.rows());
  std::vector<int> face_of(nd, -1);
  std::vector<Eigen::Vector3d> bary_of(nd), normal_of(nd);
  tbb::parallel_for(tbb::blocked_range<int>(0, nd, 8192), [&](const tbb::blocked_range<int>& range) {
    for (int f = range.begin(); f < range.end(); ++f) {
      const double w = weight[f];
      if (!(w > 0.0)) continue;
      const Eigen::Vector3d a = dense_V.row(dense_F(f, 0)).transpose(), b = dense_V.row(dense_F(f, 1)).transpose(),
                            c = dense_V.row(dense_F(f, 2)).transpose();
      const Eigen::Vector3d u = (b - a).cross(c - a).normalized();
      const Eigen::Vector3d p = (a + b + c) / 3.0;
      // [0]: the nearest face of the own patch, [1]: of another patch.
      double best[2] = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
      int best_face[2] = {-1, -1};
      Eigen::Vector3d best_bary[2] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
      for (int k = 0; k < 3; ++k) {
        const int o = output_of_dense[dense_F(f, k)];
        if (o < 0) continue;
        for (int g : faces_of[o]) {
          const int which = coarse_patch[g] == dense_patch[f] ? 0 : 1;
          const Eigen::Vector3d x0 = coarse.V.row(coarse.F(g, 0)).transpose(),
                                x1 = coarse.V.row(coarse.F(g, 1)).transpose(),
                                x2 = coarse.V.row(coarse.F(g, 2)).transpose();
          // Barycentric coordinates of p's projection, clamped to the triangle.
          const Eigen::Vector3d e1 = x1 - x0, e2 = x2 - x0, d = p - x0;
          const double d11 = e1.dot(e1), d12 = e1.dot(e2), d22 = e2.dot(e2), det = d11 * d22 - d12 * d12;
          if (!(det > 0.0)) continue;
          const double l1 = (d22 * e1.dot(d) - d12 * e2.dot(d)) / det, l2 = (d11 * e2.dot(d) - d12 * e1.dot(d)) / det;
          Eigen::Vector3d bary(1.0 - l1 - l2, l1, l2);
          bary = bary.cwiseMax(0.0);
          bary /= bary.sum();
          const double dist = (bary(0) * x0 + bary(1) * x1 + bary(2) * x2 - p).squaredNorm();
          if (dist < best[which]) {
            best[which] = dist;
            best_face[which] = g;
            best_bary[which] = bary;
          }
        }
      }
      const bool other = best_face[1] >= 0 &&
                         (best_face[0] < 0 ||
                          (best[1] < best[0] && u.dot(face_normal[best_face[1]]) >= u.dot(face_normal[best_face[0]])));
      face_of[f] = best_face[other ? 1 : 0];
      bary_of[f] = best_bary[other ? 1 : 0];
      normal_of[f] = u;
    }
  });
  const Eigen::MatrixXd field = corner->normals;  // the patch fields' normals, the ridge's target
  std::vector<double> robust(nd, 1.0);
  for (int round = 0; round < kCornerNormalRounds; ++round) {
    if (round > 0) {
      tbb::parallel_for(tbb::blocked_range<int>(0, nd, 8192), [&](const tbb::blocked_range<int>& range) {
        for (int f = range.begin(); f < range.end(); ++f) {
          const int g = face_of[f];
          if (g < 0) continue;
          Eigen::Vector3d n = Eigen::Vector3d::Zero();
          for (int i = 0; i < 3; ++i) n += bary_of[f](i) * corner->normals.row(corner->normal_index(g, i)).transpose();
          const double length = n.norm();
          const double residual = length > 1e-12 ? (n / length - normal_of[f]).norm() : 2.0;
          robust[f] = 1.0 / std::max(residual, kCornerResidualFloor);
        }
      });
    }
    // The normal equations gathered per output face (a 3×3 block over its corner normals), then once per block.
    Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(nn, 3);
    std::vector<double> diagonal(nn, 0.0);
    std::vector<Eigen::Matrix3d> block(nc, Eigen::Matrix3d::Zero());
    for (int f = 0; f < nd; ++f) {
      const int g = face_of[f];
      if (g < 0) continue;
      const double w = weight[f] * robust[f];
      const Eigen::Vector3d& b = bary_of[f];
      block[g] += w * b * b.transpose();
      for (int i = 0; i < 3; ++i) {
        const int ni = corner->normal_index(g, i);
        rhs.row(ni) += w * b(i) * normal_of[f].transpose();
        diagonal[ni] += w * b(i);
      }
    }
    std::vector<Eigen::Triplet<double>> triplets;
    triplets.reserve(static_cast<size_t>(9 * nc + nn));
    for (int g = 0; g < nc; ++g) {
      if (block[g].isZero(0.0)) continue;
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
          triplets.emplace_back(corner->normal_index(g, i), corner->normal_index(g, j), block[g](i, j));
        }
      }
    }
    double mean_diagonal = 0.0;
    for (double x : diagonal) mean_diagonal += x / std::max(1, nn);
    for (int i = 0; i < nn; ++i) {
      const double mu = ridge * diagonal[i] + 1e-6 * mean_diagonal + 1e-300;
      triplets.emplace_back(i, i, mu);
      rhs.row(i) += mu * field.row(i);
    }
    Eigen::SparseMatrix<double> A(nn, nn);
    A.setFromTriplets(triplets.begin(), triplets.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver(A);
    if (solver.info() != Eigen::Success) return;
    const Eigen::MatrixXd solved = solver.solve(rhs);
    if (solver.info() != Eigen::Success || !solved.allFinite()) return;
    for (int i = 0; i < nn; ++i) {
      const double length = solved.row(i).norm();
      if (length > 1e-9) corner->normals.row(i) = solved.row(i) / length;
    }
  }
}

// The summary's fields that the options and the input sizes decide, before anything runs.
void StartSummary(const std::vector<Mesh>& poses, const DecimateOptions& options, DecimateSummary* s) {
  *s = DecimateSummary{};
  s->input_faces = poses[0].num_faces();
  s->target_faces = options.target_faces;
  s->refitted = options.refit_vertices;
  s->poses = static_cast<int>(poses.size());
}

// signature: of the split mesh (TopologySignature), one entry per piece.
void NoteComponentsAndLoops(const Prepared& prep, const std::vector<std::pair<int, int>>& signature,
                            std::vector<std::string>* notices) {
  int loops = 0;
  for (const auto& c : signature) loops += c.second;
  const int pieces = static_cast<int>(signature.size());
  if (prep.input_components > 0 && prep.input_components != pieces) {
    notices->push_back(StrCat("the mesh has ", prep.input_components,
                              prep.input_components == 1 ? " component" : " components", ", ", pieces,
                              " pieces where cut at its non-manifold vertices; patches never span two pieces"));
  } else if (pieces > 1) {
    notices->push_back(StrCat("the mesh has ", pieces, " components; patches never span two"));
  }
  if (loops > 0) notices->push_back(StrCat("the mesh has ", loops, " boundary loops; they are kept"));
}

// The λ the search tries: λ is the energy of one patch in units of squared normal difference × faces, so the
// range is the same for every mesh. Below it a patch costs nothing that a face's data term could notice (the
// partition only merges faces that are coplanar to rounding); above it every component is one patch.
constexpr double kMinLambda = 1e-12, kMaxLambda = 1e12;

// Finds a bracket [lo, hi] (hi/lo ≤ 1 + resolution, lo "too many", hi "fits") of `eval` (λ → fits?, log faces)
// within the open interval (lo0, hi0) (0: unbounded), starting at `start`. Bracketing: the face count falls
// roughly like a power of λ, so the next λ is extrapolated from the last two evaluations (the first step
// assumes faces ∝ 1/λ), by a factor of 1 + 2·resolution to 64, overshooting a little. Then safeguarded
// interpolation in log λ against log faces (regula falsi); a step that did not halve the bracket is followed by
// a bisection step; a point within the resolution of an end is moved to just that far, which can close the
// bracket.
template <typename Eval>
class LambdaBracket {
 public:
  LambdaBracket(Eval& eval, double log_budget, double resolution)
      : eval_(eval), log_budget_(log_budget), resolution_(resolution), res_step_(std::log(1.0 + resolution)) {}

  // Returns {lo, hi}; call once.
  std::pair<double, double> Find(double lo0, double hi0, double start, int max_evals) {
    lo0_ = lo0;
    hi0_ = hi0;
    lo_ = lo0;
    hi_ = hi0;
    max_evals_ = max_evals;
    if (lo_ <= 0.0 || hi_ <= 0.0) Extrapolate(start);
    Interpolate();
    return {lo_, hi_};
  }

 private:
  std::pair<bool, double> Go(double l) {
    ++evals_;
    const auto [ok, lf] = eval_(l);
    if (ok) {
      hi_ = l;
      f_hi_ = lf;
    } else {
      lo_ = l;
      f_lo_ = lf;
    }
    return std::make_pair(ok, lf);
  }

  double Factor(double lf) const {
    double slope = -1.0;  // d log faces / d log λ
    if (prev_l_ > 0.0 && std::abs(std::log(l_ / prev_l_)) > 1e-9) {
      slope = std::min(-0.2, (lf - prev_lf_) / std::log(l_ / prev_l_));
    }
    return std::clamp(std::exp(1.3 * std::abs((log_budget_ - lf) / slope)), 1.0 + 2.0 * resolution_, 64.0);
  }

  void Extrapolate(double start) {
    l_ = start;
    auto [ok, lf] = Go(l_);
    while (evals_ < max_evals_ && (lo_ <= 0.0 || hi_ <= 0.0) && l_ > kMinLambda && l_ < kMaxLambda) {
      const double next = ok ? l_ / Factor(lf) : l_ * Factor(lf);
      prev_l_ = l_;
      prev_lf_ = lf;
      l_ = next;
      if (ok && lo0_ > 0.0 && l_ <= lo0_) break;
      if (!ok && hi0_ > 0.0 && l_ >= hi0_) break;
      std::tie(ok, lf) = Go(l_);
    }
  }

  void Interpolate() {
    bool bisect_next = false;
    while (lo_ > 0.0 && hi_ > 0.0 && hi_ > lo_ * (1.0 + resolution_) && evals_ < max_evals_) {
      const double width = std::log(hi_ / lo_);
      double t = 0.5;
      if (!bisect_next && f_lo_ > f_hi_ && lo_ != lo0_ && hi_ != hi0_) {
        t = std::clamp((f_lo_ - log_budget_) / (f_lo_ - f_hi_), 0.0, 1.0);
      }
      double x = std::log(lo_) + t * width;
      x = std::clamp(x, std::log(lo_) + 0.5 * res_step_, std::log(hi_) - 0.5 * res_step_);
      if (x - std::log(lo_) < res_step_) x = std::log(lo_) + res_step_ * 0.999;
      if (std::log(hi_) - x < res_step_) x = std::log(hi_) - res_step_ * 0.999;
      Go(std::exp(x));
      bisect_next = !bisect_next && std::log(hi_ / lo_) > 0.5 * width;
    }
  }

  Eval& eval_;
  const double log_budget_, resolution_, res_step_;
  double lo0_ = 0.0, hi0_ = 0.0;
  double lo_ = 0.0, hi_ = 0.0, f_lo_ = 0.0, f_hi_ = 0.0;
  int evals_ = 0, max_evals_ = 0;
  double l_ = 0.0, prev_l_ = 0.0, prev_lf_ = 0.0;  // the extrapolation's last two λ and the log faces at prev_l_
};

// Search λ in log scale on "the straightened patches fit in the budget" (see decimate.h, Target faces).
class LambdaSearch {
 public:
  LambdaSearch(const Prepared& prep, const Problem& problem, const std::vector<std::pair<int, int>>& signature,
               const DecimateOptions& options, DecimateSummary* s)
      : prep_(prep),
        problem_(problem),
        signature_(signature),
        options_(options),
        s_(*s),
        target_(options.target_faces),
        budget_(std::max(
            1, static_cast<int>(std::lround((1.0 - options.chain_reserve_share) * static_cast<double>(target_))))),
        log_budget_(std::log(static_cast<double>(budget_))) {
    s_.budget_faces = budget_;
  }

  // The attempt at the λ found, which goes to *lambda; fills the search's fields of the summary.
  Attempt Run(double* lambda) {
    GuidedRounds();
    BisectRemaining();
    return Finish(lambda);
  }

 private:
  static int FacesOf(const Attempt& a) { return static_cast<int>(a.triangulation.F.rows()); }
  bool Closed() const { return lo_ > 0.0 && hi_ > 0.0 && hi_ <= lo_ * (1.0 + options_.lambda_resolution); }
  bool Inside(double l) const { return l > 0.0 && l > lo_ && (hi_ <= 0.0 || l < hi_); }

  // Hill climbings by λ, each a function of λ alone: the first climb (at the smallest λ climbed from single
  // faces) is the base, and every larger λ starts from the base's partition (a warm start: coarsening a finer
  // partition costs a fraction of a climb from single faces). A λ climbed before is reused.
  const Attempt& Climb(double l) {
    auto it = climbs_.find(l);
    if (it == climbs_.end()) it = Remember(l, ClimbUncached(l));
    return it->second;
  }

  // The climb at l from the current base (not looked up, not cached).
  Attempt ClimbUncached(double l) const {
    const bool warm = base_lambda_ > 0.0 && l > base_lambda_;
    return PartitionOnce(problem_, l, options_, nullptr, warm ? &climbs_.at(base_lambda_).face_patch : nullptr);
  }

  // Caches a climb made by ClimbUncached from the current base.
  std::map<double, Attempt>::iterator Remember(double l, Attempt a) {
    if (!(base_lambda_ > 0.0 && l > base_lambda_)) {
      // A new, smaller base: the climbs from the old one are dropped, so that every cached climb above
      // the base starts from it.
      climbs_.clear();
      base_lambda_ = l;
    }
    s_.seconds_search_partition += a.seconds_partition;
    return climbs_.emplace(l, std::move(a)).first;
  }

  // A full evaluation: hill climbing and triangulation with the budget, the triangulation at the target
  // recorded on the way. True when it fits.
  bool Evaluate(double l) {
    Attempt attempt = Climb(l);
    GeometryOnce(prep_, options_, budget_, signature_, &attempt, target_);
    return Apply(l, std::move(attempt));
  }

  // Evaluate(b), then Evaluate(below) only when b fits; the second runs beside the first on another core
  // (climb and triangulation), and is thrown away when b has too many, so the search takes the same steps and
  // ends with the same result as one after the other. What it costs: when b has too many, one evaluation of
  // CPU that the serial order would not spend (docs/journal/decimation.md, round 9).
  std::vector<double> EvaluatePair(double b, double below) {
    Attempt at_b = Climb(b);
    const bool below_cached = climbs_.count(below) > 0;
    Attempt at_below, below_climb;
    tbb::parallel_invoke([&] { GeometryOnce(prep_, options_, budget_, signature_, &at_b, target_); },
                         [&] {
                           below_climb = below_cached ? climbs_.at(below) : ClimbUncached(below);
                           at_below = below_climb;
                           GeometryOnce(prep_, options_, budget_, signature_, &at_below, target_);
                         });
    if (!Apply(b, std::move(at_b))) return {b};
    if (!below_cached) Remember(below, std::move(below_climb));
    Apply(below, std::move(at_below));
    return {b, below};
  }

  // Whether an attempt at l with `faces` too many would replace fewest_.
  bool BeatsFewest(int faces, double l) const {
    return faces < fewest_faces_ || (faces == fewest_faces_ && l > fewest_lambda_);
  }

  // The faces attempt a has at the target (its triangulation recorded there, or its own when it has fewer), or
  // −1 when it has more.
  int FacesAtTarget(const Attempt& a) const {
    if (!a.triangulation.recorded.empty()) return static_cast<int>(a.triangulation.recorded.front().F.rows());
    return FacesOf(a) <= target_ ? FacesOf(a) : -1;
  }

  // Keeps a copy of the attempt at l, at the target, when it has more faces there within the target than every
  // attempt before it (Finish's fallback where the face count jumps).
  void RememberClosest(double l, const Attempt& attempt) {
    const int faces = FacesAtTarget(attempt);
    if (faces <= closest_faces_) return;
    Attempt copy;
    copy.face_patch = attempt.face_patch;
    copy.num_patches = attempt.num_patches;
    copy.stats = attempt.stats;
    copy.seconds_partition = attempt.seconds_partition;
    copy.seconds_geometry = attempt.seconds_geometry;
    copy.triangulation =
        attempt.triangulation.recorded.empty() ? attempt.triangulation : attempt.triangulation.recorded.front();
    copy.triangulation.recorded.clear();
    CheckTopology(prep_, signature_, &copy);
    if (copy.fell_back) return;
    closest_ = std::move(copy);
    closest_faces_ = faces;
    closest_lambda_ = l;
  }

  // Records an evaluated attempt at l in the bracket. True when it fits.
  bool Apply(double l, Attempt attempt) {
    ++steps_;
    s_.seconds_search_geometry += attempt.seconds_geometry;
    RememberClosest(l, attempt);
    const bool ok = FacesOf(attempt) <= budget_;
    if (ok) {
      if (hi_ <= 0.0 || l < hi_) {
        hi_ = l;
        fits_ = std::move(attempt);
      }
    } else if (l > lo_) {
      // The bracket's end moves up. The face count need not fall with λ (a larger patch can block more
      // collapses), so the attempt it held is kept when it has the fewest faces of all that did not fit.
      if (lo_ > 0.0 && FacesOf(too_many_) < FacesOf(attempt) && BeatsFewest(FacesOf(too_many_), lo_)) {
        fewest_faces_ = FacesOf(too_many_);
        fewest_lambda_ = lo_;
        fewest_ = std::move(too_many_);
      }
      lo_ = l;
      too_many_ = std::move(attempt);
    } else if (FacesOf(attempt) < FacesOf(too_many_) && BeatsFewest(FacesOf(attempt), l)) {
      fewest_faces_ = FacesOf(attempt);
      fewest_lambda_ = l;
      fewest_ = std::move(attempt);
    }
    if (options_.progress) {
      options_.progress(std::min(0.99, static_cast<double>(steps_) / options_.max_bisection_steps), "searching lambda");
    }
    return ok;
  }

  // The full evaluations decide; a cheap one guides them: the hill climbing alone, with the triangle count
  // predicted as (vertices where ≥ 3 patch sides meet) × the ratio of faces to such vertices measured on the
  // last full evaluations (before any: 2, a closed mesh of triangulated patches with V corners has about 2V
  // triangles).
  int CornersOf(const std::vector<int>& g) const {
    const DecimationProblem& pr = problem_.problem;
    const int ns = static_cast<int>(prep_.split_source.size());
    std::vector<unsigned char> features(ns, 0);
    for (int f = 0; f < pr.num_faces(); ++f) {
      for (int k = 0; k < 3; ++k) {
        const int h = pr.neighbours[f][k];
        if (h >= 0 && (h < f || g[h] == g[f])) continue;
        for (int v : {pr.corners[f][k], pr.corners[f][(k + 1) % 3]}) {
          features[v] = static_cast<unsigned char>(std::min(255, features[v] + 1));
        }
      }
    }
    int count = 0;
    for (int v = 0; v < ns; ++v) count += (features[v] >= 3 || prep_.locked[v]) ? 1 : 0;
    return std::max(1, count);
  }

  std::pair<bool, double> Cheap(double l) {
    const double predicted = ratio_ * CornersOf(Climb(l).face_patch);
    return std::make_pair(predicted <= budget_, std::log(std::max(1.0, predicted)));
  }

  // Each round evaluates the guide's smallest fitting λ b and, when b fits, the step below it, b / (1 +
  // resolution), so a guide that is right closes the bracket in one round; the ratio is then recalibrated
  // on the results. When b has too many the step below would have too many as well and decide nothing; run in
  // parallel with b it cost a third of the 1.06M-face stereo case (docs/journal/decimation.md, round 4).
  //
  // The guide can only over-predict where everything it was calibrated on fits: a fit's count is the budget the
  // chain pass filled, not what the straightened patches need. Then b and the step below it both fit, and each
  // round would move λ down by one resolution step (30 full decimations on a smoothed stereo mesh of ArtL at
  // 2,000 faces). So after a round in which everything fit, the search gallops instead: one full evaluation
  // 2, 4, 8, … resolution steps below the smallest fitting λ (bisecting when that passes a λ with too many),
  // until one has too many, and the guide takes over again.
  void GuidedRounds() {
    auto cheap = [this](double l) { return Cheap(l); };
    int stride = 1;
    while (!Closed() && steps_ < options_.max_bisection_steps) {
      if (hi_ > 0.0 && fits_.num_patches >= prep_.F.rows()) break;  // every face its own patch fits
      if (stride > 1) {
        double l = hi_ / std::pow(1.0 + options_.lambda_resolution, stride);
        if (lo_ > 0.0 && !(l > lo_ * (1.0 + options_.lambda_resolution))) l = std::sqrt(lo_ * hi_);
        if (!Inside(l) || l < kMinLambda) break;
        stride = Evaluate(l) ? 2 * stride : 1;
        Recalibrate({l});
        continue;
      }
      LambdaBracket bracket(cheap, log_budget_, options_.lambda_resolution);
      const auto [guide_lo, b] = bracket.Find(lo_, hi_, hi_ > 0.0 ? hi_ : (lo_ > 0.0 ? lo_ : options_.lambda), 40);
      std::vector<double> ls;
      if (Inside(b)) ls.push_back(b);
      // The guide's own too-many end when it lies within the resolution below b: its climb is cached, and
      // the bracket closes on it just as well.
      double below = b / (1.0 + options_.lambda_resolution);
      if (guide_lo > below && guide_lo < b && climbs_.count(guide_lo) > 0) below = guide_lo;
      if (Inside(below) && steps_ + static_cast<int>(ls.size()) < options_.max_bisection_steps) ls.push_back(below);
      // The guide found no fitting λ up to the largest (a budget below one patch per component): its largest
      // λ, fully evaluated, is the fewest faces there are.
      if (ls.empty() && steps_ == 0 && b <= 0.0 && Inside(guide_lo)) ls.push_back(guide_lo);
      if (ls.empty()) break;
      std::vector<double> evaluated{ls[0]};
      if (ls.size() > 1) {
        evaluated = EvaluatePair(ls[0], ls[1]);
      } else {
        Evaluate(ls[0]);
      }
      const bool all_fit = evaluated.size() == ls.size() && hi_ == evaluated.back();
      if (all_fit) stride = 2;
      Recalibrate(evaluated);
    }
  }

  void Recalibrate(const std::vector<double>& ls) {
    double sum = 0.0;
    int count = 0;
    for (double l : ls) {
      const Attempt& at = l == hi_ ? fits_ : too_many_;
      if (l == hi_ || l == lo_) {
        sum += static_cast<double>(FacesOf(at)) / CornersOf(at.face_patch);
        ++count;
      }
    }
    if (count > 0) ratio_ = sum / count;
  }

  // Whatever the guide left open is closed by full evaluations alone (bisection in log λ).
  void BisectRemaining() {
    while (!Closed() && steps_ < options_.max_bisection_steps && !(hi_ > 0.0 && fits_.num_patches >= prep_.F.rows())) {
      double l;
      if (lo_ <= 0.0) {
        l = hi_ / 4.0;
      } else if (hi_ <= 0.0) {
        l = lo_ * 4.0;
      } else {
        l = std::sqrt(lo_ * hi_);
      }
      if (l < kMinLambda || l > kMaxLambda) break;
      // One patch per component has the fewest faces; a larger λ cannot change that.
      if (hi_ <= 0.0 && lo_ > 0.0 && too_many_.num_patches <= static_cast<int>(signature_.size())) break;
      Evaluate(l);
    }
  }

  Attempt Finish(double* lambda) {
    s_.bisection_steps = steps_;
    s_.lambda_too_many = lo_;
    s_.lambda_fits = hi_;
    s_.faces_too_many = lo_ > 0.0 ? FacesOf(too_many_) : 0;
    s_.faces_fits = hi_ > 0.0 ? FacesOf(fits_) : 0;
    Attempt best;
    if (hi_ > 0.0) {
      *lambda = hi_;
      best = std::move(fits_);
      if (budget_ < target_) UseRecorded(prep_, options_, target_, signature_, &best);
      // The face count need not fall with λ, and where it jumps (a curved patch that keeps vertices against
      // flipped triangles merges into one that does not) the smallest fitting λ can come far below the target.
      // Then the attempt closest to the target within it, whichever λ it had (its patches may need more than the
      // budget when straightened: less is left for chain detail).
      const int found = FacesOf(best);
      if (found < target_ - 1 && closest_faces_ > found) {
        *lambda = closest_lambda_;
        best = std::move(closest_);
      }
      NoteBelowTarget(best, *lambda);
    } else if (closest_faces_ > 0) {
      // No λ tried fits the budget, but some fit the target with less left for chain detail: the closest to it.
      *lambda = closest_lambda_;
      best = std::move(closest_);
      NoteBelowTarget(best, *lambda);
    } else {
      // No λ tried fits the target: the attempt with the fewest faces (at the largest λ among equals).
      *lambda = lo_;
      if (fewest_lambda_ > 0.0 && fewest_faces_ < FacesOf(too_many_)) {
        *lambda = fewest_lambda_;
        best = std::move(fewest_);
      } else {
        best = std::move(too_many_);
      }
      UseRecorded(prep_, options_, target_, signature_, &best);
      if (FacesOf(best) > target_) {
        s_.notices.push_back(StrCat("target ", target_, " faces not reachable: ", FacesOf(best), " faces at lambda ",
                                    *lambda,
                                    ", the fewest of the lambdas tried (the patches' corners and guarded vertices)"));
      }
    }
    return best;
  }

  // A notice when the output (best, at lambda) has fewer faces than the budget and than target − 1 (the
  // normal result: the budget filled with chain detail), saying what was reached and why.
  void NoteBelowTarget(const Attempt& best, double lambda) {
    const int faces = FacesOf(best);
    if (faces >= std::min(budget_, target_ - 1)) return;
    if (lo_ <= 0.0) {
      // No λ tried had too many: the patches need fewer faces than the target even at the smallest λ (a mesh
      // whose flat regions merge at any λ), which the output's count alone does not say.
      s_.notices.push_back(StrCat("target ", target_, " faces not reached: ", faces, " faces at lambda ", lambda,
                                  ", the smallest tried; the patches fit in fewer "
                                  "faces at every lambda (flat regions merge at any lambda)"));
      return;
    }
    s_.notices.push_back(StrCat(
        "target ", target_, " faces not reached: ", faces, " faces (", best.num_patches,
        best.num_patches == 1 ? " patch" : " patches", ") at lambda ", lambda,
        ", the closest to the target of the lambdas tried; at lambda ", lo_, " the straightened patches need ",
        FacesOf(too_many_), " faces (", too_many_.num_patches, too_many_.num_patches == 1 ? " patch" : " patches",
        "): the face count jumps there (it need not fall with lambda: curved patches keep vertices against flipped "
        "triangles), and no lambda tried gave a count in between"));
  }

  const Prepared& prep_;
  const Problem& problem_;
  const std::vector<std::pair<int, int>>& signature_;
  const DecimateOptions& options_;
  DecimateSummary& s_;
  const int target_;
  const int budget_;
  const double log_budget_;
  int steps_ = 0;
  Attempt too_many_, fits_;  // the attempts at the bracket ends
  // Of the attempts that did not fit, the one with the fewest faces when that is not too_many_ (fewest_lambda_ 0:
  // none); ties go to the larger λ.
  Attempt fewest_;
  int fewest_faces_ = std::numeric_limits<int>::max();
  double fewest_lambda_ = 0.0;
  // Of all attempts, at the target (FacesAtTarget, its triangulation there), the one with the most faces within
  // it (closest_faces_ 0: none); ties go to the first.
  Attempt closest_;
  int closest_faces_ = 0;
  double closest_lambda_ = 0.0;
  double lo_ = 0.0, hi_ = 0.0;
  std::map<double, Attempt> climbs_;
  double base_lambda_ = 0.0;
  double ratio_ = 2.0;
};

// Outputs: compact the kept split vertices, weld copies of one input vertex back together. What every pose's
// output shares.
struct WeldedOutput {
  Faces F;                                 // over output vertices
  std::vector<int> out_of_input;           // per input vertex, its output vertex (−1: not kept)
  std::vector<int> vertex_source;          // per output vertex, its input vertex
  std::vector<int> vertex_split;           // per output vertex, the split vertex it was made from
  std::vector<int> dense_face_patch;       // per input face, its patch (−1: dropped)
  std::vector<std::vector<int>> polygons;  // per patch
};

WeldedOutput WeldOutput(const Mesh& base, const Prepared& prep, const Attempt& best) {
  const PatchTriangulation& tri = best.triangulation;
  WeldedOutput w;
  w.out_of_input.assign(base.num_vertices(), -1);
  w.F.resize(tri.F.rows(), 3);
  for (int f = 0; f < tri.F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int input = prep.split_source[tri.F(f, k)];
      int& id = w.out_of_input[input];
      if (id < 0) {
        id = static_cast<int>(w.vertex_source.size());
        w.vertex_source.push_back(input);
        w.vertex_split.push_back(tri.F(f, k));
      }
      w.F(f, k) = id;
    }
  }
  w.dense_face_patch.assign(base.num_faces(), -1);
  for (size_t i = 0; i < prep.kept_faces.size(); ++i) w.dense_face_patch[prep.kept_faces[i]] = best.face_patch[i];
  w.polygons = PatchPolygons(w.F, tri.face_patch, best.num_patches);
  return w;
}

// The vertex refit's input for pose m of the chosen attempt.
RefitInput RefitInputFor(const Prepared& prep, const Attempt& best, const DecimateOptions& options, size_t m) {
  RefitInput in;
  in.dense_V = &prep.poses[m];
  in.dense_F = &prep.F;
  in.dense_face_patch = &best.face_patch;
  in.representative = &best.triangulation.representative;
  in.boundary_vertex = &prep.boundary_vertex;
  in.fixed = &prep.locked;  // copies of one input vertex stay where it is, so that they weld back
  in.coarse_F = &best.triangulation.F;
  in.coarse_face_patch = &best.triangulation.face_patch;
  in.num_patches = best.num_patches;
  in.min_cos_to_patch_normal = options.min_cos_to_patch_normal;
  return in;
}

// The discrete half of the refit, before its continuous half (decimate_refit.h): edges inside patches flipped
// where the other diagonal lies closer to the dense vertices, judged at the positions of the refit's quadric
// step in every pose (so that the flips suit where the vertices will stand); returns the flips. The refit then
// runs in full on the flipped connectivity, which every pose shares.
int FlipEdgesBeforeRefit(const Prepared& prep, const DecimateOptions& options, Attempt* best) {
  VertexRefitOptions quadric_step = options.refit;
  quadric_step.fit_rounds = 0;
  std::vector<Vertices> quadric(prep.poses.size());
  tbb::parallel_for(size_t{0}, prep.poses.size(), [&](size_t m) {
    quadric[m] = RefitVertices(RefitInputFor(prep, *best, options, m), quadric_step);
  });
  EdgeFlipInput flip;
  for (size_t m = 0; m < prep.poses.size(); ++m) {
    flip.dense_poses.push_back(&prep.poses[m]);
    flip.coarse_poses.push_back(&quadric[m]);
  }
  flip.dense_F = &prep.F;
  flip.dense_face_patch = &best->face_patch;
  flip.representative = &best->triangulation.representative;
  flip.coarse_face_patch = &best->triangulation.face_patch;
  flip.num_patches = best->num_patches;
  flip.weld_group = &prep.weld_group;
  EdgeFlipSummary fs;
  FlipEdgesToFit(flip, options.min_cos_to_patch_normal, options.refit.flip_sweeps, &best->triangulation.F, &fs);
  return fs.flips;
}

// One pose's output over the welded connectivity: positions (refitted or the input's) and shading normals.
class PoseOutput {
 public:
  PoseOutput(const Prepared& prep, const Problem& problem, const Attempt& best, const WeldedOutput& welded,
             const DecimateOptions& options)
      : prep_(prep), problem_(problem), best_(best), tri_(best.triangulation), welded_(welded), options_(options) {}

  // Pose m of the input; adds its vertex refit to *s.
  DecimatedMesh Build(const Mesh& pose, size_t m, DecimateSummary* s) const {
    DecimatedMesh d;
    d.mesh.F = welded_.F;
    d.mesh.V.resize(static_cast<Eigen::Index>(welded_.vertex_source.size()), 3);
    if (options_.refit_vertices && !best_.fell_back) {
      RefitPositions(m, s, &d.mesh.V);
    } else {
      for (size_t i = 0; i < welded_.vertex_source.size(); ++i) {
        d.mesh.V.row(static_cast<Eigen::Index>(i)) = pose.V.row(welded_.vertex_source[i]);
      }
    }
    d.face_patch = tri_.face_patch;
    d.vertex_source = welded_.vertex_source;
    d.dense_face_patch = welded_.dense_face_patch;
    d.polygons = welded_.polygons;
    d.num_patches = best_.num_patches;
    FieldNormals(m, d.mesh, &d.corner_normals);
    if (options_.corner_normal_ridge > 0.0 && !best_.fell_back) RefitNormals(m, d.mesh, &d.corner_normals);
    return d;
  }

 private:
  void RefitPositions(size_t m, DecimateSummary* s, Vertices* V) const {
    VertexRefitSummary rs;
    const Vertices moved = RefitVertices(RefitInputFor(prep_, best_, options_, m), options_.refit, &rs);
    for (size_t i = 0; i < welded_.vertex_split.size(); ++i) {
      V->row(static_cast<Eigen::Index>(i)) = moved.row(welded_.vertex_split[i]);
    }
    s->refit_moved += rs.moved;
    s->refit_blocked += rs.blocked;
    s->refit_quadric_before += rs.quadric_error_before;
    s->refit_quadric_after += rs.quadric_error_after;
    if (m == 0) {
      s->refit_rms_before = rs.fit_rms_before;
      s->refit_rms_after = rs.fit_rms_after;
    }
  }

  void FieldNormals(size_t m, const Mesh& mesh, CornerNormals* corner_normals) const {
    const Faces& F = welded_.F;
    const auto fields = FitPatchNormalFields(prep_.poses[m], prep_.F, problem_.weight, best_.face_patch,
                                             best_.num_patches, options_.shading_regularisation);
    // One normal per (vertex, patch) pair.
    std::unordered_map<long long, int> index;
    std::vector<Eigen::Vector3d> normals;
    corner_normals->normal_index.resize(F.rows(), 3);
    for (int f = 0; f < F.rows(); ++f) {
      const int k = tri_.face_patch[f];
      for (int c = 0; c < 3; ++c) {
        const int v = F(f, c);
        const long long key = static_cast<long long>(v) * best_.num_patches + k;
        auto [it, inserted] = index.emplace(key, static_cast<int>(normals.size()));
        if (inserted) normals.push_back(fields[k].Evaluate(mesh.V.row(v).transpose()));
        corner_normals->normal_index(f, c) = it->second;
      }
    }
    corner_normals->normals.resize(static_cast<Eigen::Index>(normals.size()), 3);
    for (size_t i = 0; i < normals.size(); ++i) {
      corner_normals->normals.row(static_cast<Eigen::Index>(i)) = normals[i].transpose();
    }
  }

  void RefitNormals(size_t m, const Mesh& mesh, CornerNormals* corner_normals) const {
    const int ns = static_cast<int>(prep_.split_source.size());
    std::vector<int> output_of_dense(ns, -1);
    for (int v = 0; v < ns; ++v) {
      const int r = tri_.representative[v];
      if (r >= 0) output_of_dense[v] = welded_.out_of_input[prep_.split_source[r]];
    }
    RefitCornerNormals(prep_.poses[m], prep_.F, best_.face_patch, problem_.weight, output_of_dense, mesh,
                       tri_.face_patch, options_.corner_normal_ridge, corner_normals);
  }

  const Prepared& prep_;
  const Problem& problem_;
  const Attempt& best_;
  const PatchTriangulation& tri_;
  const WeldedOutput& welded_;
  const DecimateOptions& options_;
};

// The summary's fields that the chosen attempt and the output decide.
void RecordOutcome(const Attempt& best, const WeldedOutput& welded, DecimateSummary* s) {
  const PatchTriangulation& tri = best.triangulation;
  s->num_patches = best.num_patches;
  s->output_faces = static_cast<int>(welded.F.rows());
  s->output_vertices = static_cast<int>(welded.vertex_source.size());
  s->energy = best.stats.energy;
  s->data_energy = best.stats.data_energy;
  s->fuses = best.stats.fuses;
  s->splits = best.stats.splits;
  s->swaps = best.stats.swaps;
  s->rejected_disconnecting = best.stats.rejected_disconnecting;
  s->rounds = best.stats.rounds;
  s->converged = best.stats.converged;
  // On the output's vertices: a welded vertex's copies are all locked, so kept unconditionally.
  s->kept_corner_vertices = 0;
  for (int split : welded.vertex_split) s->kept_corner_vertices += tri.unconditional[split] ? 1 : 0;
  s->blocked_vertices = s->output_vertices - s->kept_corner_vertices;
  s->max_chain_error_rel = tri.max_chain_error_rel;
  s->fell_back_to_dense = best.fell_back;
  if (best.fell_back) {
    s->notices.push_back("the reduced mesh failed the topology check; the dense faces were kept (please report)");
  }
  s->seconds_partition = best.seconds_partition;
  s->seconds_geometry = best.seconds_geometry;
}

}  // namespace

std::string ConnectivityDifference(const Mesh& first, const Mesh& pose) {
  if (pose.num_vertices() != first.num_vertices() || pose.num_faces() != first.num_faces()) {
    return StrCat(pose.num_vertices(), " vertices and ", pose.num_faces(), " faces against ", first.num_vertices(),
                  " and ", first.num_faces());
  }
  // Faces as corner sets, to tell faces in another order from other faces.
  auto corner_sets = [](const Faces& F) {
    std::vector<std::array<int, 3>> sets(F.rows());
    for (Eigen::Index f = 0; f < F.rows(); ++f) {
      sets[f] = {F(f, 0), F(f, 1), F(f, 2)};
      std::sort(sets[f].begin(), sets[f].end());
    }
    std::sort(sets.begin(), sets.end());
    return sets;
  };
  for (int f = 0; f < first.num_faces(); ++f) {
    const Eigen::RowVector3i a = first.F.row(f), b = pose.F.row(f);
    if (a == b) continue;
    // Only once a face differs: the sorts are not paid by the poses that agree (the normal case, checked by the
    // command as it reads each pose and again by DecimateAnimated).
    const bool same_sets = corner_sets(first.F) == corner_sets(pose.F);
    std::string what = same_sets ? "other vertices (the same triangles, in another order)" : "other vertices";
    for (int k = 0; k < 3; ++k) {
      if (b == Eigen::RowVector3i(a(k), a((k + 1) % 3), a((k + 2) % 3))) what = "its corners in another order";
      if (b == Eigen::RowVector3i(a(k), a((k + 2) % 3), a((k + 1) % 3))) what = "reversed orientation";
    }
    int differing = 0;
    for (int g = f; g < first.num_faces(); ++g) differing += first.F.row(g) == pose.F.row(g) ? 0 : 1;
    return StrCat("face ", f + 1, " (counting from 1) has ", what, ", and ", differing,
                  differing == 1 ? " face differs" : " faces differ",
                  " (the poses need the same faces in the same order)");
  }
  return "";
}

void DecimateOptions::Check() const {
  RB_CHECK(lambda > 0.0 && std::isfinite(lambda), "decimate: lambda must be positive, got ", lambda);
  RB_CHECK(target_faces >= 0, "decimate: target_faces must be ≥ 0, got ", target_faces);
  RB_CHECK(chain_reserve_share >= 0.0 && chain_reserve_share < 1.0, "decimate: chain_reserve_share must be in [0, 1)");
  RB_CHECK(lambda_resolution > 0.0 && lambda_resolution < 1.0, "decimate: lambda_resolution must be in (0, 1)");
  RB_CHECK(max_bisection_steps >= 2, "decimate: max_bisection_steps must be ≥ 2");
  RB_CHECK(max_rounds >= 1, "decimate: max_rounds must be ≥ 1");
  RB_CHECK(min_cos_to_patch_normal >= 0.0 && min_cos_to_patch_normal < 1.0,
           "decimate: min_cos_to_patch_normal must be in [0, 1)");
  RB_CHECK(chain_tolerance_rel >= 0.0, "decimate: chain_tolerance_rel must be ≥ 0");
  RB_CHECK(shading_regularisation >= 0.0, "decimate: shading_regularisation must be ≥ 0");
  RB_CHECK(corner_normal_ridge >= 0.0, "decimate: corner_normal_ridge must be ≥ 0");
  refit.Check();
}

std::vector<DecimatedMesh> DecimateAnimated(const std::vector<Mesh>& poses, const DecimateOptions& options,
                                            DecimateSummary* summary) {
  options.Check();
  RB_CHECK(!poses.empty(), "decimate: no input meshes");
  const auto t_start = Clock::now();
  DecimateSummary local;
  DecimateSummary& s = summary != nullptr ? *summary : local;
  StartSummary(poses, options, &s);
  const Prepared prep = Prepare(poses);
  s.notices = prep.notices;
  const Problem problem = BuildProblem(prep, options.weighting, &s.notices);
  const int ns = static_cast<int>(prep.split_source.size());
  const auto signature = TopologySignature(ns, prep.F, prep.topology);
  NoteComponentsAndLoops(prep, signature, &s.notices);

  Attempt best;
  double lambda = options.lambda;
  if (options.target_faces <= 0) {
    best = PartitionOnce(problem, lambda, options, options.progress);
    GeometryOnce(prep, options, 0, signature, &best);
    s.seconds_search_partition = best.seconds_partition;
    s.seconds_search_geometry = best.seconds_geometry;
  } else {
    best = LambdaSearch(prep, problem, signature, options, &s).Run(&lambda);
  }
  s.lambda = lambda;

  const auto t_refit = Clock::now();
  if (options.refit_vertices && !best.fell_back && options.refit.flip_sweeps > 0) {
    s.refit_flips = FlipEdgesBeforeRefit(prep, options, &best);
  }
  const WeldedOutput welded = WeldOutput(poses[0], prep, best);
  const PoseOutput pose_output(prep, problem, best, welded, options);
  std::vector<DecimatedMesh> out(poses.size());
  for (size_t m = 0; m < poses.size(); ++m) out[m] = pose_output.Build(poses[m], m, &s);

  RecordOutcome(best, welded, &s);
  s.seconds_refit_and_shading = Seconds(t_refit);
  s.seconds_total = Seconds(t_start);
  if (options.progress) options.progress(1.0, "done");
  return out;
}

DecimatedMesh Decimate(const Mesh& mesh, const DecimateOptions& options, DecimateSummary* summary) {
  std::vector<Mesh> poses{mesh};
  return std::move(DecimateAnimated(poses, options, summary)[0]);
}

double PatchShadingErrorDeg(const Mesh& pose, const std::vector<int>& dense_face_patch, double regularisation) {
  const int nf = pose.num_faces();
  RB_CHECK(static_cast<int>(dense_face_patch.size()) == nf, "decimate: patch map size does not match the pose");
  int num = 0;
  for (int k : dense_face_patch) num = std::max(num, k + 1);
  std::vector<double> area(nf, 0.0);
  std::vector<int> patch(nf, 0);
  for (int f = 0; f < nf; ++f) {
    const Eigen::Vector3d a = pose.V.row(pose.F(f, 0)).transpose(), b = pose.V.row(pose.F(f, 1)).transpose(),
                          c = pose.V.row(pose.F(f, 2)).transpose();
    area[f] = 0.5 * (b - a).cross(c - a).norm();
    patch[f] = dense_face_patch[f] < 0 ? 0 : dense_face_patch[f];
    if (dense_face_patch[f] < 0) area[f] = 0.0;
  }
  const auto fields = FitPatchNormalFields(pose.V, pose.F, area, patch, std::max(num, 1), regularisation);
  double sum = 0.0, total = 0.0;
  for (int f = 0; f < nf; ++f) {
    if (area[f] <= 0.0) continue;
    const Eigen::Vector3d a = pose.V.row(pose.F(f, 0)).transpose(), b = pose.V.row(pose.F(f, 1)).transpose(),
                          c = pose.V.row(pose.F(f, 2)).transpose();
    const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
    const Eigen::Vector3d s = fields[patch[f]].Evaluate((a + b + c) / 3.0);
    sum += area[f] * std::acos(std::clamp(n.dot(s), -1.0, 1.0));
    total += area[f];
  }
  return total > 0.0 ? sum / total * 180.0 / M_PI : 0.0;
}

std::string DecimateSummary::BriefReport() const {
  std::string out;
  char line[512];
  std::snprintf(line, sizeof(line), "input: %d faces%s\n", input_faces,
                poses > 1 ? (", " + std::to_string(poses) + " poses sharing one patch map").c_str() : "");
  out += line;
  std::snprintf(line, sizeof(line), "patches: %d; output: %d faces, %d vertices (%.2f%% of the input faces)\n",
                num_patches, output_faces, output_vertices, 100.0 * output_faces / std::max(1, input_faces));
  out += line;
  std::snprintf(line, sizeof(line), "lambda: %.6g%s; energy %.6g (data %.6g + lambda x patches %.6g)\n", lambda,
                target_faces > 0 ? (" (found in " + std::to_string(bisection_steps) + " full decimations)").c_str()
                                 : "",
                energy, data_energy, energy - data_energy);
  out += line;
  if (target_faces > 0) {
    // A fit's count is what the chain pass filled the budget to; only an overflow measures what the straightened
    // patches need.
    char too_many[96] = "fit at every lambda tried";
    if (lambda_too_many > 0) {
      std::snprintf(too_many, sizeof(too_many), "need %d faces at lambda %.6g", faces_too_many, lambda_too_many);
    }
    char fits[96] = "fit at no lambda tried";
    if (lambda_fits > 0) std::snprintf(fits, sizeof(fits), "fit in %d at lambda %.6g", faces_fits, lambda_fits);
    std::snprintf(line, sizeof(line),
                  "lambda search: straightened patches %s, %s (budget %d of %d; chain vertices kept up to chain error "
                  "%.3g%% of the diagonal)\n",
                  too_many, fits, budget_faces, target_faces, 100.0 * max_chain_error_rel);
    out += line;
  }
  std::snprintf(line, sizeof(line),
                "moves: %lld fuses, %lld splits, %lld swaps; %lld refused because they would disconnect a patch; "
                "%d rounds%s\n",
                fuses, splits, swaps, rejected_disconnecting, rounds, converged ? ", converged" : ", stopped at max_rounds");
  out += line;
  std::snprintf(line, sizeof(line),
                "vertices: %d where patches meet, %d more kept for chain shape or to avoid flipped triangles\n",
                kept_corner_vertices, blocked_vertices);
  out += line;
  if (refitted) {
    std::snprintf(line, sizeof(line),
                  "vertex refit: %d edges flipped, %d vertices moved, %d kept in place by the flip guard; quadric "
                  "error %.4g -> %.4g, fit RMS %.4g -> %.4g\n",
                  refit_flips, refit_moved, refit_blocked, refit_quadric_before, refit_quadric_after, refit_rms_before,
                  refit_rms_after);
    out += line;
  }
  std::snprintf(line, sizeof(line),
                "time: %.3f s partition, %.3f s geometry (all lambdas: %.3f s, %.3f s), %.3f s refit and shading, "
                "%.3f s total\n",
                seconds_partition, seconds_geometry, seconds_search_partition, seconds_search_geometry,
                seconds_refit_and_shading, seconds_total);
  out += line;
  return out;
}

}  // namespace rangebayes
