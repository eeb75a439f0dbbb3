#include "reconstruction/triangulate.h"

#include <tbb/parallel_for.h>

#include <cmath>
#include <vector>

#include "core/error.h"

namespace rangebayes {

void TriangulateOptions::Check() const {
  RB_CHECK(downsample >= 1 && downsample <= 64, "downsample ", downsample, " is outside 1–64");
  RB_CHECK(max_jump_sigma > 0.0, "max_jump_sigma ", max_jump_sigma, " must be positive");
  RB_CHECK(max_slope_deg >= 0.0 && max_slope_deg < 89.95, "max_slope_deg ", max_slope_deg, " is outside 0–89.9");
  RB_CHECK(default_sigma_disparity_px > 0.0, "default_sigma_disparity_px must be positive");
}

NoisyMesh TriangulateDepth(const DepthFrame& frame, const TriangulateOptions& options, TriangulateSummary* summary) {
  options.Check();
  RB_CHECK(!frame.empty() && frame.depth_m.type() == CV_32F, "depth frame ", frame.frame_id, " is empty");
  RB_CHECK(frame.sigma_depth_m.size() == frame.depth_m.size() && frame.sigma_depth_m.type() == CV_32F,
           "depth frame ", frame.frame_id, ": sigma_depth size differs from the depth");
  const CameraIntrinsics& K = frame.intrinsics;
  RB_CHECK(K.fx_px > 0 && K.fy_px > 0 && K.width == frame.width() && K.height == frame.height(), "depth frame ",
           frame.frame_id, ": intrinsics do not match the ", frame.width(), "x", frame.height(), " image");
  const int s = options.downsample;
  const int gw = (frame.width() + s - 1) / s;
  const int gh = (frame.height() + s - 1) / s;
  const double fb = K.fx_px * frame.baseline_m;
  const double sigma_px = options.sigma_pixel_px >= 0.0 ? options.sigma_pixel_px : frame.sigma_pixel_px;
  const double slope = std::tan(options.max_slope_deg * M_PI / 180.0) * s / K.fx_px;
  const double k2 = options.max_jump_sigma * options.max_jump_sigma;

  // Depth and σ_Z on the grid; σ_Z from the default σ_d where the matcher gave none.
  std::vector<float> z(static_cast<size_t>(gw) * gh), sz(z.size());
  std::vector<int> row_vertices(gh + 1, 0);
  tbb::parallel_for(0, gh, [&](int gy) {
    const float* depth = frame.depth_m.ptr<float>(gy * s);
    const float* sigma = frame.sigma_depth_m.ptr<float>(gy * s);
    int count = 0;
    for (int gx = 0; gx < gw; ++gx) {
      const float d = depth[gx * s];
      float sd = sigma[gx * s];
      if (std::isfinite(d) && !std::isfinite(sd) && fb > 0.0) {
        sd = static_cast<float>(static_cast<double>(d) * d / fb * options.default_sigma_disparity_px);
      }
      const bool ok = std::isfinite(d) && d > 0.0f && std::isfinite(sd);
      z[static_cast<size_t>(gy) * gw + gx] = ok ? d : NAN;
      sz[static_cast<size_t>(gy) * gw + gx] = ok ? sd : NAN;
      count += ok;
    }
    row_vertices[gy + 1] = count;
  });
  for (int gy = 0; gy < gh; ++gy) row_vertices[gy + 1] += row_vertices[gy];
  const int nv = row_vertices[gh];

  NoisyMesh out;
  out.mesh.V.resize(nv, 3);
  out.covariance.resize(nv);
  out.pixel.resize(nv, 2);
  std::vector<int> index(z.size(), -1);
  tbb::parallel_for(0, gh, [&](int gy) {
    int i = row_vertices[gy];
    for (int gx = 0; gx < gw; ++gx) {
      const size_t g = static_cast<size_t>(gy) * gw + gx;
      if (!std::isfinite(z[g])) continue;
      index[g] = i;
      const double u = gx * s, v = gy * s, depth = z[g];
      const Eigen::Vector3d p((u - K.cx_px) * depth / K.fx_px, (v - K.cy_px) * depth / K.fy_px, depth);
      const Eigen::Vector3d r = p.normalized();
      const double sigma_ray = sz[g] / r.z();
      const double sigma_lat = p.norm() / K.fx_px * sigma_px;
      out.mesh.V.row(i) = p.transpose();
      out.covariance[i] = (sigma_ray * sigma_ray - sigma_lat * sigma_lat) * (r * r.transpose()) +
                          sigma_lat * sigma_lat * Eigen::Matrix3d::Identity();
      out.pixel(i, 0) = static_cast<float>(u);
      out.pixel(i, 1) = static_cast<float>(v);
      ++i;
    }
  });

  const auto connected = [&](size_t a, size_t b) {
    const double za = z[a], zb = z[b];
    const double jump = std::abs(za - zb);
    const double noise2 = static_cast<double>(sz[a]) * sz[a] + static_cast<double>(sz[b]) * sz[b];
    const double allowed_slope = 0.5 * (za + zb) * slope;
    // jump > k·σ + slope allowance, written without a square root when the slope term is zero.
    if (jump <= allowed_slope) return true;
    const double excess = jump - allowed_slope;
    return excess * excess <= k2 * noise2;
  };

  // Faces per row of 2×2 blocks: counted, then written, so rows can run in parallel.
  const int block_rows = std::max(0, gh - 1);
  std::vector<int> row_faces(block_rows + 1, 0);
  std::vector<int> row_cuts(block_rows, 0);
  // Per block: bit mask of emitted triangles (1: a-b-c type 1, 2: type 2 ...), computed once.
  std::vector<std::uint8_t> block_code(static_cast<size_t>(std::max(0, gw - 1)) * block_rows, 0);
  tbb::parallel_for(0, block_rows, [&](int gy) {
    int faces = 0, cuts = 0;
    for (int gx = 0; gx + 1 < gw; ++gx) {
      // Corners: 0 = (x, y), 1 = (x+1, y), 2 = (x, y+1), 3 = (x+1, y+1).
      const size_t c[4] = {static_cast<size_t>(gy) * gw + gx, static_cast<size_t>(gy) * gw + gx + 1,
                           static_cast<size_t>(gy + 1) * gw + gx, static_cast<size_t>(gy + 1) * gw + gx + 1};
      bool valid[4];
      for (int k = 0; k < 4; ++k) valid[k] = index[c[k]] >= 0;
      const auto edge = [&](int a, int b) { return valid[a] && valid[b] && connected(c[a], c[b]); };
      const bool e01 = edge(0, 1), e02 = edge(0, 2), e13 = edge(1, 3), e23 = edge(2, 3);
      const bool e03 = edge(0, 3), e12 = edge(1, 2);
      // Edges on the block's top and left sides are counted here once; the others belong to the next block.
      cuts += (valid[0] && valid[1] && !e01) + (valid[0] && valid[2] && !e02);
      if (gy + 2 == gh) cuts += valid[2] && valid[3] && !e23;
      if (gx + 2 == gw) cuts += valid[1] && valid[3] && !e13;
      // Triangles (image y down, so (0,2,1) is counter-clockwise seen from the camera):
      //   diagonal 0–3: A = (0,2,3), B = (0,3,1); diagonal 1–2: C = (0,2,1), D = (1,2,3).
      const bool A = e02 && e23 && e03, B = e03 && e13 && e01;
      const bool C = e02 && e12 && e01, D = e12 && e23 && e13;
      std::uint8_t code = 0;
      if (A && B && C && D) {
        const Eigen::Vector3d p0 = out.mesh.V.row(index[c[0]]), p1 = out.mesh.V.row(index[c[1]]);
        const Eigen::Vector3d p2 = out.mesh.V.row(index[c[2]]), p3 = out.mesh.V.row(index[c[3]]);
        code = (p0 - p3).squaredNorm() <= (p1 - p2).squaredNorm() ? 0b0011 : 0b1100;
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
    row_cuts[gy] = cuts;
  });
  for (int gy = 0; gy < block_rows; ++gy) row_faces[gy + 1] += row_faces[gy];
  out.mesh.F.resize(row_faces[block_rows], 3);
  tbb::parallel_for(0, block_rows, [&](int gy) {
    int f = row_faces[gy];
    for (int gx = 0; gx + 1 < gw; ++gx) {
      const std::uint8_t code = block_code[static_cast<size_t>(gy) * (gw - 1) + gx];
      if (!code) continue;
      const int i0 = index[static_cast<size_t>(gy) * gw + gx], i1 = index[static_cast<size_t>(gy) * gw + gx + 1];
      const int i2 = index[static_cast<size_t>(gy + 1) * gw + gx], i3 = index[static_cast<size_t>(gy + 1) * gw + gx + 1];
      if (code & 0b0001) out.mesh.F.row(f++) << i0, i2, i3;
      if (code & 0b0010) out.mesh.F.row(f++) << i0, i3, i1;
      if (code & 0b0100) out.mesh.F.row(f++) << i0, i2, i1;
      if (code & 0b1000) out.mesh.F.row(f++) << i1, i2, i3;
    }
  });
  if (summary) {
    summary->vertices = nv;
    summary->faces = static_cast<int>(out.mesh.F.rows());
    summary->cut_edges = 0;
    for (int c : row_cuts) summary->cut_edges += c;
  }
  return out;
}

}  // namespace rangebayes
