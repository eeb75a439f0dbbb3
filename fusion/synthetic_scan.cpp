#include "fusion/synthetic_scan.h"

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "core/error.h"

namespace rangebayes {

void SyntheticScanOptions::Check() const {
  RB_CHECK(width >= 2 && width <= 10000 && height >= 2 && height <= 10000, "synthetic scan size ", width, "x",
           height, " is outside 2–10000");
  RB_CHECK(spacing > 0 && std::isfinite(spacing), "synthetic scan spacing must be positive");
  RB_CHECK(sigma_range >= 0 && std::isfinite(sigma_range), "synthetic scan sigma_range must not be negative");
}

RangeGridScan RenderSyntheticScan(const Mesh& mesh, const Eigen::Isometry3d& world_from_scan,
                                  const SyntheticScanOptions& options) {
  options.Check();
  const int w = options.width, h = options.height;
  const double s = options.spacing;
  const double x0 = -(w - 1) / 2.0 * s, y0 = -(h - 1) / 2.0 * s;
  const Eigen::Isometry3d scan_from_world = world_from_scan.inverse();
  std::vector<double> depth(static_cast<size_t>(w) * h, -std::numeric_limits<double>::infinity());
  for (int f = 0; f < mesh.num_faces(); ++f) {
    Eigen::Vector3d p[3];
    for (int k = 0; k < 3; ++k) p[k] = scan_from_world * Eigen::Vector3d(mesh.V.row(mesh.F(f, k)));
    const double area = (p[1].x() - p[0].x()) * (p[2].y() - p[0].y()) - (p[2].x() - p[0].x()) * (p[1].y() - p[0].y());
    if (std::abs(area) < 1e-300) continue;
    const double xmin = std::min({p[0].x(), p[1].x(), p[2].x()}), xmax = std::max({p[0].x(), p[1].x(), p[2].x()});
    const double ymin = std::min({p[0].y(), p[1].y(), p[2].y()}), ymax = std::max({p[0].y(), p[1].y(), p[2].y()});
    const int ix0 = std::max(0, static_cast<int>(std::ceil((xmin - x0) / s)));
    const int ix1 = std::min(w - 1, static_cast<int>(std::floor((xmax - x0) / s)));
    const int iy0 = std::max(0, static_cast<int>(std::ceil((ymin - y0) / s)));
    const int iy1 = std::min(h - 1, static_cast<int>(std::floor((ymax - y0) / s)));
    for (int iy = iy0; iy <= iy1; ++iy) {
      for (int ix = ix0; ix <= ix1; ++ix) {
        const double x = x0 + ix * s, y = y0 + iy * s;
        const double b1 = ((x - p[0].x()) * (p[2].y() - p[0].y()) - (p[2].x() - p[0].x()) * (y - p[0].y())) / area;
        const double b2 = ((p[1].x() - p[0].x()) * (y - p[0].y()) - (x - p[0].x()) * (p[1].y() - p[0].y())) / area;
        const double b0 = 1.0 - b1 - b2;
        if (b0 < 0 || b1 < 0 || b2 < 0) continue;
        const double z = b0 * p[0].z() + b1 * p[1].z() + b2 * p[2].z();
        double& d = depth[static_cast<size_t>(iy) * w + ix];
        if (z > d) d = z;
      }
    }
  }
  RangeGridScan scan;
  scan.width = w;
  scan.height = h;
  scan.cell_vertex.assign(depth.size(), -1);
  std::mt19937_64 rng(options.seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::vector<double> xyz;
  for (int iy = 0; iy < h; ++iy) {
    for (int ix = 0; ix < w; ++ix) {
      const double d = depth[static_cast<size_t>(iy) * w + ix];
      if (!std::isfinite(d)) continue;
      scan.cell_vertex[static_cast<size_t>(iy) * w + ix] = static_cast<int>(xyz.size() / 3);
      xyz.insert(xyz.end(), {x0 + ix * s, y0 + iy * s, d + options.sigma_range * noise(rng)});
    }
  }
  scan.mesh.mesh.V = Eigen::Map<const Vertices>(xyz.data(), static_cast<Eigen::Index>(xyz.size() / 3), 3);
  return scan;
}

Mesh MakeSphereMesh(double radius, const Eigen::Vector3d& centre, int rings) {
  RB_CHECK(rings >= 3 && radius > 0, "sphere needs radius > 0 and at least 3 rings");
  const int segments = 2 * rings;
  Mesh mesh;
  mesh.V.resize(2 + (rings - 1) * segments, 3);
  mesh.V.row(0) = centre + Eigen::Vector3d(0, 0, radius);
  mesh.V.row(1) = centre - Eigen::Vector3d(0, 0, radius);
  for (int r = 1; r < rings; ++r) {
    const double theta = M_PI * r / rings;
    for (int k = 0; k < segments; ++k) {
      const double phi = 2 * M_PI * k / segments;
      mesh.V.row(2 + (r - 1) * segments + k) =
          centre + radius * Eigen::Vector3d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                                            std::cos(theta));
    }
  }
  std::vector<int> F;
  const auto at = [&](int r, int k) { return 2 + (r - 1) * segments + (k % segments); };
  for (int k = 0; k < segments; ++k) {
    F.insert(F.end(), {0, at(1, k), at(1, k + 1)});
    F.insert(F.end(), {1, at(rings - 1, k + 1), at(rings - 1, k)});
    for (int r = 1; r + 1 < rings; ++r) {
      F.insert(F.end(), {at(r, k), at(r + 1, k), at(r + 1, k + 1)});
      F.insert(F.end(), {at(r, k), at(r + 1, k + 1), at(r, k + 1)});
    }
  }
  mesh.F = Eigen::Map<const Faces>(F.data(), static_cast<Eigen::Index>(F.size() / 3), 3);
  return mesh;
}

}  // namespace rangebayes
