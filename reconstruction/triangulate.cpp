#include "reconstruction/triangulate.h"

#include <tbb/parallel_for.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cmath>
#include <vector>

#include "core/error.h"

namespace rangebayes {

void TriangulateOptions::Check() const {
  RB_CHECK(downsample >= 1 && downsample <= 64, "downsample ", downsample, " is outside 1–64");
  RB_CHECK(max_jump_sigma > 0.0, "max_jump_sigma ", max_jump_sigma, " must be positive");
  RB_CHECK(max_slope_deg >= 0.0 && max_slope_deg < 89.95, "max_slope_deg ", max_slope_deg, " is outside 0–89.9");
  RB_CHECK(default_sigma_disparity_px > 0.0, "default_sigma_disparity_px must be positive");
  RB_CHECK(sigma_pixel_px != 0.0, "sigma_pixel_px 0 gives no lateral covariance (> 0; < 0: the frame's)");
}

void ApplyDisparityNoiseModel(const DisparityNoiseModel& model, TriangulateOptions* options) {
  if (model.form == NoiseForm::kConstant) options->default_sigma_disparity_px = model.sigma_px;
}

namespace {

// Depth and σ_Z on the grid of every s-th pixel (NaN where there is no vertex), and the first vertex of
// each grid row.
struct DepthGrid {
  int s = 1, gw = 0, gh = 0;
  std::vector<float> z, sz;
  std::vector<float> edge_sz;     // the discontinuity test's σ_Z (DepthFrame::edge_sigma_depth_m); empty: sz
  std::vector<int> row_vertices;  // gh + 1 prefix sums
  int num_vertices() const { return row_vertices.back(); }
};

// σ_Z from the default σ_d where the matcher gave none.
DepthGrid SampleDepthGrid(const DepthFrame& frame, const TriangulateOptions& options) {
  DepthGrid grid;
  const int s = grid.s = options.downsample;
  const int gw = grid.gw = (frame.width() + s - 1) / s;
  const int gh = grid.gh = (frame.height() + s - 1) / s;
  const double fb = frame.intrinsics.fx_px * frame.baseline_m;
  std::vector<float>& z = grid.z;
  std::vector<float>& sz = grid.sz;
  z.resize(static_cast<size_t>(gw) * gh);
  sz.resize(z.size());
  const bool edge = !frame.edge_sigma_depth_m.empty();
  if (edge) grid.edge_sz.resize(z.size());
  std::vector<int>& row_vertices = grid.row_vertices;
  row_vertices.assign(gh + 1, 0);
  tbb::parallel_for(0, gh, [&](int gy) {
    const float* depth = frame.depth_m.ptr<float>(gy * s);
    const float* sigma = frame.sigma_depth_m.ptr<float>(gy * s);
    int count = 0;
    for (int gx = 0; gx < gw; ++gx) {
      const float d = depth[gx * s];
      float sd = sigma[gx * s];
      // A σ_Z that is missing, or zero (no uncertainty is no covariance: rank-deficient Σ), takes the default σ_d.
      if (std::isfinite(d) && !(std::isfinite(sd) && sd > 0.0f) && fb > 0.0) {
        sd = static_cast<float>(static_cast<double>(d) * d / fb * options.default_sigma_disparity_px);
      }
      const bool ok = std::isfinite(d) && d > 0.0f && std::isfinite(sd) && sd > 0.0f;
      z[static_cast<size_t>(gy) * gw + gx] = ok ? d : NAN;
      sz[static_cast<size_t>(gy) * gw + gx] = ok ? sd : NAN;
      if (edge) {
        // Where the edge σ is missing or zero, the covariance's σ.
        const float e = frame.edge_sigma_depth_m.ptr<float>(gy * s)[gx * s];
        grid.edge_sz[static_cast<size_t>(gy) * gw + gx] = ok ? (std::isfinite(e) && e > 0.0f ? e : sd) : NAN;
      }
      count += ok;
    }
    row_vertices[gy + 1] = count;
  });
  for (int gy = 0; gy < gh; ++gy) row_vertices[gy + 1] += row_vertices[gy];
  return grid;
}

// The vertices (back-projected grid points), their ray-aligned covariances and pixels; index[g] = the vertex
// of grid point g, or −1.
void BackProject(const DepthFrame& frame, const DepthGrid& grid, double sigma_px, NoisyMesh* mesh,
                 std::vector<int>* vertex_index) {
  const CameraIntrinsics& K = frame.intrinsics;
  const int s = grid.s, gw = grid.gw, gh = grid.gh;
  const std::vector<float>& z = grid.z;
  const std::vector<float>& sz = grid.sz;
  const std::vector<int>& row_vertices = grid.row_vertices;
  const int nv = grid.num_vertices();
  NoisyMesh& out = *mesh;
  out.mesh.V.resize(nv, 3);
  out.covariance.resize(nv);
  out.pixel.resize(nv, 2);
  std::vector<int>& index = *vertex_index;
  index.assign(z.size(), -1);
  const double inv_fx = 1.0 / K.fx_px, inv_fy = 1.0 / K.fy_px;
  tbb::parallel_for(0, gh, [&](int gy) {
    int i = row_vertices[gy];
    const double v = gy * s;
    const double ny = (v - K.cy_px) * inv_fy;
    for (int gx = 0; gx < gw; ++gx) {
      const size_t g = static_cast<size_t>(gy) * gw + gx;
      const double depth = z[g];
      if (!std::isfinite(depth)) continue;
      index[g] = i;
      const double u = gx * s;
      const double px = (u - K.cx_px) * inv_fx * depth, py = ny * depth;
      const double norm = std::sqrt(px * px + py * py + depth * depth);
      const double inv_norm = 1.0 / norm;
      const double rx = px * inv_norm, ry = py * inv_norm, rz = depth * inv_norm;
      // Closed form of Σ = σ_ray² r rᵀ + σ_lat² (I − r rᵀ) = (σ_ray² − σ_lat²) r rᵀ + σ_lat² I, with
      // σ_ray = σ_Z / r_z = σ_Z·|p|/Z. A pixel error δ (σ_px per image axis) moves the point by Z/f·δ at its
      // depth; across the ray that is Z/f·σ_px tangentially and Z/f·σ_px·cos θ radially (θ the ray's angle
      // to the optical axis). σ_lat² is half the trace of that 2×2 covariance, (Z·σ_px/f)²·(Z² + |p|²)/(2|p|²),
      // so E[|e_⊥|²/σ_lat²] = 2 exactly (docs/design.md §2 writes Z/f·σ_px, its on-axis value; |p|/f·σ_px, used
      // before, overstated it off-axis by up to 1/cos²θ: a mean of 1.64 instead of 2 at 53° field of view).
      const double sigma_ray = sz[g] * norm / depth;
      const double b = depth * depth * inv_fx * inv_fx * sigma_px * sigma_px * (depth * depth + norm * norm) /
                       (2.0 * norm * norm);
      const double a = sigma_ray * sigma_ray - b;
      double* vrow = out.mesh.V.data() + static_cast<size_t>(i) * 3;
      vrow[0] = px;
      vrow[1] = py;
      vrow[2] = depth;
      double* c = out.covariance[i].data();  // symmetric: storage order does not matter
      c[0] = a * rx * rx + b;
      c[4] = a * ry * ry + b;
      c[8] = a * rz * rz + b;
      c[1] = c[3] = a * rx * ry;
      c[2] = c[6] = a * rx * rz;
      c[5] = c[7] = a * ry * rz;
      float* pix = out.pixel.data() + static_cast<size_t>(i) * 2;
      pix[0] = static_cast<float>(u);
      pix[1] = static_cast<float>(v);
      ++i;
    }
  });

}

// Per grid point a bit mask of its connected edges (see below); an edge is cut where the depth jump exceeds
// k·σ plus the slope allowance.
std::vector<std::uint8_t> ConnectedEdges(const DepthGrid& grid, double slope, double k2) {
  const int gw = grid.gw, gh = grid.gh;
  const std::vector<float>& z = grid.z;
  const std::vector<float>& sz = grid.edge_sz.empty() ? grid.sz : grid.edge_sz;
  const auto connected = [&](size_t a, size_t b) {
    const double za = z[a], zb = z[b];
    if (!(za == za) || !(zb == zb)) return false;  // NaN: no vertex
    const double jump = std::abs(za - zb);
    const double allowed_slope = 0.5 * (za + zb) * slope;
    // jump > k·σ + slope allowance, written without a square root.
    if (jump <= allowed_slope) return true;
    const double excess = jump - allowed_slope;
    const double noise2 = static_cast<double>(sz[a]) * sz[a] + static_cast<double>(sz[b]) * sz[b];
    return excess * excess <= k2 * noise2;
  };

  // Every grid edge is tested once: per block (x, y) bit 0 its top edge (x,y)–(x+1,y), bit 1 its left edge
  // (x,y)–(x,y+1), bit 2 the diagonal (x,y)–(x+1,y+1), bit 3 the diagonal (x+1,y)–(x,y+1); the bottom and
  // right edges are the top and left edges of the blocks below and to the right (a last row and column of
  // pseudo-blocks holds the grid's bottom and right edges).
  std::vector<std::uint8_t> edges(z.size(), 0);
  tbb::parallel_for(0, gh, [&](int gy) {
    std::uint8_t* e = edges.data() + static_cast<size_t>(gy) * gw;
    const size_t row = static_cast<size_t>(gy) * gw;
    for (int gx = 0; gx < gw; ++gx) {
      const size_t c0 = row + gx;
      std::uint8_t bits = 0;
      if (gx + 1 < gw) bits |= connected(c0, c0 + 1) ? 1 : 0;
      if (gy + 1 < gh) {
        bits |= connected(c0, c0 + gw) ? 2 : 0;
        if (gx + 1 < gw) {
          bits |= connected(c0, c0 + gw + 1) ? 4 : 0;
          bits |= connected(c0 + 1, c0 + gw) ? 8 : 0;
        }
      }
      e[gx] = bits;
    }
  });

  return edges;
}

// Per 2×2 block the triangles to emit, and per row the faces and cut edges.
struct BlockTriangles {
  std::vector<int> row_faces;           // block rows + 1 prefix sums
  std::vector<int> row_cuts;            // per grid row
  std::vector<std::uint8_t> block_code;  // per block: 1: A, 2: B, 4: C, 8: D
};

BlockTriangles ChooseTriangles(const DepthGrid& grid, const std::vector<int>& index,
                               const std::vector<std::uint8_t>& edges, const NoisyMesh& out) {
  const int gw = grid.gw, gh = grid.gh;
  BlockTriangles blocks;
  const int block_rows = std::max(0, gh - 1);
  std::vector<int>& row_faces = blocks.row_faces;
  std::vector<int>& row_cuts = blocks.row_cuts;
  std::vector<std::uint8_t>& block_code = blocks.block_code;
  row_faces.assign(block_rows + 1, 0);
  row_cuts.assign(gh, 0);
  block_code.assign(static_cast<size_t>(std::max(0, gw - 1)) * block_rows, 0);
  // Faces per row of 2×2 blocks: counted, then written, so rows can run in parallel.
  tbb::parallel_for(0, gh, [&](int gy) {
    // Cut edges: grid edges between two valid vertices that are not connected (top and left edges here).
    int cuts = 0;
    const size_t row = static_cast<size_t>(gy) * gw;
    for (int gx = 0; gx < gw; ++gx) {
      const bool valid = index[row + gx] >= 0;
      if (!valid) continue;
      if (gx + 1 < gw && index[row + gx + 1] >= 0) cuts += !(edges[row + gx] & 1);
      if (gy + 1 < gh && index[row + gx + gw] >= 0) cuts += !(edges[row + gx] & 2);
    }
    row_cuts[gy] = cuts;
    if (gy + 1 >= gh) return;
    int faces = 0;
    for (int gx = 0; gx + 1 < gw; ++gx) {
      const std::uint8_t here = edges[row + gx];
      const bool e01 = here & 1, e02 = here & 2, e03 = here & 4, e12 = here & 8;
      const bool e13 = edges[row + gx + 1] & 2, e23 = edges[row + gw + gx] & 1;
      // Triangles (image y down, so (0,2,1) is counter-clockwise seen from the camera):
      //   diagonal 0–3: A = (0,2,3), B = (0,3,1); diagonal 1–2: C = (0,2,1), D = (1,2,3).
      const bool A = e02 && e23 && e03, B = e03 && e13 && e01;
      const bool C = e02 && e12 && e01, D = e12 && e23 && e13;
      std::uint8_t code = 0;
      if (A && B && C && D) {
        // Split along the shorter 3-D diagonal.
        const double* p0 = out.mesh.V.data() + 3 * static_cast<size_t>(index[row + gx]);
        const double* p1 = out.mesh.V.data() + 3 * static_cast<size_t>(index[row + gx + 1]);
        const double* p2 = out.mesh.V.data() + 3 * static_cast<size_t>(index[row + gw + gx]);
        const double* p3 = out.mesh.V.data() + 3 * static_cast<size_t>(index[row + gw + gx + 1]);
        double d03 = 0, d12 = 0;
        for (int k = 0; k < 3; ++k) {
          d03 += (p0[k] - p3[k]) * (p0[k] - p3[k]);
          d12 += (p1[k] - p2[k]) * (p1[k] - p2[k]);
        }
        code = d03 <= d12 ? 0b0011 : 0b1100;
      } else if (A && B) {
        code = 0b0011;
      } else if (C && D) {
        code = 0b1100;
      } else {
        code = static_cast<std::uint8_t>(A ? 0b0001 : B ? 0b0010 : C ? 0b0100 : D ? 0b1000 : 0);
      }
      block_code[static_cast<size_t>(gy) * (gw - 1) + gx] = code;
      faces += __builtin_popcount(code);
    }
    row_faces[gy + 1] = faces;
  });
  for (int gy = 0; gy < block_rows; ++gy) row_faces[gy + 1] += row_faces[gy];
  return blocks;
}

void WriteFaces(const DepthGrid& grid, const std::vector<int>& index, const BlockTriangles& blocks, Faces* faces) {
  const int gw = grid.gw;
  const int block_rows = std::max(0, grid.gh - 1);
  const std::vector<int>& row_faces = blocks.row_faces;
  const std::vector<std::uint8_t>& block_code = blocks.block_code;
  faces->resize(row_faces[block_rows], 3);
  tbb::parallel_for(0, block_rows, [&](int gy) {
    int* f = faces->data() + 3 * static_cast<size_t>(row_faces[gy]);
    const size_t row = static_cast<size_t>(gy) * gw;
    for (int gx = 0; gx + 1 < gw; ++gx) {
      const std::uint8_t code = block_code[static_cast<size_t>(gy) * (gw - 1) + gx];
      if (!code) continue;
      const int i0 = index[row + gx], i1 = index[row + gx + 1];
      const int i2 = index[row + gw + gx], i3 = index[row + gw + gx + 1];
      const auto put = [&f](int a, int b, int c) {
        f[0] = a;
        f[1] = b;
        f[2] = c;
        f += 3;
      };
      if (code & 0b0001) put(i0, i2, i3);
      if (code & 0b0010) put(i0, i3, i1);
      if (code & 0b0100) put(i0, i2, i1);
      if (code & 0b1000) put(i1, i2, i3);
    }
  });
}

}  // namespace

std::string TriangulateSummary::BriefReport() const {
  char line[160];
  std::snprintf(line, sizeof(line), "mesh: %d vertices, %d faces, %d edges cut at discontinuities, triangulated in %.1f ms",
                vertices, faces, cut_edges, time_ms);
  return line;
}

NoisyMesh TriangulateDepth(const DepthFrame& frame, const TriangulateOptions& options, TriangulateSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  options.Check();
  RB_CHECK(!frame.empty() && frame.depth_m.type() == CV_32F, "depth frame ", frame.frame_id, " is empty");
  RB_CHECK(frame.sigma_depth_m.size() == frame.depth_m.size() && frame.sigma_depth_m.type() == CV_32F,
           "depth frame ", frame.frame_id, ": sigma_depth size differs from the depth");
  RB_CHECK(frame.edge_sigma_depth_m.empty() ||
               (frame.edge_sigma_depth_m.size() == frame.depth_m.size() && frame.edge_sigma_depth_m.type() == CV_32F),
           "depth frame ", frame.frame_id, ": edge_sigma_depth size differs from the depth");
  const CameraIntrinsics& K = frame.intrinsics;
  K.Check();
  RB_CHECK(K.width == frame.width() && K.height == frame.height(), "depth frame ", frame.frame_id,
           ": intrinsics do not match the ", frame.width(), "x", frame.height(), " image");
  const int s = options.downsample;
  const double sigma_px = options.sigma_pixel_px > 0.0 ? options.sigma_pixel_px : frame.sigma_pixel_px;
  RB_CHECK(sigma_px > 0.0 && std::isfinite(sigma_px), "depth frame ", frame.frame_id, ": sigma_pixel_px ", sigma_px,
           " must be positive (a zero lateral σ makes every covariance singular)");
  const double slope = std::tan(options.max_slope_deg * M_PI / 180.0) * s / K.fx_px;
  const double k2 = options.max_jump_sigma * options.max_jump_sigma;

  const DepthGrid grid = SampleDepthGrid(frame, options);
  NoisyMesh out;
  std::vector<int> index;
  BackProject(frame, grid, sigma_px, &out, &index);
  const std::vector<std::uint8_t> edges = ConnectedEdges(grid, slope, k2);
  const BlockTriangles blocks = ChooseTriangles(grid, index, edges, out);
  WriteFaces(grid, index, blocks, &out.mesh.F);
  if (summary) {
    summary->vertices = grid.num_vertices();
    summary->faces = static_cast<int>(out.mesh.F.rows());
    summary->cut_edges = 0;
    for (int c : blocks.row_cuts) summary->cut_edges += c;
    summary->time_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  }
  return out;
}

}  // namespace rangebayes
