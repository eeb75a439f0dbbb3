// Bayesian decimation against CGAL's quadric edge collapse (Garland–Heckbert plane policies, QSlim-style) and
// CGAL's variational shape approximation (Cohen-Steiner et al. 2004) at equal triangle count.
//
//   bench_decimate_compare MESH [SHARE ...] [--reserve R] [--bayes-only] [--no-vsa] [--no-refit] [--both]
//   (default shares 0.02 0.10)
//
// --reserve sets DecimateOptions::chain_reserve_share (default: the library's); --bayes-only skips CGAL;
// --no-vsa skips VSA only; --no-refit turns the vertex refit off; --both prints ours without the refit
// ("bayes-sub", vertices a subset of the input's) before ours with it; --refit-reg X sets
// VertexRefitOptions::regularisation, --fit-rounds N its fit_rounds, --coverage X its coverage_weight,
// --flip-sweeps N its flip_sweeps (0: no edge flips), --corner-ridge X DecimateOptions::corner_normal_ridge (0: the
// patch fields' normals at the corners); --write DIR writes each output as DIR/METHOD_SHARE.obj (an existing folder).
//
// Per method and share it prints: output triangles, symmetric Hausdorff and RMS surface distance (relative to
// the bounding-box diagonal, from area-uniform samples on both surfaces), the area-weighted angle between each
// dense face normal and the decimated shading normal at the closest point (degrees), and the mean absolute
// difference of Lambert renderings (grey levels 0–255, over pixels covered in either image) from 14 views.
// Shading normals: ours, the per-patch linear fields; CGAL outputs, the better (per metric) of flat face
// normals and area-weighted vertex normals. CGAL is used here only (bench), never by the library.
#include <CGAL/AABB_traits.h>
#include <CGAL/AABB_tree.h>
#include <CGAL/AABB_triangle_primitive.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/Surface_mesh_approximation/approximate_triangle_mesh.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/Count_stop_predicate.h>
#include <CGAL/Surface_mesh_simplification/Policies/Edge_collapse/GarlandHeckbert_plane_policies.h>
#include <CGAL/Surface_mesh_simplification/edge_collapse.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <random>
#include <string>
#include <vector>

#include "bayes/decimation/decimate.h"
#include "bench/bench_main.h"
#include "core/mesh_io.h"
#include "core/render.h"

namespace {

using namespace rangebayes;
using K = CGAL::Simple_cartesian<double>;
using Point = K::Point_3;
using SurfaceMesh = CGAL::Surface_mesh<Point>;
using Triangle = K::Triangle_3;
using TriangleIt = std::vector<Triangle>::const_iterator;
using Primitive = CGAL::AABB_triangle_primitive<K, TriangleIt>;
using Tree = CGAL::AABB_tree<CGAL::AABB_traits<K, Primitive>>;
namespace SMS = CGAL::Surface_mesh_simplification;

double Now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// A decimated mesh with per-corner shading normals (#F·3 rows, corner k of face f at 3f + k).
struct Shaded {
  Mesh mesh;
  Normals corner;
};

Normals FlatCorners(const Mesh& m) {
  Normals n(3 * m.num_faces(), 3);
  for (int f = 0; f < m.num_faces(); ++f) {
    const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
    Eigen::Vector3d x = (b - a).cross(c - a);
    if (x.norm() > 0) x.normalize();
    for (int k = 0; k < 3; ++k) n.row(3 * f + k) = x.transpose();
  }
  return n;
}

Normals SmoothCorners(const Mesh& m) {
  const Normals vn = AreaWeightedVertexNormals(m);
  Normals n(3 * m.num_faces(), 3);
  for (int f = 0; f < m.num_faces(); ++f) {
    for (int k = 0; k < 3; ++k) n.row(3 * f + k) = vn.row(m.F(f, k));
  }
  return n;
}

SurfaceMesh ToCgal(const Mesh& m) {
  SurfaceMesh sm;
  std::vector<SurfaceMesh::Vertex_index> vi;
  for (int v = 0; v < m.num_vertices(); ++v) vi.push_back(sm.add_vertex(Point(m.V(v, 0), m.V(v, 1), m.V(v, 2))));
  for (int f = 0; f < m.num_faces(); ++f) sm.add_face(vi[m.F(f, 0)], vi[m.F(f, 1)], vi[m.F(f, 2)]);
  return sm;
}

Mesh FromCgal(SurfaceMesh sm) {
  sm.collect_garbage();
  Mesh m;
  m.V.resize(static_cast<Eigen::Index>(sm.number_of_vertices()), 3);
  for (auto v : sm.vertices()) {
    const Point& p = sm.point(v);
    m.V.row(static_cast<Eigen::Index>(v.idx())) << p.x(), p.y(), p.z();
  }
  m.F.resize(static_cast<Eigen::Index>(sm.number_of_faces()), 3);
  int f = 0;
  for (auto face : sm.faces()) {
    int k = 0;
    for (auto v : sm.vertices_around_face(sm.halfedge(face))) m.F(f, k++) = static_cast<int>(v.idx());
    ++f;
  }
  return m;
}

Mesh GarlandHeckbert(const Mesh& dense, int target_faces) {
  // Count_stop_predicate counts edges: a closed triangle mesh has 1.5 edges per face.
  int edges = static_cast<int>(1.5 * target_faces);
  Mesh out;
  for (int attempt = 0; attempt < 3; ++attempt) {
    SurfaceMesh sm = ToCgal(dense);
    SMS::Count_stop_predicate<SurfaceMesh> stop(static_cast<std::size_t>(edges));
    SMS::GarlandHeckbert_plane_policies<SurfaceMesh, K> policies(sm);
    SMS::edge_collapse(sm, stop, CGAL::parameters::get_cost(policies.get_cost()).get_placement(policies.get_placement()));
    out = FromCgal(sm);
    const int miss = target_faces - out.num_faces();
    if (std::abs(miss) <= std::max(2, target_faces / 200)) break;
    edges += static_cast<int>(1.5 * miss);
  }
  return out;
}

Mesh Vsa(const Mesh& dense, int proxies) {
  SurfaceMesh sm = ToCgal(dense);
  std::vector<Point> anchors;
  std::vector<std::array<std::size_t, 3>> triangles;
  CGAL::Surface_mesh_approximation::approximate_triangle_mesh(
      sm, CGAL::parameters::max_number_of_proxies(static_cast<std::size_t>(proxies))
              .number_of_iterations(20)
              .anchors(std::back_inserter(anchors))
              .triangles(std::back_inserter(triangles)));
  Mesh m;
  m.V.resize(static_cast<Eigen::Index>(anchors.size()), 3);
  for (size_t i = 0; i < anchors.size(); ++i) m.V.row(static_cast<Eigen::Index>(i)) << anchors[i].x(), anchors[i].y(), anchors[i].z();
  m.F.resize(static_cast<Eigen::Index>(triangles.size()), 3);
  for (size_t i = 0; i < triangles.size(); ++i) {
    m.F.row(static_cast<Eigen::Index>(i)) << static_cast<int>(triangles[i][0]), static_cast<int>(triangles[i][1]),
        static_cast<int>(triangles[i][2]);
  }
  return m;
}

// VSA's triangle count follows the proxy count only roughly: bisect on proxies.
Mesh VsaAt(const Mesh& dense, int target_faces) {
  int lo = 4, hi = std::max(8, target_faces);
  Mesh best;
  int best_miss = 1 << 30;
  for (int step = 0; step < 10 && lo <= hi; ++step) {
    const int mid = (lo + hi) / 2;
    Mesh m = Vsa(dense, mid);
    const int miss = m.num_faces() - target_faces;
    if (std::abs(miss) < best_miss) {
      best_miss = std::abs(miss);
      best = m;
    }
    if (std::abs(miss) <= std::max(2, target_faces / 50)) break;
    if (miss > 0) {
      hi = mid - 1;
    } else {
      lo = mid + 1;
    }
  }
  return best;
}

std::vector<Triangle> Triangles(const Mesh& m) {
  std::vector<Triangle> t;
  for (int f = 0; f < m.num_faces(); ++f) {
    auto p = [&](int k) { return Point(m.V(m.F(f, k), 0), m.V(m.F(f, k), 1), m.V(m.F(f, k), 2)); };
    t.emplace_back(p(0), p(1), p(2));
  }
  return t;
}

// Area-uniform samples (plus all vertices) on a mesh.
std::vector<Point> Samples(const Mesh& m, int count, unsigned seed) {
  std::vector<double> cum;
  double total = 0.0;
  for (int f = 0; f < m.num_faces(); ++f) {
    const Eigen::Vector3d a = m.V.row(m.F(f, 0)), b = m.V.row(m.F(f, 1)), c = m.V.row(m.F(f, 2));
    total += 0.5 * (b - a).cross(c - a).norm();
    cum.push_back(total);
  }
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Point> s;
  for (int i = 0; i < count; ++i) {
    const int f = static_cast<int>(std::lower_bound(cum.begin(), cum.end(), u(rng) * total) - cum.begin());
    double r1 = u(rng), r2 = u(rng);
    if (r1 + r2 > 1) {
      r1 = 1 - r1;
      r2 = 1 - r2;
    }
    const Eigen::Vector3d a = m.V.row(m.F(std::min(f, m.num_faces() - 1), 0)), b = m.V.row(m.F(std::min(f, m.num_faces() - 1), 1)),
                          c = m.V.row(m.F(std::min(f, m.num_faces() - 1), 2));
    const Eigen::Vector3d p = a + r1 * (b - a) + r2 * (c - a);
    s.emplace_back(p.x(), p.y(), p.z());
  }
  return s;
}

struct Distances {
  double hausdorff = 0.0, rms = 0.0;
};

// One direction: samples of `from` against the surface of `to`: max and sum of squares.
void OneWay(const std::vector<Point>& samples, const Tree& tree, double* max_d, double* sum2) {
  for (const Point& p : samples) {
    const double d2 = tree.squared_distance(p);
    *max_d = std::max(*max_d, std::sqrt(d2));
    *sum2 += d2;
  }
}

struct Metrics {
  int faces = 0;
  double hausdorff = 0.0, rms = 0.0, normal_deg = 0.0, render_diff = 0.0;
};

double Diagonal(const Mesh& m) { return BoundingBoxExtent(m.V).norm(); }

// Area-weighted angle between each dense face normal and the interpolated shading normal at the closest point.
double NormalError(const Mesh& dense, const std::vector<Triangle>& tris, const Tree& tree, const Shaded& x) {
  double sum = 0.0, total = 0.0;
  for (int f = 0; f < dense.num_faces(); ++f) {
    const Eigen::Vector3d a = dense.V.row(dense.F(f, 0)), b = dense.V.row(dense.F(f, 1)), c = dense.V.row(dense.F(f, 2));
    const Eigen::Vector3d cr = (b - a).cross(c - a);
    const double area = 0.5 * cr.norm();
    if (area <= 0) continue;
    const Eigen::Vector3d centroid = (a + b + c) / 3.0;
    const auto hit = tree.closest_point_and_primitive(Point(centroid.x(), centroid.y(), centroid.z()));
    const int t = static_cast<int>(hit.second - tris.begin());
    const Eigen::Vector3d p(hit.first.x(), hit.first.y(), hit.first.z());
    const Eigen::Vector3d A = x.mesh.V.row(x.mesh.F(t, 0)), B = x.mesh.V.row(x.mesh.F(t, 1)), C = x.mesh.V.row(x.mesh.F(t, 2));
    // Barycentric coordinates of p in ABC.
    const Eigen::Vector3d v0 = B - A, v1 = C - A, v2 = p - A;
    const double d00 = v0.dot(v0), d01 = v0.dot(v1), d11 = v1.dot(v1), d20 = v2.dot(v0), d21 = v2.dot(v1);
    const double den = d00 * d11 - d01 * d01;
    double wb = den != 0 ? (d11 * d20 - d01 * d21) / den : 1.0 / 3, wc = den != 0 ? (d00 * d21 - d01 * d20) / den : 1.0 / 3;
    const double wa = 1 - wb - wc;
    Eigen::Vector3d n = wa * x.corner.row(3 * t).transpose() + wb * x.corner.row(3 * t + 1).transpose() +
                        wc * x.corner.row(3 * t + 2).transpose();
    if (n.norm() == 0) continue;
    n.normalize();
    sum += area * std::acos(std::clamp(n.dot(cr / (2 * area)), -1.0, 1.0));
    total += area;
  }
  return sum / total * 180.0 / M_PI;
}

// Adds the dense mesh's bounding-box corners as two unused vertices so every render fits the same box.
Mesh WithBox(const Mesh& m, const Mesh& dense) {
  Mesh out = m;
  out.V.conservativeResize(m.num_vertices() + 2, 3);
  out.V.row(m.num_vertices()) = dense.V.colwise().minCoeff();
  out.V.row(m.num_vertices() + 1) = dense.V.colwise().maxCoeff();
  return out;
}

std::vector<Eigen::Vector3d> Views() {
  std::vector<Eigen::Vector3d> v = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
  for (int sx : {-1, 1}) {
    for (int sy : {-1, 1}) {
      for (int sz : {-1, 1}) v.emplace_back(sx, sy, sz);
    }
  }
  return v;
}

double Grey(const RgbImage& im, int x, int y) {
  const auto* p = im.at(x, y);
  return (p[0] + p[1] + p[2]) / 3.0;
}
bool Covered(const RgbImage& im, int x, int y) {
  const auto* p = im.at(x, y);
  return !(p[0] == 255 && p[1] == 255 && p[2] == 255);
}

std::vector<RgbImage> RenderViews(const Mesh& m, const Normals& corner, const Mesh& dense, bool smooth) {
  std::vector<RgbImage> images;
  for (const Eigen::Vector3d& view : Views()) {
    RenderOptions o;
    o.width_px = 320;
    o.height_px = 320;
    o.view_direction = view;
    o.up = std::abs(view.z()) > 0.9 * view.norm() ? Eigen::Vector3d(0, 1, 0) : Eigen::Vector3d(0, 0, 1);
    o.two_sided = false;
    if (smooth) {
      o.shading = Shading::kSmooth;
      o.corner_normals = corner;
    }
    images.push_back(RenderMesh(WithBox(m, dense), o));
  }
  return images;
}

double RenderDiff(const std::vector<RgbImage>& a, const std::vector<RgbImage>& b) {
  double sum = 0.0;
  long long count = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    for (int y = 0; y < a[i].height; ++y) {
      for (int x = 0; x < a[i].width; ++x) {
        if (!Covered(a[i], x, y) && !Covered(b[i], x, y)) continue;
        sum += std::abs(Grey(a[i], x, y) - Grey(b[i], x, y));
        ++count;
      }
    }
  }
  return count > 0 ? sum / count : 0.0;
}

struct Reference {
  Mesh dense;
  std::vector<Triangle> tris;
  Tree tree;
  std::vector<Point> samples;
  std::vector<RgbImage> renders;
  double diag = 1.0;
};

Metrics Evaluate(const Reference& ref, const std::vector<Shaded>& candidates) {
  Metrics best;
  best.faces = candidates[0].mesh.num_faces();
  const std::vector<Triangle> tris = Triangles(candidates[0].mesh);
  Tree tree(tris.begin(), tris.end());
  tree.accelerate_distance_queries();
  double max_d = 0.0, sum_a = 0.0, sum_b = 0.0;
  OneWay(ref.samples, tree, &max_d, &sum_a);
  const std::vector<Point> xs = Samples(candidates[0].mesh, static_cast<int>(ref.samples.size()), 11);
  OneWay(xs, ref.tree, &max_d, &sum_b);
  best.hausdorff = max_d / ref.diag;
  best.rms = std::sqrt((sum_a + sum_b) / (ref.samples.size() + xs.size())) / ref.diag;
  best.normal_deg = 1e9;
  best.render_diff = 1e9;
  for (const Shaded& c : candidates) {
    best.normal_deg = std::min(best.normal_deg, NormalError(ref.dense, tris, tree, c));
    best.render_diff = std::min(best.render_diff, RenderDiff(ref.renders, RenderViews(c.mesh, c.corner, ref.dense, true)));
  }
  return best;
}

void Print(const char* method, double share, const Metrics& m, double seconds) {
  std::printf("%-10s %5.1f%% %7d %10.5f %10.6f %9.3f %9.3f %8.2f\n", method, 100 * share, m.faces, m.hausdorff, m.rms,
              m.normal_deg, m.render_diff, seconds);
  std::fflush(stdout);
}

}  // namespace

int RunBench(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s MESH [SHARE ...]\n", argv[0]);
    return 2;
  }
  std::vector<double> shares;
  double reserve = DecimateOptions{}.chain_reserve_share;
  bool bayes_only = false, no_vsa = false, refit = true, both = false;
  double refit_reg = VertexRefitOptions{}.regularisation;
  int fit_rounds = VertexRefitOptions{}.fit_rounds;
  double coverage = VertexRefitOptions{}.coverage_weight;
  int flip_sweeps = VertexRefitOptions{}.flip_sweeps;
  double corner_ridge = DecimateOptions{}.corner_normal_ridge;
  std::string write_dir;
  for (int i = 2; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--reserve" && i + 1 < argc) {
      reserve = std::atof(argv[++i]);
    } else if (arg == "--bayes-only") {
      bayes_only = true;
    } else if (arg == "--fit-rounds" && i + 1 < argc) {
      fit_rounds = std::atoi(argv[++i]);
    } else if (arg == "--coverage" && i + 1 < argc) {
      coverage = std::atof(argv[++i]);
    } else if (arg == "--flip-sweeps" && i + 1 < argc) {
      flip_sweeps = std::atoi(argv[++i]);
    } else if (arg == "--refit-reg" && i + 1 < argc) {
      refit_reg = std::atof(argv[++i]);
    } else if (arg == "--corner-ridge" && i + 1 < argc) {
      corner_ridge = std::atof(argv[++i]);
    } else if (arg == "--write" && i + 1 < argc) {
      write_dir = argv[++i];
    } else if (arg == "--no-vsa") {
      no_vsa = true;
    } else if (arg == "--no-refit") {
      refit = false;
    } else if (arg == "--both") {
      both = true;
    } else {
      shares.push_back(std::atof(argv[i]));
    }
  }
  if (shares.empty()) shares = {0.02, 0.10};
  auto write = [&](const char* method, double share, const Mesh& mesh) {
    if (write_dir.empty()) return;
    char name[64];
    std::snprintf(name, sizeof(name), "/%s_%g.obj", method, share);
    WriteMesh(mesh, write_dir + name);
  };
  Reference ref;
  ref.dense = ReadMesh(argv[1]);
  ref.diag = Diagonal(ref.dense);
  ref.tris = Triangles(ref.dense);
  ref.tree.insert(ref.tris.begin(), ref.tris.end());
  ref.tree.accelerate_distance_queries();
  ref.samples = Samples(ref.dense, 100000, 7);
  ref.renders = RenderViews(ref.dense, Normals(), ref.dense, false);
  std::printf("%s: %d faces, bbox diagonal %.4g\n", argv[1], ref.dense.num_faces(), ref.diag);
  std::printf("%-10s %6s %7s %10s %10s %9s %9s %8s\n", "method", "share", "faces", "hausdorff", "rms", "normal°",
              "render", "time s");
  for (double share : shares) {
    const int target = std::max(4, static_cast<int>(std::lround(share * ref.dense.num_faces())));
    double t0 = 0.0;
    DecimatedMesh ours;
    for (int pass = both ? 0 : 1; pass < 2; ++pass) {
      t0 = Now();
      DecimateOptions options;
      options.target_faces = target;
      options.chain_reserve_share = reserve;
      options.refit_vertices = pass == 1 && refit;
      options.refit.regularisation = refit_reg;
      options.refit.fit_rounds = fit_rounds;
      options.refit.coverage_weight = coverage;
      options.refit.flip_sweeps = flip_sweeps;
      options.corner_normal_ridge = corner_ridge;
      DecimateSummary summary;
      ours = Decimate(ref.dense, options, &summary);
      const double t_ours = Now() - t0;
      Normals corner(3 * ours.mesh.num_faces(), 3);
      for (int f = 0; f < ours.mesh.num_faces(); ++f) {
        for (int k = 0; k < 3; ++k) corner.row(3 * f + k) = ours.corner_normals.normals.row(ours.corner_normals.normal_index(f, k));
      }
      Print(options.refit_vertices ? "bayes" : "bayes-sub", share, Evaluate(ref, {{ours.mesh, corner}}), t_ours);
      write(options.refit_vertices ? "bayes" : "bayes-sub", share, ours.mesh);
      std::printf("           (%d patches, lambda %.4g, chain reserve %.2f, chain error up to %.3g%% of the diagonal, "
                  "refit: %d flips, %d moved, %d blocked, fit rms %.3g -> %.3g, refit and shading %.2f s)\n",
                  summary.num_patches, summary.lambda, reserve, 100.0 * summary.max_chain_error_rel, summary.refit_flips,
                  summary.refit_moved, summary.refit_blocked, summary.refit_rms_before, summary.refit_rms_after,
                  summary.seconds_refit_and_shading);
    }
    if (bayes_only) continue;
    const int n = ours.mesh.num_faces();
    t0 = Now();
    const Mesh gh = GarlandHeckbert(ref.dense, n);
    const double t_gh = Now() - t0;
    Print("qslim", share, Evaluate(ref, {{gh, SmoothCorners(gh)}, {gh, FlatCorners(gh)}}), t_gh);
    write("qslim", share, gh);
    if (no_vsa) continue;
    t0 = Now();
    const Mesh vsa = VsaAt(ref.dense, n);
    const double t_vsa = Now() - t0;
    Print("vsa", share, Evaluate(ref, {{vsa, SmoothCorners(vsa)}, {vsa, FlatCorners(vsa)}}), t_vsa);
    write("vsa", share, vsa);
  }
  return 0;
}

// Bad input (a missing file, a wrong option or value) ends with one error line and exit code 1, not an abort.
int main(int argc, char** argv) { return rangebayes::bench::Main("bench_decimate_compare", RunBench, argc, argv); }
