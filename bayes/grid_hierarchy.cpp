#include "bayes/grid_hierarchy.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include "bayes/smooth.h"
#include "core/error.h"

namespace rangebayes {
namespace {

// A coarse and a fine vertex are taken as one surface when they lie within this many local edge lengths per
// grid step of each other (a depth jump across a discontinuity is far longer; a surface seen at 70° from the
// ray has edges ≈ 3× the fronto-parallel ones, so the local length already covers slant).
constexpr double kConnectedEdges = 3.0;

struct Grid {
  int width = 0, height = 0;
  std::vector<int> i, j;      // grid coordinates per vertex
  std::vector<int> at;        // width·height → vertex or −1
  int Index(int gi, int gj) const {
    if (gi < 0 || gj < 0 || gi >= width || gj >= height) return -1;
    return at[static_cast<size_t>(gj) * static_cast<size_t>(width) + static_cast<size_t>(gi)];
  }
};

// The grid of `mesh` (its pixels on a lattice of one step), or false and (when not null) *why_not says why;
// *step_px (when not null): the step.
bool MakeGrid(const NoisyMesh& mesh, Grid* grid, double* step_px = nullptr, std::string* why_not = nullptr) {
  auto no = [why_not](auto&&... parts) {
    if (why_not != nullptr) *why_not = StrCat(parts...);
    return false;
  };
  const int nv = mesh.mesh.num_vertices();
  if (mesh.pixel.rows() != nv || nv == 0 || mesh.mesh.num_faces() == 0) return no("no pixel positions or no faces");
  for (int v = 0; v < nv; ++v) {
    if (!mesh.pixel.row(v).allFinite()) return no("vertex ", v, " has a non-finite pixel position");
  }
  double step = std::numeric_limits<double>::infinity();
  const Faces& F = mesh.mesh.F;
  for (int f = 0; f < F.rows(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int a = F(f, k), b = F(f, (k + 1) % 3);
      for (int axis = 0; axis < 2; ++axis) {
        const double d = std::abs(static_cast<double>(mesh.pixel(a, axis)) - mesh.pixel(b, axis));
        if (d > 1e-3) step = std::min(step, d);
      }
    }
  }
  if (!std::isfinite(step)) return no("every edge joins two vertices on one pixel");
  const float u0 = mesh.pixel.col(0).minCoeff(), v0 = mesh.pixel.col(1).minCoeff();
  grid->i.resize(static_cast<size_t>(nv));
  grid->j.resize(static_cast<size_t>(nv));
  int max_i = 0, max_j = 0;
  for (int v = 0; v < nv; ++v) {
    const double fi = (mesh.pixel(v, 0) - u0) / step, fj = (mesh.pixel(v, 1) - v0) / step;
    if (fi > 1 << 20 || fj > 1 << 20) return no("vertex ", v, " lies more than 2^20 grid steps from the others");
    const long ri = std::lround(fi), rj = std::lround(fj);
    if (std::abs(fi - static_cast<double>(ri)) > 1e-2 || std::abs(fj - static_cast<double>(rj)) > 1e-2) {
      return no("vertex ", v, " at pixel (", mesh.pixel(v, 0), ", ", mesh.pixel(v, 1), ") is off the lattice of step ",
                step, " px");
    }
    grid->i[static_cast<size_t>(v)] = static_cast<int>(ri);
    grid->j[static_cast<size_t>(v)] = static_cast<int>(rj);
    max_i = std::max(max_i, static_cast<int>(ri));
    max_j = std::max(max_j, static_cast<int>(rj));
  }
  grid->width = max_i + 1;
  grid->height = max_j + 1;
  // A sparse scatter of pixels is no organized grid (and would make the index image large).
  if (static_cast<double>(grid->width) * grid->height > 64.0 * nv + 4096) {
    return no("the pixels are a sparse scatter (", grid->width, " x ", grid->height, " grid steps for ", nv,
              " vertices)");
  }
  grid->at.assign(static_cast<size_t>(grid->width) * static_cast<size_t>(grid->height), -1);
  for (int v = 0; v < nv; ++v) {
    int& slot = grid->at[static_cast<size_t>(grid->j[static_cast<size_t>(v)]) * static_cast<size_t>(grid->width) +
                         static_cast<size_t>(grid->i[static_cast<size_t>(v)])];
    if (slot >= 0) {
      return no("vertices ", slot, " and ", v, " lie on one pixel (", mesh.pixel(v, 0), ", ", mesh.pixel(v, 1), ")");
    }
    slot = v;
  }
  if (step_px != nullptr) *step_px = step;
  return true;
}

// Mean length of the edges at each vertex.
std::vector<double> LocalEdgeLength(const Mesh& mesh) {
  const int nv = mesh.num_vertices();
  std::vector<double> sum(static_cast<size_t>(nv), 0.0);
  std::vector<int> count(static_cast<size_t>(nv), 0);
  for (int f = 0; f < mesh.num_faces(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int a = mesh.F(f, k), b = mesh.F(f, (k + 1) % 3);
      const double l = (mesh.V.row(a) - mesh.V.row(b)).norm();
      sum[static_cast<size_t>(a)] += l;
      sum[static_cast<size_t>(b)] += l;
      ++count[static_cast<size_t>(a)];
      ++count[static_cast<size_t>(b)];
    }
  }
  for (int v = 0; v < nv; ++v) {
    if (count[static_cast<size_t>(v)] > 0) sum[static_cast<size_t>(v)] /= count[static_cast<size_t>(v)];
  }
  return sum;
}

bool Connected(const Mesh& mesh, const std::vector<double>& edge, int a, int b, int steps) {
  const double limit = kConnectedEdges * steps * std::max(edge[static_cast<size_t>(a)], edge[static_cast<size_t>(b)]);
  return (mesh.V.row(a) - mesh.V.row(b)).squaredNorm() <= limit * limit;
}

// Faces per fine cell (keyed by its lower-left grid corner; a full cell has its two triangles) and the sign of
// the grid-space cross product of the input's faces (0 when no face spans a cell).
std::vector<uint8_t> CountCellFaces(const Mesh& m, const Grid& grid, double* orientation_out) {
  std::vector<uint8_t> cell_faces(grid.at.size(), 0);
  double orientation = 0;  // sign of the grid-space cross product of the input's faces
  for (int f = 0; f < m.num_faces(); ++f) {
    int lo_i = 1 << 30, lo_j = 1 << 30, hi_i = -1, hi_j = -1;
    for (int k = 0; k < 3; ++k) {
      const int v = m.F(f, k);
      lo_i = std::min(lo_i, grid.i[static_cast<size_t>(v)]);
      hi_i = std::max(hi_i, grid.i[static_cast<size_t>(v)]);
      lo_j = std::min(lo_j, grid.j[static_cast<size_t>(v)]);
      hi_j = std::max(hi_j, grid.j[static_cast<size_t>(v)]);
    }
    if (hi_i - lo_i != 1 || hi_j - lo_j != 1) continue;
    uint8_t& c = cell_faces[static_cast<size_t>(lo_j) * static_cast<size_t>(grid.width) + static_cast<size_t>(lo_i)];
    if (c < 255) ++c;
    if (orientation == 0) {
      const int a = m.F(f, 0), b = m.F(f, 1), d = m.F(f, 2);
      const double ax = grid.i[static_cast<size_t>(b)] - grid.i[static_cast<size_t>(a)];
      const double ay = grid.j[static_cast<size_t>(b)] - grid.j[static_cast<size_t>(a)];
      const double bx = grid.i[static_cast<size_t>(d)] - grid.i[static_cast<size_t>(a)];
      const double by = grid.j[static_cast<size_t>(d)] - grid.j[static_cast<size_t>(a)];
      orientation = ax * by - ay * bx > 0 ? 1.0 : -1.0;
    }
  }
  *orientation_out = orientation;
  return cell_faces;
}

// Coarse faces over fine vertex indices: two per coarse cell whose four fine cells are full, oriented as the input.
std::vector<Eigen::Vector3i> CoarseFaces(const Mesh& m, const Grid& grid, const std::vector<uint8_t>& cell_faces,
                                         double orientation) {
  auto full = [&](int ci, int cj) {
    if (ci < 0 || cj < 0 || ci + 1 >= grid.width || cj + 1 >= grid.height) return false;
    return cell_faces[static_cast<size_t>(cj) * static_cast<size_t>(grid.width) + static_cast<size_t>(ci)] == 2;
  };
  std::vector<Eigen::Vector3i> faces;
  const int coarse_w = (grid.width + 1) / 2, coarse_h = (grid.height + 1) / 2;
  for (int cj = 0; cj + 1 < coarse_h; ++cj) {
    for (int ci = 0; ci + 1 < coarse_w; ++ci) {
      const int i0 = 2 * ci, j0 = 2 * cj;
      if (!full(i0, j0) || !full(i0 + 1, j0) || !full(i0, j0 + 1) || !full(i0 + 1, j0 + 1)) continue;
      const int a = grid.Index(i0, j0), b = grid.Index(i0 + 2, j0), c = grid.Index(i0, j0 + 2),
                d = grid.Index(i0 + 2, j0 + 2);
      if (a < 0 || b < 0 || c < 0 || d < 0) continue;
      auto add = [&](int p, int q, int r) {
        const double ax = grid.i[static_cast<size_t>(q)] - grid.i[static_cast<size_t>(p)];
        const double ay = grid.j[static_cast<size_t>(q)] - grid.j[static_cast<size_t>(p)];
        const double bx = grid.i[static_cast<size_t>(r)] - grid.i[static_cast<size_t>(p)];
        const double by = grid.j[static_cast<size_t>(r)] - grid.j[static_cast<size_t>(p)];
        if ((ax * by - ay * bx > 0 ? 1.0 : -1.0) == orientation) {
          faces.emplace_back(p, q, r);
        } else {
          faces.emplace_back(p, r, q);
        }
      };
      if ((m.V.row(a) - m.V.row(d)).squaredNorm() <= (m.V.row(b) - m.V.row(c)).squaredNorm()) {
        add(a, b, d);
        add(a, d, c);
      } else {
        add(a, b, c);
        add(b, d, c);
      }
    }
  }
  return faces;
}

// Fills level's faces with the coarse ids of `faces`; coarse_of (per fine vertex, −1 where unused) and fine_of
// (per coarse vertex) number the coarse vertices in order of first use.
void NumberCoarseVertices(int nv, const std::vector<Eigen::Vector3i>& faces, std::vector<int>* coarse_of_out,
                          std::vector<int>* fine_of_out, GridLevel* level_out) {
  GridLevel& level = *level_out;
  std::vector<int>& coarse_of = *coarse_of_out;
  std::vector<int>& fine_of = *fine_of_out;
  coarse_of.assign(static_cast<size_t>(nv), -1);
  for (const Eigen::Vector3i& t : faces) {
    for (int k = 0; k < 3; ++k) {
      if (coarse_of[static_cast<size_t>(t[k])] < 0) {
        coarse_of[static_cast<size_t>(t[k])] = static_cast<int>(fine_of.size());
        fine_of.push_back(t[k]);
      }
    }
  }
  level.mesh.mesh.F.resize(static_cast<int>(faces.size()), 3);
  for (size_t t = 0; t < faces.size(); ++t) {
    for (int k = 0; k < 3; ++k) level.mesh.mesh.F(static_cast<int>(t), k) = coarse_of[static_cast<size_t>(faces[t][k])];
  }
}

// Coarse positions, covariances and pixels: per coarse vertex the information-weighted hat average of the
// connected fine vertices of its 3×3 neighbourhood; throws when a fine covariance is not positive definite.
void RestrictVertices(const NoisyMesh& fine, const Grid& grid, const std::vector<double>& edge,
                      const std::vector<int>& fine_of, GridLevel* level_out) {
  const Mesh& m = fine.mesh;
  const int nv = m.num_vertices();
  const int nc = static_cast<int>(fine_of.size());
  GridLevel& level = *level_out;
  std::vector<Eigen::Matrix3d> information(static_cast<size_t>(nv));
  for (int v = 0; v < nv; ++v) {
    RB_CHECK(InformationFromCovariance(fine.covariance[static_cast<size_t>(v)], &information[static_cast<size_t>(v)]),
             "grid hierarchy: the covariance of vertex ", v, " is not finite, positive semi-definite and non-zero");
  }
  level.mesh.mesh.V.resize(nc, 3);
  level.mesh.covariance.resize(static_cast<size_t>(nc));
  level.mesh.pixel.resize(nc, 2);
  for (int c = 0; c < nc; ++c) {
    const int c0 = fine_of[static_cast<size_t>(c)];
    const int gi = grid.i[static_cast<size_t>(c0)], gj = grid.j[static_cast<size_t>(c0)];
    Eigen::Matrix3d w = Eigen::Matrix3d::Zero();
    Eigen::Vector3d b = Eigen::Vector3d::Zero();
    for (int dj = -1; dj <= 1; ++dj) {
      for (int di = -1; di <= 1; ++di) {
        const int f = grid.Index(gi + di, gj + dj);
        if (f < 0 || (f != c0 && !Connected(m, edge, f, c0, 1))) continue;
        const double hat = (1.0 - 0.5 * std::abs(di)) * (1.0 - 0.5 * std::abs(dj));
        w += hat * information[static_cast<size_t>(f)];
        b += hat * information[static_cast<size_t>(f)] * m.V.row(f).transpose();
      }
    }
    const Eigen::Matrix3d w_inverse = w.inverse();
    level.mesh.mesh.V.row(c) = (w_inverse * b).transpose();
    level.mesh.covariance[static_cast<size_t>(c)] = 0.5 * w_inverse;
    level.mesh.pixel.row(c) = fine.pixel.row(c0);
  }
}

// Prolongation: each fine vertex from the coarse corners of its cell (CSR in level's offsets, coarse, weight).
void BuildProlongation(const Mesh& m, const Grid& grid, const std::vector<double>& edge,
                       const std::vector<int>& coarse_of, GridLevel* level_out) {
  const int nv = m.num_vertices();
  GridLevel& level = *level_out;
  level.offsets.assign(static_cast<size_t>(nv) + 1, 0);
  for (int f = 0; f < nv; ++f) {
    const int gi = grid.i[static_cast<size_t>(f)], gj = grid.j[static_cast<size_t>(f)];
    const int size_before = static_cast<int>(level.coarse.size());
    double total = 0;
    for (int cj = gj - (gj % 2); cj <= gj + (gj % 2); cj += 2) {
      for (int ci = gi - (gi % 2); ci <= gi + (gi % 2); ci += 2) {
        const int c0 = grid.Index(ci, cj);
        if (c0 < 0 || coarse_of[static_cast<size_t>(c0)] < 0) continue;
        const int steps = std::max(std::abs(ci - gi), std::abs(cj - gj));
        if (steps > 0 && !Connected(m, edge, f, c0, steps)) continue;
        const double hat = (gi % 2 ? 0.5 : 1.0) * (gj % 2 ? 0.5 : 1.0);
        level.coarse.push_back(coarse_of[static_cast<size_t>(c0)]);
        level.weight.push_back(hat);
        total += hat;
      }
    }
    for (size_t k = static_cast<size_t>(size_before); k < level.weight.size(); ++k) level.weight[k] /= total;
    level.offsets[static_cast<size_t>(f) + 1] = static_cast<int>(level.coarse.size());
  }
}

// One level coarser than `fine` (empty mesh when no coarse cell exists).
GridLevel Coarsen(const NoisyMesh& fine, const Grid& grid) {
  const Mesh& m = fine.mesh;
  const int nv = m.num_vertices();
  double orientation = 0;
  const std::vector<uint8_t> cell_faces = CountCellFaces(m, grid, &orientation);
  const std::vector<Eigen::Vector3i> faces = CoarseFaces(m, grid, cell_faces, orientation);
  GridLevel level;
  if (faces.empty()) return level;
  std::vector<int> coarse_of, fine_of;
  NumberCoarseVertices(nv, faces, &coarse_of, &fine_of, &level);
  const std::vector<double> edge = LocalEdgeLength(m);
  RestrictVertices(fine, grid, edge, fine_of, &level);
  BuildProlongation(m, grid, edge, coarse_of, &level);
  return level;
}

}  // namespace

void GridHierarchyOptions::Check() const {
  RB_CHECK(min_vertices >= 3 && min_vertices <= 1000000000, "grid hierarchy: min_vertices ", min_vertices,
           " is outside [3, 1e9]");
  RB_CHECK(max_levels >= 0 && max_levels <= 20, "grid hierarchy: max_levels ", max_levels, " is outside [0, 20]");
}

double PixelGridStep(const NoisyMesh& mesh, std::string* why_not) {
  Grid grid;
  double step = 0;
  return MakeGrid(mesh, &grid, &step, why_not) ? step : 0.0;
}

std::vector<GridLevel> BuildGridHierarchy(const NoisyMesh& fine, const GridHierarchyOptions& options) {
  options.Check();
  std::vector<GridLevel> levels;
  if (!fine.has_covariance()) return levels;
  const NoisyMesh* current = &fine;
  while (static_cast<int>(levels.size()) < options.max_levels) {
    Grid grid;
    if (!MakeGrid(*current, &grid)) break;
    GridLevel level = Coarsen(*current, grid);
    if (level.mesh.mesh.num_vertices() < options.min_vertices) break;
    levels.push_back(std::move(level));
    current = &levels.back().mesh;
  }
  return levels;
}

Vertices ProlongPositions(const GridLevel& level, const NoisyMesh& finer, const Vertices& coarse_positions) {
  const int nv = finer.mesh.num_vertices();
  RB_CHECK(static_cast<int>(level.offsets.size()) == nv + 1, "grid hierarchy: the level was not built from this mesh");
  RB_CHECK(coarse_positions.rows() == level.mesh.mesh.num_vertices(), "grid hierarchy: ", coarse_positions.rows(),
           " coarse positions for ", level.mesh.mesh.num_vertices(), " coarse vertices");
  const Vertices displacement = coarse_positions - level.mesh.mesh.V;
  Vertices out = finer.mesh.V;
  for (int f = 0; f < nv; ++f) {
    for (int k = level.offsets[static_cast<size_t>(f)]; k < level.offsets[static_cast<size_t>(f) + 1]; ++k) {
      out.row(f) += level.weight[static_cast<size_t>(k)] * displacement.row(level.coarse[static_cast<size_t>(k)]);
    }
  }
  return out;
}

std::vector<Eigen::SparseMatrix<double>> ProlongationMatrices(const std::vector<GridLevel>& levels, size_t first,
                                                             const std::vector<int>& vertex_order) {
  std::vector<Eigen::SparseMatrix<double>> chain;
  for (size_t k = first; k < levels.size(); ++k) {
    const GridLevel& level = levels[k];
    const int rows = static_cast<int>(level.offsets.size()) - 1, cols = level.mesh.mesh.num_vertices();
    std::vector<int> row_of(static_cast<size_t>(rows));
    for (int f = 0; f < rows; ++f) row_of[static_cast<size_t>(f)] = f;
    if (k == first && !vertex_order.empty()) {
      RB_CHECK(static_cast<int>(vertex_order.size()) == rows, "grid hierarchy: ", vertex_order.size(),
               " vertices in the order for a level of ", rows);
      for (int n = 0; n < rows; ++n) row_of[static_cast<size_t>(vertex_order[static_cast<size_t>(n)])] = n;
    }
    std::vector<Eigen::Triplet<double>> triplets;
    for (int f = 0; f < rows; ++f) {
      for (int q = level.offsets[static_cast<size_t>(f)]; q < level.offsets[static_cast<size_t>(f) + 1]; ++q) {
        triplets.emplace_back(row_of[static_cast<size_t>(f)], level.coarse[static_cast<size_t>(q)],
                              level.weight[static_cast<size_t>(q)]);
      }
    }
    Eigen::SparseMatrix<double> p(rows, cols);
    p.setFromTriplets(triplets.begin(), triplets.end());
    chain.push_back(std::move(p));
  }
  return chain;
}

}  // namespace rangebayes
