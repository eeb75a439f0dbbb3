#include "fusion/tsdf.h"

// Only the classic marching-cubes tables (Paul Bourke's, as PCL ships them) are used from PCL here.
#include <pcl/surface/marching_cubes.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_map>

#include "core/error.h"
#include "core/topology.h"

namespace rangebayes {
namespace {

// Marching-cubes cube corners and the corner pairs of its twelve edges, in the order of PCL's tables.
const int kCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
const int kEdge[12][2] = {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {4, 5}, {5, 6},
                          {6, 7}, {7, 4}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};

// What fusion needs from the scans before the grid exists: their world bounding box, the mean edge length and
// a sample of the measurement variances along the rays.
struct ScanExtent {
  double mean_edge = 0;
  std::vector<double> sigma2;
  Eigen::AlignedBox3d box;
};

ScanExtent MeasureScans(const std::vector<Scan>& scans, const std::vector<Eigen::Isometry3d>& world_from_scan) {
  ScanExtent extent;
  for (size_t s = 0; s < scans.size(); ++s) {
    const Scan& scan = scans[s];
    RB_CHECK(scan.noisy.has_covariance() && scan.normal.rows() == scan.num_vertices() &&
                 scan.ray.rows() == scan.num_vertices(),
             scan.name, ": scan lacks normals, rays or covariances");
    extent.mean_edge += scan.mean_edge / scans.size();
    for (int i = 0; i < scan.num_vertices(); ++i) {
      if (scan.normal.row(i).squaredNorm() < 0.5) continue;
      extent.box.extend(world_from_scan[s] * Eigen::Vector3d(scan.noisy.mesh.V.row(i)));
      if (i % 16 == 0) {
        const Eigen::Vector3d r = scan.ray.row(i);
        extent.sigma2.push_back(r.dot(scan.noisy.covariance[i] * r));
      }
    }
  }
  RB_CHECK(!extent.box.isEmpty() && !extent.sigma2.empty(), "fusion: the scans hold no vertex on a triangle");
  return extent;
}

// The voxel grid: per voxel the weighted signed distance D, the weight W and V2.
struct Grid {
  double voxel = 0, tau = 0;  // voxel edge and truncation distance, model units
  Eigen::Vector3d origin;
  Eigen::Vector3i dims;
  std::vector<float> D, W;
  // Σ w²·(variance of the measurement along its normal): the variance of the weighted mean is this / (Σw)².
  std::vector<float> V2;

  size_t At(int x, int y, int z) const { return (static_cast<size_t>(z) * dims.y() + y) * dims.x() + x; }
  Eigen::Vector3d Position(int x, int y, int z) const { return origin + voxel * Eigen::Vector3d(x, y, z); }
};

// An empty grid over the box, grown by the truncation distance and two voxels.
Grid MakeGrid(const ScanExtent& extent, const FuseOptions& options) {
  Grid grid;
  const double voxel = options.voxel_size > 0 ? options.voxel_size : options.voxel_edges * extent.mean_edge;
  RB_CHECK(voxel > 0, "fusion: voxel size is zero (scans without edges)");
  const double tau = options.truncation_voxels * voxel;
  grid.voxel = voxel;
  grid.tau = tau;
  grid.origin = extent.box.min().array() - (tau + 2 * voxel);
  const Eigen::Vector3d size = extent.box.max().array() + (tau + 2 * voxel) - grid.origin.array();
  // Counted in double first: a voxel far too small for the scene (1e-9 of it) overflowed the int sides, and the
  // wrapped count passed the guard.
  const Eigen::Vector3d sides = (size / voxel).array().ceil() + 1;
  const double total_d = sides.prod();
  RB_CHECK(total_d <= static_cast<double>(options.max_voxels), "fusion: ", sides.x(), "x", sides.y(), "x", sides.z(),
           " = ", total_d, " voxels of ", voxel, " exceed max_voxels ", options.max_voxels,
           "; use a larger voxel size");
  grid.dims = sides.cast<int>();
  const Eigen::Vector3i& dims = grid.dims;
  const long long total = static_cast<long long>(dims.x()) * dims.y() * dims.z();
  grid.D.assign(static_cast<size_t>(total), 0.0f);
  grid.W.assign(static_cast<size_t>(total), 0.0f);
  grid.V2.assign(static_cast<size_t>(total), 0.0f);
  return grid;
}

// One vertex of a scan in the world frame, with its weight and its variance along the normal.
struct Measurement {
  Eigen::Vector3d p, n;
  double w0, variance_along_normal;
};

// The footprint of a scan's measurements: a Gaussian across the normal, cut at radius, within tau along it.
struct Kernel {
  double radius, inv_2h2, reach;
};

// Adds one measurement to every voxel within its footprint.
void Splat(const Measurement& m, const Kernel& kernel, Grid* grid) {
  const Eigen::Vector3d& origin = grid->origin;
  const Eigen::Vector3i& dims = grid->dims;
  const double voxel = grid->voxel, tau = grid->tau, radius = kernel.radius, reach = kernel.reach;
  const Eigen::Vector3d& p = m.p;
  const Eigen::Vector3i lo = ((p.array() - reach - origin.array()) / voxel).ceil().cast<int>().max(0);
  const Eigen::Vector3i hi =
      ((p.array() + reach - origin.array()) / voxel).floor().cast<int>().min(dims.array() - 1);
  for (int z = lo.z(); z <= hi.z(); ++z) {
    for (int y = lo.y(); y <= hi.y(); ++y) {
      for (int x = lo.x(); x <= hi.x(); ++x) {
        const Eigen::Vector3d d = grid->Position(x, y, z) - p;
        const double along = m.n.dot(d);
        if (std::abs(along) > tau) continue;
        const double across2 = d.squaredNorm() - along * along;
        if (across2 > radius * radius) continue;
        const double w = m.w0 * std::exp(-across2 * kernel.inv_2h2);
        const size_t k = grid->At(x, y, z);
        grid->D[k] += static_cast<float>(w * along);
        grid->W[k] += static_cast<float>(w);
        grid->V2[k] += static_cast<float>(w * w * m.variance_along_normal);
      }
    }
  }
}

// Splats every vertex of the scan that has a normal and faces its ray closely enough; returns their count.
int IntegrateScan(const Scan& scan, const Eigen::Isometry3d& world_from_scan, const FuseOptions& options,
                  Grid* grid) {
  const Eigen::Matrix3d R = world_from_scan.linear();
  const double radius = options.kernel_radius_edges * scan.mean_edge;
  const Kernel kernel{radius, 1.0 / (2.0 * scan.mean_edge * scan.mean_edge),
                      std::sqrt(grid->tau * grid->tau + radius * radius)};
  int measurements = 0;
  for (int i = 0; i < scan.num_vertices(); ++i) {
    const Eigen::Vector3d n_s = scan.normal.row(i);
    if (n_s.squaredNorm() < 0.5) continue;
    const Eigen::Vector3d r_s = scan.ray.row(i);
    const double cos_ray = -n_s.dot(r_s);
    if (cos_ray < options.min_cos_ray) continue;
    Measurement m;
    m.w0 = cos_ray / r_s.dot(scan.noisy.covariance[i] * r_s);
    m.variance_along_normal = n_s.dot(scan.noisy.covariance[i] * n_s);
    m.p = world_from_scan * Eigen::Vector3d(scan.noisy.mesh.V.row(i));
    m.n = R * n_s;
    ++measurements;
    Splat(m, kernel, grid);
  }
  return measurements;
}

// Turns the sums into weighted means and unobserved voxels (weight below min_weight) into W = 0; returns the
// number of observed voxels.
long long Normalize(float min_weight, Grid* grid) {
  std::vector<float>& D = grid->D;
  std::vector<float>& W = grid->W;
  std::vector<float>& V2 = grid->V2;
  long long observed = 0;
  for (size_t k = 0; k < D.size(); ++k) {
    if (W[k] >= min_weight) {
      D[k] /= W[k];
      V2[k] = static_cast<float>(V2[k] / (static_cast<double>(W[k]) * W[k]));
      ++observed;
    } else {
      W[k] = 0;
    }
  }
  return observed;
}

// Marching cubes over cells whose eight corners are observed; one vertex per crossed grid edge.
class SurfaceExtractor {
 public:
  explicit SurfaceExtractor(const Grid& grid) : grid_(grid) {}

  void Run() {
    const Eigen::Vector3i& dims = grid_.dims;
    for (int z = 0; z + 1 < dims.z(); ++z) {
      for (int y = 0; y + 1 < dims.y(); ++y) {
        for (int x = 0; x + 1 < dims.x(); ++x) Cell(x, y, z);
      }
    }
  }

  // The surface found so far, each vertex with an isotropic covariance.
  NoisyMesh ToMesh() const {
    NoisyMesh out;
    out.mesh.V = Eigen::Map<const Vertices>(xyz_.data(), static_cast<Eigen::Index>(xyz_.size() / 3), 3);
    out.mesh.F = Eigen::Map<const Faces>(faces_.data(), static_cast<Eigen::Index>(faces_.size() / 3), 3);
    out.covariance.resize(vertex_sigma2_.size());
    for (size_t i = 0; i < vertex_sigma2_.size(); ++i) {
      out.covariance[i] = vertex_sigma2_[i] * Eigen::Matrix3d::Identity();
    }
    return out;
  }

 private:
  void Cell(int x, int y, int z) {
    int corner[8][3];
    int cube = 0;
    bool observed_cell = true;
    for (int c = 0; c < 8 && observed_cell; ++c) {
      corner[c][0] = x + kCorner[c][0];
      corner[c][1] = y + kCorner[c][1];
      corner[c][2] = z + kCorner[c][2];
      const size_t k = grid_.At(corner[c][0], corner[c][1], corner[c][2]);
      observed_cell = grid_.W[k] > 0;
      if (grid_.D[k] < 0) cube |= 1 << c;
    }
    if (!observed_cell || pcl::edgeTable[cube] == 0) return;
    int ids[12];
    for (int e = 0; e < 12; ++e) {
      if (pcl::edgeTable[cube] & (1 << e)) ids[e] = VertexOn(corner[kEdge[e][0]], corner[kEdge[e][1]]);
    }
    for (int t = 0; pcl::triTable[cube][t] != -1; t += 3) {
      faces_.insert(faces_.end(), {ids[pcl::triTable[cube][t]], ids[pcl::triTable[cube][t + 1]],
                                   ids[pcl::triTable[cube][t + 2]]});
    }
  }

  int VertexOn(const int c0[3], const int c1[3]) {
    const size_t k0 = grid_.At(c0[0], c0[1], c0[2]), k1 = grid_.At(c1[0], c1[1], c1[2]);
    const size_t lo = std::min(k0, k1), hi = std::max(k0, k1);
    const int axis = hi - lo == 1 ? 0 : hi - lo == static_cast<size_t>(grid_.dims.x()) ? 1 : 2;
    const long long key = static_cast<long long>(lo) * 3 + axis;
    const auto found = edge_vertex_.find(key);
    if (found != edge_vertex_.end()) return found->second;
    const double d0 = grid_.D[k0], d1 = grid_.D[k1];
    const double t = d0 / (d0 - d1);
    const Eigen::Vector3d p0 = grid_.Position(c0[0], c0[1], c0[2]);
    const Eigen::Vector3d p1 = grid_.Position(c1[0], c1[1], c1[2]);
    const Eigen::Vector3d p = p0 + t * (p1 - p0);
    const int id = static_cast<int>(xyz_.size() / 3);
    xyz_.insert(xyz_.end(), {p.x(), p.y(), p.z()});
    vertex_sigma2_.push_back((1 - t) * grid_.V2[k0] + t * grid_.V2[k1]);
    edge_vertex_.emplace(key, id);
    return id;
  }

  const Grid& grid_;
  std::unordered_map<long long, int> edge_vertex_;
  std::vector<double> xyz_, vertex_sigma2_;
  std::vector<int> faces_;
};

// Orientation: normals point where the signed distance grows (out of the object, towards the sensors).
void OrientAlongDistanceGradient(const Grid& grid, Mesh* mesh) {
  const std::vector<float>& D = grid.D;
  double agree = 0;
  for (int f = 0; f < mesh->num_faces(); f += 7) {
    const Eigen::Vector3d a = mesh->V.row(mesh->F(f, 0)), b = mesh->V.row(mesh->F(f, 1)),
                          c = mesh->V.row(mesh->F(f, 2));
    const Eigen::Vector3d nf = (b - a).cross(c - a);
    const Eigen::Vector3d m = (a + b + c) / 3.0;
    const Eigen::Vector3i g = ((m - grid.origin) / grid.voxel).array().floor().cast<int>();
    if ((g.array() < 0).any() || (g.array() + 1 >= grid.dims.array()).any()) continue;
    const Eigen::Vector3d grad(D[grid.At(g.x() + 1, g.y(), g.z())] - D[grid.At(g.x(), g.y(), g.z())],
                               D[grid.At(g.x(), g.y() + 1, g.z())] - D[grid.At(g.x(), g.y(), g.z())],
                               D[grid.At(g.x(), g.y(), g.z() + 1)] - D[grid.At(g.x(), g.y(), g.z())]);
    agree += nf.dot(grad);
  }
  if (agree < 0) mesh->F.col(1).swap(mesh->F.col(2));
}

}  // namespace


void FuseOptions::Check() const {
  RB_CHECK(voxel_edges > 0 && voxel_edges <= 100, "voxel_edges ", voxel_edges, " is outside (0, 100]");
  RB_CHECK(voxel_size >= 0 && std::isfinite(voxel_size), "voxel_size must be >= 0");
  RB_CHECK(truncation_voxels >= 1 && truncation_voxels <= 50, "truncation_voxels is outside [1, 50]");
  RB_CHECK(kernel_radius_edges > 0 && kernel_radius_edges <= 10, "kernel_radius_edges is outside (0, 10]");
  RB_CHECK(min_cos_ray >= 0 && min_cos_ray < 1, "min_cos_ray is outside [0, 1)");
  RB_CHECK(min_weight_share > 0 && min_weight_share <= 10, "min_weight_share is outside (0, 10]");
  RB_CHECK(max_voxels > 0, "max_voxels must be positive");
}

std::string FuseSummary::BriefReport() const {
  return StrCat("fused on ", grid.x(), "x", grid.y(), "x", grid.z(), " voxels of ", voxel_size, " (",
                observed_voxels, " observed) from ", measurements, " measurements: ", vertices, " vertices, ",
                faces, " faces, ", boundary_edges, " boundary edges, ", time_s, " s");
}

int CountBoundaryEdges(const Mesh& mesh) {
  if (mesh.num_faces() == 0) return 0;
  const EdgeTopology topology = ComputeEdgeTopology(mesh);
  int count = 0;
  for (int e = 0; e < topology.edges.rows(); ++e) count += topology.edge_faces.size(e) == 1;
  return count;
}

NoisyMesh FuseScans(const std::vector<Scan>& scans, const std::vector<Eigen::Isometry3d>& world_from_scan,
                    const FuseOptions& options, FuseSummary* summary) {
  options.Check();
  const auto start = std::chrono::steady_clock::now();
  RB_CHECK(!scans.empty(), "fusion needs at least one scan");
  RB_CHECK(scans.size() == world_from_scan.size(), "fusion: ", world_from_scan.size(), " poses for ", scans.size(),
           " scans");
  ScanExtent extent = MeasureScans(scans, world_from_scan);
  Grid grid = MakeGrid(extent, options);
  std::vector<double>& sigma2 = extent.sigma2;
  std::nth_element(sigma2.begin(), sigma2.begin() + sigma2.size() / 2, sigma2.end());
  const float min_weight = static_cast<float>(options.min_weight_share / sigma2[sigma2.size() / 2]);
  int measurements = 0;
  for (size_t s = 0; s < scans.size(); ++s) measurements += IntegrateScan(scans[s], world_from_scan[s], options, &grid);
  const long long observed = Normalize(min_weight, &grid);
  SurfaceExtractor surface(grid);
  surface.Run();
  NoisyMesh out = surface.ToMesh();
  OrientAlongDistanceGradient(grid, &out.mesh);
  if (summary) {
    summary->voxel_size = grid.voxel;
    summary->grid = grid.dims;
    summary->observed_voxels = observed;
    summary->measurements = measurements;
    summary->vertices = out.mesh.num_vertices();
    summary->faces = out.mesh.num_faces();
    summary->boundary_edges = CountBoundaryEdges(out.mesh);
    summary->time_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }
  return out;
}

}  // namespace rangebayes
