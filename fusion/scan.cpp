#include "fusion/scan.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>

#include "bayes/noise_model.h"
#include "bayes/smooth.h"
#include "core/error.h"
#include "core/render.h"
#include "core/topology.h"
#include "core/validate.h"

namespace rangebayes {
namespace {

Eigen::Matrix3d RayCovariance(const Eigen::Vector3d& r, double sigma_ray, double sigma_lat) {
  const double a = sigma_ray * sigma_ray - sigma_lat * sigma_lat;
  return a * r * r.transpose() + sigma_lat * sigma_lat * Eigen::Matrix3d::Identity();
}

// Vertex normals facing the sensor (and faces turned so that most face it).
void OrientTowardsSensor(Scan* scan) {
  Mesh& mesh = scan->noisy.mesh;
  double facing = 0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
    const Eigen::Vector3d n = (b - a).cross(c - a);
    facing += n.dot(scan->ray.row(mesh.F(f, 0)));
  }
  if (facing > 0) mesh.F.col(1).swap(mesh.F.col(2));
  scan->normal = AreaWeightedVertexNormals(mesh);
  for (int i = 0; i < mesh.num_vertices(); ++i) {
    if (scan->normal.row(i).dot(scan->ray.row(i)) > 0) scan->normal.row(i) *= -1.0;
  }
  scan->mean_edge = mesh.num_faces() > 0 ? MeanEdgeLength(mesh) : 0.0;
}

// Grid cells as pixel positions: Smooth then solves the scan as an organized mesh (coarse to fine).
void SetPixelPositions(const RangeGridScan& grid, Scan* scan) {
  const int w = grid.width, h = grid.height;
  scan->noisy.pixel.setConstant(scan->noisy.mesh.num_vertices(), 2, -1.0f);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const int v = grid.cell_vertex[static_cast<size_t>(y) * w + x];
      if (v >= 0) scan->noisy.pixel.row(v) << static_cast<float>(x), static_cast<float>(y);
    }
  }
}

// The line of one grid row in the (y, z) plane: the mean of its points and its unit direction (z ≤ 0).
struct RowLine {
  Eigen::Vector2d mean, direction;
  int points;
  double residual2;  // sum of the squared distances of the points from the line
};

std::optional<RowLine> FitRow(const RangeGridScan& grid, int y, const RangeGridScanOptions& options) {
  const Vertices& V = grid.mesh.mesh.V;
  const int w = grid.width;
  Eigen::Vector2d c = Eigen::Vector2d::Zero();
  int n = 0;
  for (int x = 0; x < w; ++x) {
    const int v = grid.cell_vertex[static_cast<size_t>(y) * w + x];
    if (v < 0) continue;
    c += Eigen::Vector2d(V(v, 1), V(v, 2));
    ++n;
  }
  if (n < 3) return std::nullopt;
  c /= n;
  Eigen::Matrix2d S = Eigen::Matrix2d::Zero();
  for (int x = 0; x < w; ++x) {
    const int v = grid.cell_vertex[static_cast<size_t>(y) * w + x];
    if (v < 0) continue;
    const Eigen::Vector2d d = Eigen::Vector2d(V(v, 1), V(v, 2)) - c;
    S += d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(S);
  // A row needs extent along its ray (5 σ) to define it.
  if (!(eig.eigenvalues()(1) > n * 25.0 * options.sigma_range * options.sigma_range)) return std::nullopt;
  Eigen::Vector2d d = eig.eigenvectors().col(1);
  if (d.y() > 0) d = -d;
  return RowLine{c, d, n, eig.eigenvalues()(0)};
}

// The least-squares normal equations A·centre = rhs of the point closest to all row lines, and what the
// parallel and axis ray models fall back on.
struct RowFit {
  Eigen::Matrix2d A = Eigen::Matrix2d::Zero();
  Eigen::Vector2d rhs = Eigen::Vector2d::Zero();
  Eigen::Vector2d mean_direction = Eigen::Vector2d::Zero();
  double residual2 = 0;
  int fitted_points = 0, fitted_rows = 0;
};

// Each grid row lies on one ray in the (y, z) plane: fit its line, then the common centre of the fan.
RowFit FitRows(const RangeGridScan& grid, const RangeGridScanOptions& options) {
  RowFit fit;
  for (int y = 0; y < grid.height; ++y) {
    const std::optional<RowLine> line = FitRow(grid, y, options);
    if (!line) continue;
    const Eigen::Vector2d& c = line->mean;
    const Eigen::Vector2d& d = line->direction;
    fit.residual2 += line->residual2;
    fit.fitted_points += line->points;
    ++fit.fitted_rows;
    const Eigen::Matrix2d P = Eigen::Matrix2d::Identity() - d * d.transpose();
    fit.A += P;
    fit.rhs += P * c;
    fit.mean_direction += d;
  }
  return fit;
}

// Rays from the fan's centre when the rows pin one down, else parallel to the rows, else along -z.
void AssignRays(const RowFit& fit, Scan* scan, RangeGridScanSummary* local) {
  const Vertices& V = scan->noisy.mesh.V;
  const int nv = static_cast<int>(V.rows());
  scan->ray.resize(nv, 3);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> conditioning(fit.A);
  const bool fan = fit.fitted_rows >= 2 && conditioning.eigenvalues()(0) > 1e-6 * conditioning.eigenvalues()(1);
  if (fan) {
    const Eigen::Vector2d centre = fit.A.ldlt().solve(fit.rhs);
    local->ray_model = "fan";
    local->sensor_centre = Eigen::Vector3d(0, centre.x(), centre.y());
    for (int i = 0; i < nv; ++i) {
      const Eigen::Vector3d r(0, V(i, 1) - centre.x(), V(i, 2) - centre.y());
      scan->ray.row(i) = r.norm() > 0 ? r.normalized() : Eigen::Vector3d(0, 0, -1);
    }
  } else {
    Eigen::Vector3d r(0, 0, -1);
    local->ray_model = "axis";
    if (fit.fitted_rows > 0 && fit.mean_direction.norm() > 0) {
      r = Eigen::Vector3d(0, fit.mean_direction.x(), fit.mean_direction.y()).normalized();
      local->ray_model = "parallel";
    }
    for (int i = 0; i < nv; ++i) scan->ray.row(i) = r;
  }
}

// Grid triangulation with the depth-image discontinuity cut, measured along the ray.
class GridTriangulation {
 public:
  GridTriangulation(const RangeGridScan& grid, const Vertices& ray, const RangeGridScanOptions& options)
      : grid_(grid),
        V_(grid.mesh.mesh.V),
        ray_(ray),
        slope_(std::tan(options.max_slope_deg * M_PI / 180.0)),
        allowed_noise_(options.max_jump_sigma * std::sqrt(2.0) * options.sigma_range) {}

  // Grid neighbours (left–right and up–down) that both hold a vertex and are cut apart.
  int CountCuts() const {
    const int w = grid_.width, h = grid_.height;
    int cuts = 0;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const int i0 = Cell(x, y);
        if (i0 < 0) continue;
        if (x + 1 < w && Cell(x + 1, y) >= 0) cuts += !Connected(i0, Cell(x + 1, y));
        if (y + 1 < h && Cell(x, y + 1) >= 0) cuts += !Connected(i0, Cell(x, y + 1));
      }
    }
    return cuts;
  }

  // Vertex indices, three per triangle, quad by quad in row order.
  std::vector<int> Triangulate() const {
    std::vector<int> faces;
    for (int y = 0; y + 1 < grid_.height; ++y) {
      for (int x = 0; x + 1 < grid_.width; ++x) TriangulateQuad(x, y, &faces);
    }
    return faces;
  }

 private:
  int Cell(int x, int y) const { return grid_.cell_vertex[static_cast<size_t>(y) * grid_.width + x]; }

  bool Connected(int a, int b) const {
    if (a < 0 || b < 0) return false;
    const Eigen::Vector3d d = V_.row(a) - V_.row(b);
    const Eigen::Vector3d r = (ray_.row(a) + ray_.row(b)).normalized();
    const double along = std::abs(d.dot(r));
    const double across = (d - d.dot(r) * r).norm();
    return along <= slope_ * across + allowed_noise_;
  }

  void TriangulateQuad(int x, int y, std::vector<int>* faces) const {
    const Vertices& V = V_;
    const int i0 = Cell(x, y), i1 = Cell(x + 1, y), i2 = Cell(x, y + 1), i3 = Cell(x + 1, y + 1);
    const bool e01 = Connected(i0, i1), e02 = Connected(i0, i2), e13 = Connected(i1, i3);
    const bool e23 = Connected(i2, i3), e03 = Connected(i0, i3), e12 = Connected(i1, i2);
    const bool A3 = e02 && e23 && e03, B3 = e03 && e13 && e01;
    const bool C3 = e02 && e12 && e01, D3 = e12 && e23 && e13;
    const auto put = [&](int a, int b, int c) { faces->insert(faces->end(), {a, b, c}); };
    if (A3 && B3 && C3 && D3) {
      if ((V.row(i0) - V.row(i3)).squaredNorm() <= (V.row(i1) - V.row(i2)).squaredNorm()) {
        put(i0, i2, i3);
        put(i0, i3, i1);
      } else {
        put(i0, i2, i1);
        put(i1, i2, i3);
      }
    } else if (A3 && B3) {
      put(i0, i2, i3);
      put(i0, i3, i1);
    } else if (C3 && D3) {
      put(i0, i2, i1);
      put(i1, i2, i3);
    } else if (A3) {
      put(i0, i2, i3);
    } else if (B3) {
      put(i0, i3, i1);
    } else if (C3) {
      put(i0, i2, i1);
    } else if (D3) {
      put(i1, i2, i3);
    }
  }

  const RangeGridScan& grid_;
  const Vertices& V_;
  const Vertices& ray_;
  const double slope_, allowed_noise_;
};

// Triangulation scanners lose range precision where the surface turns away from the ray; see
// RangeGridScanOptions::min_cos_incidence.
void InflateForIncidence(const RangeGridScanOptions& options, Scan* scan) {
  if (options.min_cos_incidence < 1) {
    for (int i = 0; i < scan->noisy.mesh.num_vertices(); ++i) {
      if (scan->normal.row(i).squaredNorm() < 0.5) continue;
      const double c = std::max(-scan->normal.row(i).dot(scan->ray.row(i)), options.min_cos_incidence);
      scan->noisy.covariance[i] = RayCovariance(scan->ray.row(i), options.sigma_range / c, options.sigma_lateral);
    }
  }
}

// A noise level near the size of the scan, or a millionth of it, is a mistake of units (millimetres given for a
// scan in metres, or the reverse): registration and fusion would then go wrong for a reason they cannot name
// (every residual inside one σ, the discontinuity cuts off; or a thousand σ away). Real sensors lie between: a
// long-range depth camera near 1/100 of its scene, a metrology scanner near 1e-5 of its part; a small piece of a
// scan may be only ten times its noise. The bounds were 1 and 1e-7, which let both mistakes through on the
// Stanford bunny scans (σ 0.2 for 0.2 mm on scans of 0.25 m; the scans in millimetres with σ in metres).
constexpr double kMaxNoiseOfDiagonal = 0.25;
constexpr double kMinNoiseOfDiagonal = 1e-6;

void CheckNoiseAgainstScanSize(const RangeGridScanOptions& options, const Vertices& V, const std::string& name) {
  const double diagonal = BoundingBoxExtent(V).norm();
  for (const auto& [what, sigma] : {std::pair<const char*, double>{"sigma_range", options.sigma_range},
                                    std::pair<const char*, double>{"sigma_lateral", options.sigma_lateral}}) {
    RB_CHECK(sigma <= kMaxNoiseOfDiagonal * diagonal, name, ": ", what, " ", sigma, " is over ", kMaxNoiseOfDiagonal,
             " of the scan's size (bounding-box diagonal ", diagonal, "); give the noise in the scan's units");
    RB_CHECK(sigma >= kMinNoiseOfDiagonal * diagonal, name, ": ", what, " ", sigma, " is under ", kMinNoiseOfDiagonal,
             " of the scan's size (bounding-box diagonal ", diagonal, "); give the noise in the scan's units");
  }
}

}  // namespace

void RangeGridScanOptions::Check() const {
  RB_CHECK(sigma_range > 0 && std::isfinite(sigma_range), "sigma_range ", sigma_range, " must be positive");
  RB_CHECK(sigma_lateral > 0 && std::isfinite(sigma_lateral), "sigma_lateral ", sigma_lateral,
           " must be positive");
  RB_CHECK(min_cos_incidence > 0 && min_cos_incidence <= 1, "min_cos_incidence ", min_cos_incidence,
           " is outside (0, 1]");
  RB_CHECK(max_jump_sigma > 0, "max_jump_sigma ", max_jump_sigma, " must be positive");
  RB_CHECK(max_slope_deg >= 0 && max_slope_deg < 89.95, "max_slope_deg ", max_slope_deg, " is outside 0–89.9");
}

Scan MakeRangeGridScan(const RangeGridScan& grid, const std::string& name, const RangeGridScanOptions& options,
                       RangeGridScanSummary* summary) {
  options.Check();
  RB_CHECK(grid.has_grid(), name, ": no range_grid element (not an organized scan)");
  const Vertices& V = grid.mesh.mesh.V;
  RB_CHECK(V.rows() > 0, name, ": empty scan (no vertices)");
  CheckComputableScale(V, name);
  Scan scan;
  scan.name = name;
  scan.noisy.mesh.V = V;
  const int nv = static_cast<int>(V.rows());
  SetPixelPositions(grid, &scan);
  const RowFit fit = FitRows(grid, options);
  RangeGridScanSummary local;
  local.row_fit_rms = fit.fitted_points > 0 ? std::sqrt(fit.residual2 / fit.fitted_points) : 0.0;
  AssignRays(fit, &scan, &local);
  scan.noisy.covariance.resize(nv);
  for (int i = 0; i < nv; ++i) {
    scan.noisy.covariance[i] = RayCovariance(scan.ray.row(i), options.sigma_range, options.sigma_lateral);
  }
  const GridTriangulation triangulation(grid, scan.ray, options);
  const int cuts = triangulation.CountCuts();
  const std::vector<int> faces = triangulation.Triangulate();
  RB_CHECK(!faces.empty(), name, ": empty scan (no triangle: no two neighbouring grid cells hold vertices)");
  CheckNoiseAgainstScanSize(options, V, name);
  scan.noisy.mesh.F = Eigen::Map<const Faces>(faces.data(), static_cast<Eigen::Index>(faces.size() / 3), 3);
  OrientTowardsSensor(&scan);
  InflateForIncidence(options, &scan);
  local.vertices = nv;
  local.faces = scan.noisy.mesh.num_faces();
  local.cut_edges = cuts;
  if (summary) *summary = local;
  return scan;
}

namespace {

// The rays of a mesh scan with covariances. A ray-aligned covariance (a scanner's, a stereo mesh's) is longest
// along its ray. Where those axes lie along the lines from the origin, the sensor is at the origin (a mesh in its
// camera's frame, as `replay` writes them): the rays are p / |p|, and OrientTowardsSensor turns the faces to it.
// Where they do not (a range grid read as a mesh whose scanner's origin lies inside the object, as the Stanford
// scans'; a scan moved into world coordinates), the axes are the rays, pointed into the surface as the file's
// faces say: the rays from the origin flipped normals there and fused the scan with holes (98 components instead
// of 39 on two bunny scans). A mesh whose covariances are not elongated keeps the rays from the origin.
Vertices SensorRays(const NoisyMesh& mesh) {
  const int nv = mesh.mesh.num_vertices();
  Vertices from_origin(nv, 3), axes(nv, 3);
  int elongated = 0, along_origin = 0;
  for (int i = 0; i < nv; ++i) {
    const Eigen::Vector3d p = mesh.mesh.V.row(i);
    from_origin.row(i) = p.norm() > 0 ? p.normalized() : Eigen::Vector3d(0, 0, 1);
    // A covariance that is not finite gives NaN here and is refused by the caller's check of every covariance.
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(mesh.covariance[static_cast<size_t>(i)]);
    axes.row(i) = eig.eigenvectors().col(2);
    // Elongated: the largest variance at least twice the next (stereo and the scanners here: 10–1000×).
    if (!(eig.eigenvalues()(2) >= 2.0 * eig.eigenvalues()(1))) continue;
    ++elongated;
    if (std::abs(axes.row(i).dot(from_origin.row(i))) >= std::cos(25.0 * M_PI / 180.0)) ++along_origin;
  }
  if (elongated < nv / 2 || along_origin >= 0.9 * elongated) return from_origin;
  const Normals faces = AreaWeightedVertexNormals(mesh.mesh);
  for (int i = 0; i < nv; ++i) {
    if (axes.row(i).dot(faces.row(i)) > 0) axes.row(i) *= -1.0;
  }
  return axes;
}

}  // namespace

Scan MakeScanFromMesh(const NoisyMesh& mesh, const std::string& name) {
  RB_CHECK(mesh.mesh.num_vertices() > 0 && mesh.mesh.num_faces() > 0, name,
           ": empty scan (", mesh.mesh.num_vertices(), " vertices, ", mesh.mesh.num_faces(), " faces)");
  CheckComputableScale(mesh.mesh.V, name);
  Scan scan;
  scan.name = name;
  const int nv = mesh.mesh.num_vertices();
  if (mesh.has_covariance()) {
    scan.noisy = mesh;
    scan.ray = SensorRays(mesh);
    for (int i = 0; i < nv; ++i) {
      // Fusion weighs each vertex by 1 / its variance along the ray: a zero or indefinite covariance made the
      // fused mesh NaN where it fell (exit 0), as smoothing refuses it.
      const Eigen::Matrix3d& c = mesh.covariance[static_cast<size_t>(i)];
      Eigen::Matrix3d information;
      const Eigen::Vector3d ray = scan.ray.row(i);
      RB_CHECK(InformationFromCovariance(c, &information) && ray.dot(c * ray) > 0, name, ": the covariance of vertex ",
               i, " is not finite, positive semi-definite and non-zero along its ray");
    }
    OrientTowardsSensor(&scan);
    return scan;
  }
  scan.noisy = MakeGenericNoisyMesh(mesh.mesh);
  scan.normal = AreaWeightedVertexNormals(scan.noisy.mesh);
  scan.ray = -scan.normal;
  scan.mean_edge = MeanEdgeLength(scan.noisy.mesh);
  return scan;
}

Scan SmoothScan(const Scan& scan, const SmoothOptions& options, SmoothSummary* summary) {
  Scan out = scan;
  out.noisy.mesh = Smooth(scan.noisy, options, summary);
  out.noisy.mesh.N.resize(0, 3);
  OrientTowardsSensor(&out);
  return out;
}

namespace {
// Whether a PLY read as `grid` is triangulated from its grid: it has one and lists no faces of its own (the file's
// faces win, so that ReadScan and ReadMeshOrRangeGrid agree on every file).
bool TriangulatesGrid(const RangeGridScan& grid) { return grid.has_grid() && grid.mesh.mesh.num_faces() == 0; }
}  // namespace

Scan ReadScan(const std::string& path, const RangeGridScanOptions& options, RangeGridScanSummary* summary) {
  const bool ply = MeshFormatFromPath(path) == MeshFormat::kPly;
  if (ply) {
    RangeGridScan grid = ReadRangeGridScan(path);
    if (TriangulatesGrid(grid)) return MakeRangeGridScan(grid, path, options, summary);
    return MakeScanFromMesh(grid.mesh, path);
  }
  return MakeScanFromMesh(ReadNoisyMesh(path), path);
}

NoisyMesh ReadMeshOrRangeGrid(const std::string& path, MeshReadSummary* summary, const RangeGridScanOptions& options) {
  if (MeshFormatFromPath(path) != MeshFormat::kPly) return ReadNoisyMesh(path, summary);
  RangeGridScan grid = ReadRangeGridScan(path, summary);
  if (!TriangulatesGrid(grid)) return std::move(grid.mesh);
  RangeGridScanSummary made;
  Scan scan = MakeRangeGridScan(grid, path, options, &made);
  if (summary != nullptr) {
    summary->range_grid = StrCat("range grid ", grid.width, "x", grid.height, " triangulated: ", made.faces, " faces, ",
                                 made.cut_edges, made.cut_edges == 1 ? " edge" : " edges",
                                 " cut at discontinuities; covariance along the scanner's rays (", made.ray_model, ")");
  }
  return std::move(scan.noisy);
}

}  // namespace rangebayes
