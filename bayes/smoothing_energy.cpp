#include "bayes/smoothing_energy.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
// AVX-512 kernels, chosen at run time (the default build targets baseline x86-64). GCC only: its
// optimize("fp-contract=off") keeps every multiply and add separately rounded as in the portable code, which
// is what makes both paths give the same bytes (clang would contract them into FMAs).
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
#define RB_SMOOTHING_AVX512 1
#include <immintrin.h>
#define RB_AVX512_KERNEL __attribute__((target("avx512f,avx512vl,avx512dq"), optimize("fp-contract=off")))
#else
#define RB_SMOOTHING_AVX512 0
#endif

#include "core/error.h"

namespace rangebayes {
namespace {

// Fixed grain: with simple partitioning the reduction tree depends only on the range, not on the threads.
constexpr int kGrain = 1024;

template <typename Body>
double DeterministicSum(int n, const Body& body) {
  return tbb::parallel_deterministic_reduce(
      tbb::blocked_range<int>(0, n, kGrain), 0.0,
      [&](const tbb::blocked_range<int>& r, double sum) {
        for (int i = r.begin(); i != r.end(); ++i) sum += body(i);
        return sum;
      },
      [](double a, double b) { return a + b; });
}

inline Eigen::Vector3d Position(const double* x, int v) { return Eigen::Vector3d(x[3 * v], x[3 * v + 1], x[3 * v + 2]); }

SmoothingKernel g_kernel = SmoothingKernel::kAuto;

// The instruction set of the kernels Evaluate runs now.
enum class Isa { kPortable, kAvx512 };

#if RB_SMOOTHING_AVX512
Isa ActiveIsa() {
  static const bool avx512 = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
                             __builtin_cpu_supports("avx512dq");
  if (g_kernel == SmoothingKernel::kPortable) return Isa::kPortable;
  return avx512 ? Isa::kAvx512 : Isa::kPortable;
}

// The square-root face pass (Evaluate's pass 2) over faces [begin, end), eight faces per step in the lanes of
// a zmm register: the neighbours' normals come in by gathers, slot k of the eight faces at once (masked where
// a face has fewer than k + 1 neighbours). Each lane performs exactly the portable loop's operations in its
// order (no FMA), and the eight ½Σφ are added to `sum` one face after another, so the result has the same
// bytes as the portable pass. face_e2 null: the global e2.
struct SqrtFacePassInput {
  const double* x;
  const int* faces;  // #F×3 row-major
  const double* normals;
  const double* inverse_length;
  const int* offsets;
  const int* neighbours;
  const double* face_e2;
  double e2;
  double beta;
  double* h;  // 3 per face (h_t); null: no gradient
};

// Eight 3-vectors stored x y z x y z … (24 doubles from p; the first 3n, n ≤ 8, are read) into x, y, z
// registers, and back: permutes instead of stride-3 gathers and scatters.
RB_AVX512_KERNEL inline void LoadXyz8(const double* p, int n, __m512d* x, __m512d* y, __m512d* z) {
  const unsigned bits = 3u * static_cast<unsigned>(n);
  const __mmask8 ma = static_cast<__mmask8>(bits >= 8 ? 0xFFu : (1u << bits) - 1u);
  const __mmask8 mb = static_cast<__mmask8>(bits >= 16 ? 0xFFu : bits <= 8 ? 0u : (1u << (bits - 8)) - 1u);
  const __mmask8 mc = static_cast<__mmask8>(bits <= 16 ? 0u : (1u << (bits - 16)) - 1u);
  const __m512d a = _mm512_maskz_loadu_pd(ma, p), b = _mm512_maskz_loadu_pd(mb, p + 8), c = _mm512_maskz_loadu_pd(mc, p + 16);
  *x = _mm512_permutex2var_pd(_mm512_permutex2var_pd(a, _mm512_setr_epi64(0, 3, 6, 9, 12, 15, 0, 0), b),
                              _mm512_setr_epi64(0, 1, 2, 3, 4, 5, 10, 13), c);
  *y = _mm512_permutex2var_pd(_mm512_permutex2var_pd(a, _mm512_setr_epi64(1, 4, 7, 10, 13, 0, 0, 0), b),
                              _mm512_setr_epi64(0, 1, 2, 3, 4, 8, 11, 14), c);
  *z = _mm512_permutex2var_pd(_mm512_permutex2var_pd(a, _mm512_setr_epi64(2, 5, 8, 11, 14, 0, 0, 0), b),
                              _mm512_setr_epi64(0, 1, 2, 3, 4, 9, 12, 15), c);
}

RB_AVX512_KERNEL inline void StoreXyz8(double* p, int n, __m512d x, __m512d y, __m512d z) {
  const unsigned bits = 3u * static_cast<unsigned>(n);
  const __mmask8 ma = static_cast<__mmask8>(bits >= 8 ? 0xFFu : (1u << bits) - 1u);
  const __mmask8 mb = static_cast<__mmask8>(bits >= 16 ? 0xFFu : bits <= 8 ? 0u : (1u << (bits - 8)) - 1u);
  const __mmask8 mc = static_cast<__mmask8>(bits <= 16 ? 0u : (1u << (bits - 16)) - 1u);
  // a = x0 y0 z0 x1 y1 z1 x2 y2, b = z2 x3 y3 z3 x4 y4 z4 x5, c = y5 z5 x6 y6 z6 x7 y7 z7.
  const __m512d xy_a = _mm512_permutex2var_pd(x, _mm512_setr_epi64(0, 8, 0, 1, 9, 0, 2, 10), y);
  const __m512d a = _mm512_permutex2var_pd(xy_a, _mm512_setr_epi64(0, 1, 8, 3, 4, 9, 6, 7), z);
  const __m512d xz_b = _mm512_permutex2var_pd(x, _mm512_setr_epi64(10, 3, 0, 11, 4, 0, 12, 5), z);
  const __m512d b = _mm512_permutex2var_pd(xz_b, _mm512_setr_epi64(0, 1, 11, 3, 4, 12, 6, 7), y);
  const __m512d yz_c = _mm512_permutex2var_pd(y, _mm512_setr_epi64(5, 13, 0, 6, 14, 0, 7, 15), z);
  const __m512d c = _mm512_permutex2var_pd(yz_c, _mm512_setr_epi64(0, 1, 14, 3, 4, 15, 6, 7), x);
  _mm512_mask_storeu_pd(p, ma, a);
  _mm512_mask_storeu_pd(p + 8, mb, b);
  _mm512_mask_storeu_pd(p + 16, mc, c);
}

// Column k of eight rows of three ints stored contiguously (24 ints from p, all read).
RB_AVX512_KERNEL inline void LoadColumns8(const int* p, __m256i* columns) {
  const __m512i a = _mm512_loadu_si512(p);
  const __m512i b = _mm512_maskz_loadu_epi32(static_cast<__mmask16>(0x00FF), p + 16);
  for (int k = 0; k < 3; ++k) {
    const __m512i index = _mm512_add_epi32(_mm512_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21, 0, 0, 0, 0, 0, 0, 0, 0),
                                           _mm512_set1_epi32(k));
    // (masked extract: the plain cast trips -Wmaybe-uninitialized in GCC 12)
    columns[k] = _mm512_maskz_extracti32x8_epi32(static_cast<__mmask8>(0xFF), _mm512_permutex2var_epi32(a, index, b), 0);
  }
}

RB_AVX512_KERNEL double SqrtFacePassAvx512(const SqrtFacePassInput& in, int begin, int end, double sum) {
  const __m512d zero = _mm512_setzero_pd(), one = _mm512_set1_pd(1.0), half = _mm512_set1_pd(0.5);
  const __m512d beta = _mm512_set1_pd(in.beta), global_e2 = _mm512_set1_pd(in.e2);
  alignas(64) double energy[8];
  alignas(32) int count_lanes[8];
  for (int t0 = begin; t0 < end; t0 += 8) {
    const int n = std::min(8, end - t0);
    const __mmask8 valid = static_cast<__mmask8>((1u << n) - 1u);
    const __m256i lo = _mm256_maskz_loadu_epi32(valid, in.offsets + t0);
    const __m256i count = _mm256_sub_epi32(_mm256_maskz_loadu_epi32(valid, in.offsets + t0 + 1), lo);
    _mm256_store_si256(reinterpret_cast<__m256i*>(count_lanes), count);
    int max_count = 0;
    for (int l = 0; l < n; ++l) max_count = std::max(max_count, count_lanes[l]);
    __m512d ntx, nty, ntz;
    LoadXyz8(in.normals + 3 * static_cast<size_t>(t0), n, &ntx, &nty, &ntz);
    const __m512d e2t = in.face_e2 != nullptr ? _mm512_maskz_loadu_pd(valid, in.face_e2 + t0) : zero;
    __m512d e = zero, gx = zero, gy = zero, gz = zero;
    // The common case, eight faces with three neighbours each: their 24 neighbour indices are contiguous.
    __m256i slots[3];
    const bool three_each = n == 8 && _mm256_cmpeq_epi32_mask(count, _mm256_set1_epi32(3)) == 0xFF;
    if (three_each) LoadColumns8(in.neighbours + in.offsets[t0], slots);
    for (int k = 0; k < max_count; ++k) {
      const __mmask8 m = _mm256_cmpgt_epi32_mask(count, _mm256_set1_epi32(k));
      const __m256i s = three_each ? slots[k]
                                   : _mm256_mmask_i32gather_epi32(_mm256_setzero_si256(), m,
                                                                  _mm256_add_epi32(lo, _mm256_set1_epi32(k)),
                                                                  in.neighbours, 4);
      const __m256i s3 = _mm256_add_epi32(s, _mm256_add_epi32(s, s));
      const __m512d dx = _mm512_sub_pd(ntx, _mm512_mask_i32gather_pd(zero, m, s3, in.normals, 8));
      const __m512d dy = _mm512_sub_pd(nty, _mm512_mask_i32gather_pd(zero, m, s3, in.normals + 1, 8));
      const __m512d dz = _mm512_sub_pd(ntz, _mm512_mask_i32gather_pd(zero, m, s3, in.normals + 2, 8));
      const __m512d d2 = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)), _mm512_mul_pd(dz, dz));
      __m512d a;
      if (in.face_e2 != nullptr) {
        const __m512d e2s = _mm512_mask_i32gather_pd(zero, m, s, in.face_e2, 8);
        a = _mm512_add_pd(d2, _mm512_mul_pd(half, _mm512_add_pd(e2t, e2s)));
      } else {
        a = _mm512_add_pd(d2, global_e2);
      }
      const __m512d v = _mm512_maskz_sqrt_pd(m, a);  // (the unmasked form trips -Wmaybe-uninitialized in GCC 12)
      const __m512d w = _mm512_div_pd(one, v);
      e = _mm512_mask_add_pd(e, m, e, v);
      gx = _mm512_mask_add_pd(gx, m, gx, _mm512_mul_pd(w, dx));
      gy = _mm512_mask_add_pd(gy, m, gy, _mm512_mul_pd(w, dy));
      gz = _mm512_mask_add_pd(gz, m, gz, _mm512_mul_pd(w, dz));
    }
    if (in.h != nullptr) {
      const __m512d inv = _mm512_mul_pd(_mm512_maskz_loadu_pd(valid, in.inverse_length + t0), beta);
      const __mmask8 live = _mm512_mask_cmp_pd_mask(valid, inv, zero, _CMP_NEQ_UQ);
      const __m512d ng = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(ntx, gx), _mm512_mul_pd(nty, gy)), _mm512_mul_pd(ntz, gz));
      const __m512d hx = _mm512_mul_pd(_mm512_sub_pd(gx, _mm512_mul_pd(ntx, ng)), inv);
      const __m512d hy = _mm512_mul_pd(_mm512_sub_pd(gy, _mm512_mul_pd(nty, ng)), inv);
      const __m512d hz = _mm512_mul_pd(_mm512_sub_pd(gz, _mm512_mul_pd(ntz, ng)), inv);
      // Only h_t (zero where the face has no normal); the vertex gather forms h_t × e_k.
      StoreXyz8(in.h + 3 * static_cast<size_t>(t0), n, _mm512_maskz_mov_pd(live, hx), _mm512_maskz_mov_pd(live, hy),
                _mm512_maskz_mov_pd(live, hz));
    }
    _mm512_store_pd(energy, _mm512_mul_pd(half, e));
    for (int l = 0; l < n; ++l) sum += energy[l];
  }
  return sum;
}

// ComputeNormals over faces [begin, end), eight faces per step; the portable loop's operations per lane.
RB_AVX512_KERNEL void NormalsAvx512(const double* x, const int* faces, const char* active, int begin, int end,
                                    double* normals, double* inverse_length) {
  const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m512d zero = _mm512_setzero_pd(), one = _mm512_set1_pd(1.0);
  const __m512d infinity = _mm512_set1_pd(std::numeric_limits<double>::infinity());
  for (int t0 = begin; t0 < end; t0 += 8) {
    const int n = std::min(8, end - t0);
    __mmask8 valid = static_cast<__mmask8>((1u << n) - 1u);
    const __m256i t = _mm256_add_epi32(_mm256_set1_epi32(t0), lanes);
    const __m256i t3 = _mm256_add_epi32(t, _mm256_add_epi32(t, t));
    __mmask8 on = 0;
    __m256i corners[3];
    if (n == 8) {
      on = static_cast<__mmask8>(~_mm_movemask_epi8(_mm_cmpeq_epi8(
          _mm_loadl_epi64(reinterpret_cast<const __m128i*>(active + t0)), _mm_setzero_si128())));
      LoadColumns8(faces + 3 * static_cast<size_t>(t0), corners);
    } else {
      for (int l = 0; l < n; ++l) on = static_cast<__mmask8>(on | (active[t0 + l] ? 1u << l : 0u));
      for (int k = 0; k < 3; ++k) corners[k] = _mm256_mmask_i32gather_epi32(_mm256_setzero_si256(), on, t3, faces + k, 4);
    }
    __m512d px[3], py[3], pz[3];
    for (int k = 0; k < 3; ++k) {
      const __m256i v = corners[k];
      const __m256i v3 = _mm256_add_epi32(v, _mm256_add_epi32(v, v));
      px[k] = _mm512_mask_i32gather_pd(zero, on, v3, x, 8);
      py[k] = _mm512_mask_i32gather_pd(zero, on, v3, x + 1, 8);
      pz[k] = _mm512_mask_i32gather_pd(zero, on, v3, x + 2, 8);
    }
    const __m512d ax = _mm512_sub_pd(px[1], px[0]), ay = _mm512_sub_pd(py[1], py[0]), az = _mm512_sub_pd(pz[1], pz[0]);
    const __m512d bx = _mm512_sub_pd(px[2], px[0]), by = _mm512_sub_pd(py[2], py[0]), bz = _mm512_sub_pd(pz[2], pz[0]);
    const __m512d cx = _mm512_sub_pd(_mm512_mul_pd(ay, bz), _mm512_mul_pd(az, by));
    const __m512d cy = _mm512_sub_pd(_mm512_mul_pd(az, bx), _mm512_mul_pd(ax, bz));
    const __m512d cz = _mm512_sub_pd(_mm512_mul_pd(ax, by), _mm512_mul_pd(ay, bx));
    const __m512d length2 = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(cx, cx), _mm512_mul_pd(cy, cy)), _mm512_mul_pd(cz, cz));
    const __m512d length = _mm512_maskz_sqrt_pd(on, length2);
    // length > 0 and finite (false for NaN), as the portable test.
    const __mmask8 good = _mm512_mask_cmp_pd_mask(on, length, zero, _CMP_GT_OQ) &
                          _mm512_mask_cmp_pd_mask(on, length, infinity, _CMP_LT_OQ);
    const __m512d inv = _mm512_maskz_div_pd(good, one, length);
    const __m512d nx = _mm512_mul_pd(cx, inv), ny = _mm512_mul_pd(cy, inv), nz = _mm512_mul_pd(cz, inv);
    StoreXyz8(normals + 3 * static_cast<size_t>(t0), n, _mm512_maskz_mov_pd(good, nx), _mm512_maskz_mov_pd(good, ny),
              _mm512_maskz_mov_pd(good, nz));
    _mm512_mask_storeu_pd(inverse_length + t0, valid, inv);
  }
}

// Pass 3's gather for vertices [begin, end): per corner the contribution h_t × e_k formed from the face's h_t
// and two positions, its three components in one ymm register, added in corner order; the data term as the
// portable loop computes it. Returns `sum` plus the vertices' data terms added one after another.
RB_AVX512_KERNEL double GatherAvx512(const double* x, const double* z, const double* information, bool isotropic,
                                     const int* corner_offsets, const int* corners, const int* corner_edges,
                                     const double* h_t, int begin, int end, double* grad, double sum, double nu) {
  const __mmask8 xyz = 0x7;
  for (int i = begin; i < end; ++i) {
    double w[6];
    if (isotropic) {
      w[0] = w[3] = w[5] = information[i];
      w[1] = w[2] = w[4] = 0;
    } else {
      for (int k = 0; k < 6; ++k) w[k] = information[6 * static_cast<size_t>(i) + k];
    }
    const double rx = x[3 * i] - z[3 * i], ry = x[3 * i + 1] - z[3 * i + 1], rz = x[3 * i + 2] - z[3 * i + 2];
    const double wx = w[0] * rx + w[1] * ry + w[2] * rz;
    const double wy = w[1] * rx + w[3] * ry + w[4] * rz;
    const double wz = w[2] * rx + w[4] * ry + w[5] * rz;
    const double q = rx * wx + ry * wy + rz * wz;
    // Robust data term (SetRobustData): the Gaussian's gradient scaled by dρ/dq = ν / (ν + 2q).
    const double f = nu > 0 ? nu / (nu + 2 * q) : 1.0;
    if (grad != nullptr) {
      __m256d s = nu > 0 ? _mm256_setr_pd(2 * wx * f, 2 * wy * f, 2 * wz * f, 0.0)
                         : _mm256_setr_pd(2 * wx, 2 * wy, 2 * wz, 0.0);
      const int q_end = corner_offsets[i + 1];
      for (int q = corner_offsets[i]; q < q_end; ++q) {
        // Corner k of face t: h_t × (p_(k+2) − p_(k+1)), the portable face pass's operations, in ymm lanes
        // (x y z) as a·b − c·d with a = h.yzx, b = e.zxy, c = h.zxy, d = e.yzx.
        const int t = corners[q] / 3;
        const int v1 = corner_edges[2 * static_cast<size_t>(q)], v2 = corner_edges[2 * static_cast<size_t>(q) + 1];
        const __m256d h = _mm256_maskz_loadu_pd(xyz, h_t + 3 * static_cast<size_t>(t));
        const __m256d e = _mm256_sub_pd(_mm256_maskz_loadu_pd(xyz, x + 3 * static_cast<size_t>(v2)),
                                        _mm256_maskz_loadu_pd(xyz, x + 3 * static_cast<size_t>(v1)));
        const __m256d c = _mm256_sub_pd(_mm256_mul_pd(_mm256_permute4x64_pd(h, 0xC9), _mm256_permute4x64_pd(e, 0xD2)),
                                        _mm256_mul_pd(_mm256_permute4x64_pd(h, 0xD2), _mm256_permute4x64_pd(e, 0xC9)));
        s = _mm256_add_pd(s, c);
      }
      _mm256_mask_storeu_pd(grad + 3 * static_cast<size_t>(i), xyz, s);
    }
    sum += nu > 0 ? 0.5 * nu * std::log1p(2 * q / nu) : q;
  }
  return sum;
}

#else
Isa ActiveIsa() { return Isa::kPortable; }
#endif

// The neighbour sums of Evaluate's portable face pass: for face t with unit normal nt, add Σ_s φ and
// Σ_s w_ts (n_t − n_s) over its neighbours s (rows [offsets[t], offsets[t+1]) of neighbours) into sums[0] and
// sums[1..3], one neighbour after another in row order.
struct FaceNeighbours {
  const int* offsets;
  const int* neighbours;
  const double* normals;
};

// Any potential: pair(t, s, d², &w) returns φ(d) and sets w = φ'(d)/d.
template <typename Pair>
void PairwiseSums(const FaceNeighbours& g, int t, const double* nt, double* sums, const Pair& pair) {
  const int end = g.offsets[t + 1];
  for (int q = g.offsets[t]; q < end; ++q) {
    const int s = g.neighbours[q];
    const double* ns = &g.normals[3 * static_cast<size_t>(s)];
    const double dx = nt[0] - ns[0], dy = nt[1] - ns[1], dz = nt[2] - ns[2];
    double weight;
    sums[0] += pair(t, s, dx * dx + dy * dy + dz * dz, &weight);
    sums[1] += weight * dx;
    sums[2] += weight * dy;
    sums[3] += weight * dz;
  }
}

// The square root, φ = sqrt(d² + ε²) and w = 1/φ, two neighbours at a time in SSE2 lanes (sqrtpd, divpd):
// the square roots and divisions were ~1/6 of an evaluation. Correctly rounded either way and summed in
// the same order, so the bytes are those of the scalar loop. argument(t, s, d²) = d² + ε².
template <typename Argument>
void SquareRootSums(const FaceNeighbours& g, int t, const double* nt, double* sums, const Argument& argument) {
  const int begin = g.offsets[t], end = g.offsets[t + 1];
  for (int q = begin; q < end; q += 2) {
    const bool two = q + 1 < end;
    const int s0 = g.neighbours[q];
    const int s1 = two ? g.neighbours[q + 1] : s0;
    const double* n0 = &g.normals[3 * static_cast<size_t>(s0)];
    const double* n1 = &g.normals[3 * static_cast<size_t>(s1)];
    const double dx0 = nt[0] - n0[0], dy0 = nt[1] - n0[1], dz0 = nt[2] - n0[2];
    const double dx1 = nt[0] - n1[0], dy1 = nt[1] - n1[1], dz1 = nt[2] - n1[2];
    const double a0 = argument(t, s0, dx0 * dx0 + dy0 * dy0 + dz0 * dz0);
    const double a1 = argument(t, s1, dx1 * dx1 + dy1 * dy1 + dz1 * dz1);
    double value[2], weight[2];
#if defined(__SSE2__)
    const __m128d v = _mm_sqrt_pd(_mm_set_pd(a1, a0));
    _mm_storeu_pd(value, v);
    _mm_storeu_pd(weight, _mm_div_pd(_mm_set1_pd(1.0), v));
#else
    value[0] = std::sqrt(a0);
    value[1] = std::sqrt(a1);
    weight[0] = 1.0 / value[0];
    weight[1] = 1.0 / value[1];
#endif
    sums[0] += value[0];
    sums[1] += weight[0] * dx0;
    sums[2] += weight[0] * dy0;
    sums[3] += weight[0] * dz0;
    if (two) {
      sums[0] += value[1];
      sums[1] += weight[1] * dx1;
      sums[2] += weight[1] * dy1;
      sums[3] += weight[1] * dz1;
    }
  }
}

}  // namespace

void SetSmoothingKernel(SmoothingKernel kernel) { g_kernel = kernel; }

const char* SmoothingKernelName() {
  switch (ActiveIsa()) {
    case Isa::kAvx512:
      return "avx512";
    case Isa::kPortable:
      break;
  }
  return "portable";
}

SmoothingEnergy::SmoothingEnergy(const Mesh& measured, const std::vector<Eigen::Matrix3d>& information,
                                 double prior_weight, const Potential& potential,
                                 const std::vector<double>* face_epsilon_squared)
    : num_vertices_(measured.num_vertices()),
      faces_(measured.F),
      z_(measured.V.data(), 3 * static_cast<Eigen::Index>(measured.num_vertices())),
      prior_weight_(prior_weight),
      potential_(&potential) {
  const int nv = num_vertices_, nf = measured.num_faces();
  RB_CHECK(static_cast<int>(information.size()) == nv, "smoothing: ", information.size(),
           " information matrices for ", nv, " vertices");
  RB_CHECK(prior_weight >= 0 && std::isfinite(prior_weight), "smoothing: prior weight ", prior_weight,
           " must be finite and non-negative");
  RB_CHECK(measured.V.allFinite(), "smoothing: the input mesh has non-finite vertex coordinates");
  if (face_epsilon_squared != nullptr) SetFaceEpsilonSquared(*face_epsilon_squared);
  SetInformation(information);
  MarkActiveFaces();
  BuildCorners();
  BuildFaceNeighbours();
  normals_.assign(3 * static_cast<size_t>(nf), 0.0);
  inverse_length_.assign(static_cast<size_t>(nf), 0.0);
  h_.assign((ThreePerFace() ? 3 : 9) * static_cast<size_t>(nf), 0.0);
  if (ThreePerFace()) BuildCornerEdges();
}

void SmoothingEnergy::SetFaceEpsilonSquared(const std::vector<double>& face_epsilon_squared) {
  const int nf = num_faces();
  const Potential& potential = *potential_;
  RB_CHECK(dynamic_cast<const SqrtPotential*>(&potential) != nullptr,
           "smoothing: a per-face epsilon_squared needs the square-root potential, not ", potential.Name());
  RB_CHECK(static_cast<int>(face_epsilon_squared.size()) == nf, "smoothing: ", face_epsilon_squared.size(),
           " per-face epsilon_squared values for ", nf, " faces");
  for (int f = 0; f < nf; ++f) {
    const double e2 = face_epsilon_squared[static_cast<size_t>(f)];
    RB_CHECK(e2 > 0 && e2 <= 4, "smoothing: epsilon_squared of face ", f, " is ", e2, ", outside (0, 4]");
  }
  face_epsilon_squared_ = face_epsilon_squared;
}

void SmoothingEnergy::SetInformation(const std::vector<Eigen::Matrix3d>& information) {
  const int nv = num_vertices_;
  // Isotropic W_i = w_i I (every generic mesh) is stored as one number per vertex instead of six.
  isotropic_ = true;
  for (int i = 0; i < nv && isotropic_; ++i) {
    const Eigen::Matrix3d& W = information[static_cast<size_t>(i)];
    isotropic_ = W(0, 1) == 0 && W(1, 0) == 0 && W(0, 2) == 0 && W(2, 0) == 0 && W(1, 2) == 0 && W(2, 1) == 0 &&
                 W(0, 0) == W(1, 1) && W(1, 1) == W(2, 2);
  }
  information_.resize((isotropic_ ? 1 : 6) * static_cast<size_t>(nv));
  uniform_isotropic_ = isotropic_;
  for (int i = 1; i < nv && uniform_isotropic_; ++i) {
    uniform_isotropic_ = information[static_cast<size_t>(i)](0, 0) == information[0](0, 0);
  }
  for (int i = 0; i < nv; ++i) {
    const Eigen::Matrix3d& W = information[static_cast<size_t>(i)];
    RB_CHECK(W.allFinite(), "smoothing: information matrix of vertex ", i, " is not finite");
    if (isotropic_) {
      information_[static_cast<size_t>(i)] = W(0, 0);
      continue;
    }
    double* w = &information_[6 * static_cast<size_t>(i)];
    // Symmetrise: only the symmetric part enters rᵀ W r.
    w[0] = W(0, 0);
    w[1] = 0.5 * (W(0, 1) + W(1, 0));
    w[2] = 0.5 * (W(0, 2) + W(2, 0));
    w[3] = W(1, 1);
    w[4] = 0.5 * (W(1, 2) + W(2, 1));
    w[5] = W(2, 2);
  }
}

// Active faces: distinct indices and a measured area that is not negligible.
void SmoothingEnergy::MarkActiveFaces() {
  const int nv = num_vertices_, nf = num_faces();
  active_.assign(static_cast<size_t>(nf), 1);
  std::vector<double> area2(static_cast<size_t>(nf), 0.0);
  double sum_area2 = 0;
  for (int f = 0; f < nf; ++f) {
    const int a = faces_(f, 0), b = faces_(f, 1), c = faces_(f, 2);
    for (int v : {a, b, c}) {
      RB_CHECK(v >= 0 && v < nv, "smoothing: face ", f, " refers to vertex ", v, ", but the mesh has ", nv,
               " vertices");
    }
    if (a == b || b == c || a == c) {
      active_[static_cast<size_t>(f)] = 0;
      continue;
    }
    const Eigen::Vector3d pa = z_.segment<3>(3 * a), pb = z_.segment<3>(3 * b), pc = z_.segment<3>(3 * c);
    area2[static_cast<size_t>(f)] = (pb - pa).cross(pc - pa).norm();
    sum_area2 += area2[static_cast<size_t>(f)];
  }
  const double threshold = nf > 0 ? 1e-10 * sum_area2 / nf : 0.0;
  for (int f = 0; f < nf; ++f) {
    if (active_[static_cast<size_t>(f)] && !(area2[static_cast<size_t>(f)] > threshold)) {
      active_[static_cast<size_t>(f)] = 0;
    }
    if (!active_[static_cast<size_t>(f)]) ++num_inactive_faces_;
  }
}

// Vertex → corners of active faces, ascending.
void SmoothingEnergy::BuildCorners() {
  const int nv = num_vertices_, nf = num_faces();
  corner_offsets_.assign(static_cast<size_t>(nv) + 1, 0);
  for (int f = 0; f < nf; ++f) {
    if (!active_[static_cast<size_t>(f)]) continue;
    for (int k = 0; k < 3; ++k) ++corner_offsets_[static_cast<size_t>(faces_(f, k)) + 1];
  }
  for (int v = 0; v < nv; ++v) corner_offsets_[v + 1] += corner_offsets_[v];
  corners_.resize(static_cast<size_t>(corner_offsets_[nv]));
  std::vector<int> fill(corner_offsets_.begin(), corner_offsets_.end() - 1);
  for (int f = 0; f < nf; ++f) {
    if (!active_[static_cast<size_t>(f)]) continue;
    for (int k = 0; k < 3; ++k) corners_[static_cast<size_t>(fill[faces_(f, k)]++)] = 3 * f + k;
  }
}

// Face adjacency over active faces (the pairs of ComputeFacePairs, both directions, each row ascending):
// the active faces around an edge's first vertex that also hold its second. Linear time through the
// corner lists above, where the sort in ComputeEdgeTopology took a third of the setup at 1M faces.
void SmoothingEnergy::BuildFaceNeighbours() {
  const int nf = num_faces();
  auto collect = [&](int t, std::vector<int>* out) {
    out->clear();
    if (!active_[static_cast<size_t>(t)]) return;
    for (int k = 0; k < 3; ++k) {
      const int u = faces_(t, k), v = faces_(t, k == 2 ? 0 : k + 1);
      for (int q = corner_offsets_[u]; q < corner_offsets_[u + 1]; ++q) {
        const int s = corners_[static_cast<size_t>(q)] / 3;
        if (s != t && (faces_(s, 0) == v || faces_(s, 1) == v || faces_(s, 2) == v)) out->push_back(s);
      }
    }
    std::sort(out->begin(), out->end());
    out->erase(std::unique(out->begin(), out->end()), out->end());  // two faces sharing two edges: one pair
  };
  // One search per face into three slots per face (every face of a manifold mesh has at most three
  // neighbours), compacted in place; a second search only for faces with more (non-manifold edges).
  neighbour_offsets_.assign(static_cast<size_t>(nf) + 1, 0);
  neighbours_.resize(3 * static_cast<size_t>(nf));
  tbb::parallel_for(tbb::blocked_range<int>(0, nf, kGrain), [&](const tbb::blocked_range<int>& r) {
    std::vector<int> buffer;
    for (int t = r.begin(); t != r.end(); ++t) {
      collect(t, &buffer);
      neighbour_offsets_[static_cast<size_t>(t) + 1] = static_cast<int>(buffer.size());
      std::copy_n(buffer.begin(), std::min<size_t>(buffer.size(), 3), neighbours_.begin() + 3 * static_cast<size_t>(t));
    }
  });
  bool all_fit = true;
  for (int f = 0; f < nf; ++f) {
    all_fit = all_fit && neighbour_offsets_[f + 1] <= 3;
    neighbour_offsets_[f + 1] += neighbour_offsets_[f];
  }
  if (all_fit) {
    // offsets[f] ≤ 3f: moving left in increasing f never overwrites a slot not yet moved.
    for (int f = 0; f < nf; ++f) {
      const int count = neighbour_offsets_[f + 1] - neighbour_offsets_[f];
      for (int k = 0; k < count; ++k) {
        neighbours_[static_cast<size_t>(neighbour_offsets_[f] + k)] = neighbours_[3 * static_cast<size_t>(f) + k];
      }
    }
    neighbours_.resize(static_cast<size_t>(neighbour_offsets_[nf]));
    neighbours_.shrink_to_fit();
  } else {
    neighbours_.assign(static_cast<size_t>(neighbour_offsets_[nf]), 0);
    tbb::parallel_for(tbb::blocked_range<int>(0, nf, kGrain), [&](const tbb::blocked_range<int>& r) {
      std::vector<int> buffer;
      for (int t = r.begin(); t != r.end(); ++t) {
        collect(t, &buffer);
        std::copy(buffer.begin(), buffer.end(), neighbours_.begin() + neighbour_offsets_[static_cast<size_t>(t)]);
      }
    });
  }
}

void SmoothingEnergy::BuildCornerEdges() const {
  // Per corner 3t + k, the vertices p_(k+1), p_(k+2) of its opposite edge, in the corner order of corners_.
  corner_edges_.resize(2 * corners_.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, corners_.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t q = r.begin(); q != r.end(); ++q) {
      const int t = corners_[q] / 3, k = corners_[q] % 3;
      corner_edges_[2 * q] = faces_(t, k == 2 ? 0 : k + 1);
      corner_edges_[2 * q + 1] = faces_(t, k == 0 ? 2 : k - 1);
    }
  });
}

bool SmoothingEnergy::ThreePerFace() const {
  return !face_epsilon_squared_.empty() || dynamic_cast<const SqrtPotential*>(potential_) != nullptr;
}

Eigen::VectorXd SmoothingEnergy::Measurements() const { return z_; }

void SmoothingEnergy::SetPotential(const Potential& potential) {
  RB_CHECK((dynamic_cast<const SqrtPotential*>(&potential) != nullptr) ==
               (dynamic_cast<const SqrtPotential*>(potential_) != nullptr),
           "smoothing: cannot switch the potential from ", potential_->Name(), " to ", potential.Name());
  potential_ = &potential;
}

size_t SmoothingEnergy::MemoryBytes() const {
  return sizeof(int) * (neighbour_offsets_.size() + neighbours_.size() + corner_offsets_.size() +
                        corners_.size() + corner_edges_.size()) +
         sizeof(double) * (information_.size() + normals_.size() +
                           inverse_length_.size() + h_.size() + face_epsilon_squared_.size()) +
         active_.size();
}

// Unit normal and 1/|c_t| per active face into normals_ / inverse_length_.
void SmoothingEnergy::ComputeNormals(const double* x) const {
  const int nf = num_faces();
#if RB_SMOOTHING_AVX512
  const Isa isa = ActiveIsa();
  if (isa != Isa::kPortable) {
    tbb::parallel_for(tbb::blocked_range<int>(0, nf, kGrain), [&](const tbb::blocked_range<int>& r) {
      NormalsAvx512(x, faces_.data(), active_.data(), r.begin(), r.end(), normals_.data(), inverse_length_.data());
    });
    return;
  }
#endif
  tbb::parallel_for(tbb::blocked_range<int>(0, nf, kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int f = r.begin(); f != r.end(); ++f) {
      double* n = &normals_[3 * static_cast<size_t>(f)];
      if (!active_[static_cast<size_t>(f)]) {
        n[0] = n[1] = n[2] = 0;
        inverse_length_[static_cast<size_t>(f)] = 0;
        continue;
      }
      const Eigen::Vector3d pa = Position(x, faces_(f, 0));
      const Eigen::Vector3d c = (Position(x, faces_(f, 1)) - pa).cross(Position(x, faces_(f, 2)) - pa);
      const double length = c.norm();
      if (length > 0 && std::isfinite(length)) {
        const double inv = 1.0 / length;
        n[0] = c.x() * inv;
        n[1] = c.y() * inv;
        n[2] = c.z() * inv;
        inverse_length_[static_cast<size_t>(f)] = inv;
      } else {
        n[0] = n[1] = n[2] = 0;
        inverse_length_[static_cast<size_t>(f)] = 0;
      }
    }
  });

}

EnergyParts SmoothingEnergy::Evaluate(const Eigen::VectorXd& x_vector, Eigen::VectorXd* gradient) const {
  RB_CHECK(x_vector.size() == z_.size(), "smoothing: state has ", x_vector.size(), " entries, expected ", z_.size());
  const double* x = x_vector.data();
  ComputeNormals(x);
  const double prior_sum = PriorPass(x, gradient != nullptr);
  if (gradient != nullptr) gradient->resize(z_.size());
  const double data_sum = DataPass(x, gradient != nullptr ? gradient->data() : nullptr);
  return EnergyParts{data_sum, prior_weight_ * prior_sum};
}

// Pass 2: per face t, half of each pair's potential (both faces of a pair count it), then, for the gradient,
// h_t = β P_t g_t / |c_t| with g_t = Σ_s w_ts (n_t − n_s): h_t alone into h_[3t ..] for the square root
// (ThreePerFace), else the face's three corner contributions h_t × e_k (e_k the edge opposite corner k) into
// h_[9t + 3k ..].
double SmoothingEnergy::PriorPass(const double* x, bool want_gradient) const {
#if RB_SMOOTHING_AVX512
  if (ThreePerFace() && ActiveIsa() == Isa::kAvx512) {
    const int nf = num_faces();
    const auto* sqrt_potential = dynamic_cast<const SqrtPotential*>(potential_);
    const SqrtFacePassInput input{x,
                                  faces_.data(),
                                  normals_.data(),
                                  inverse_length_.data(),
                                  neighbour_offsets_.data(),
                                  neighbours_.data(),
                                  face_epsilon_squared_.empty() ? nullptr : face_epsilon_squared_.data(),
                                  sqrt_potential != nullptr ? sqrt_potential->epsilon_squared() : 0.0,
                                  prior_weight_,
                                  want_gradient ? h_.data() : nullptr};
    // Same range tree as DeterministicSum, same order inside each range: the same bytes.
    return tbb::parallel_deterministic_reduce(
        tbb::blocked_range<int>(0, nf, kGrain), 0.0,
        [&](const tbb::blocked_range<int>& r, double sum) {
          return SqrtFacePassAvx512(input, r.begin(), r.end(), sum);
        },
        [](double a, double b) { return a + b; });
  }
#endif
  return PortablePriorPass(x, want_gradient);
}

double SmoothingEnergy::PortablePriorPass(const double* x, bool want_gradient) const {
  const int nf = num_faces();
  const double beta = prior_weight_;
  const FaceNeighbours graph{neighbour_offsets_.data(), neighbours_.data(), normals_.data()};
  // The pair kernel is a template argument so the square root (the default) is inlined; other potentials go
  // through the virtual call. The square root keeps h_t alone (the gather forms the corner products: a third of
  // the memory traffic), other potentials the three products.
  const bool h_only = ThreePerFace();
  auto face_pass = [&](auto neighbour_sum) {
    return DeterministicSum(nf, [&](int t) {
      const double* nt = &normals_[3 * static_cast<size_t>(t)];
      double sums[4] = {0, 0, 0, 0};
      neighbour_sum(t, nt, sums);
      const double energy = sums[0], gx = sums[1], gy = sums[2], gz = sums[3];
      if (want_gradient) {
        // h_t: the gradient projected off n_t and scaled by β / |c_t| (zero on a degenerate face).
        const double inv = inverse_length_[static_cast<size_t>(t)] * beta;
        double hx = 0, hy = 0, hz = 0;
        if (inv != 0) {
          const double ng = nt[0] * gx + nt[1] * gy + nt[2] * gz;
          hx = (gx - nt[0] * ng) * inv;
          hy = (gy - nt[1] * ng) * inv;
          hz = (gz - nt[2] * ng) * inv;
        }
        if (h_only) {
          double* out = &h_[3 * static_cast<size_t>(t)];
          out[0] = hx;
          out[1] = hy;
          out[2] = hz;
        } else if (inv == 0) {
          for (int k = 0; k < 9; ++k) h_[9 * static_cast<size_t>(t) + k] = 0;
        } else {
          double* out = &h_[9 * static_cast<size_t>(t)];
          const double* p[3] = {x + 3 * faces_(t, 0), x + 3 * faces_(t, 1), x + 3 * faces_(t, 2)};
          for (int k = 0; k < 3; ++k) {
            const double* p1 = p[k == 2 ? 0 : k + 1];
            const double* p2 = p[k == 0 ? 2 : k - 1];
            const double ex = p2[0] - p1[0], ey = p2[1] - p1[1], ez = p2[2] - p1[2];
            out[3 * k] = hy * ez - hz * ey;
            out[3 * k + 1] = hz * ex - hx * ez;
            out[3 * k + 2] = hx * ey - hy * ex;
          }
        }
      }
      return 0.5 * energy;
    });
  };
  if (!face_epsilon_squared_.empty()) {
    const double* face_e2 = face_epsilon_squared_.data();
    const auto argument = [face_e2](int t, int s, double d2) { return d2 + 0.5 * (face_e2[t] + face_e2[s]); };
    return face_pass([&](int t, const double* nt, double* sums) { SquareRootSums(graph, t, nt, sums, argument); });
  }
  if (const auto* sqrt_potential = dynamic_cast<const SqrtPotential*>(potential_)) {
    const double e2 = sqrt_potential->epsilon_squared();
    const auto argument = [e2](int, int, double d2) { return d2 + e2; };
    return face_pass([&](int t, const double* nt, double* sums) { SquareRootSums(graph, t, nt, sums, argument); });
  }
  const Potential& potential = *potential_;
  const auto pair = [&potential](int, int, double d2, double* weight) {
    double value = 0;
    potential.EvaluateWeight(std::sqrt(d2), &value, weight);
    return value;
  };
  return face_pass([&](int t, const double* nt, double* sums) { PairwiseSums(graph, t, nt, sums, pair); });
}

// Pass 3: per vertex, the data term and the gather of corner contributions in corner order.
double SmoothingEnergy::DataPass(const double* x, double* grad) const {
  const int nv = num_vertices_;
  const double* contributions = h_.data();
#if RB_SMOOTHING_AVX512
  if (ThreePerFace() && ActiveIsa() == Isa::kAvx512) {
    return tbb::parallel_deterministic_reduce(
        tbb::blocked_range<int>(0, nv, kGrain), 0.0,
        [&](const tbb::blocked_range<int>& r, double sum) {
          return GatherAvx512(x, z_.data(), information_.data(), isotropic_, corner_offsets_.data(), corners_.data(),
                              corner_edges_.data(), contributions, r.begin(), r.end(), grad, sum, data_nu_);
        },
        [](double a, double b) { return a + b; });
  }
#endif
  const double nu = data_nu_;
  const bool h_only = ThreePerFace();
  return DeterministicSum(nv, [&](int i) {
    double w[6];
    Information(i, w);
    const double rx = x[3 * i] - z_[3 * i], ry = x[3 * i + 1] - z_[3 * i + 1], rz = x[3 * i + 2] - z_[3 * i + 2];
    const double wx = w[0] * rx + w[1] * ry + w[2] * rz;
    const double wy = w[1] * rx + w[3] * ry + w[4] * rz;
    const double wz = w[2] * rx + w[4] * ry + w[5] * rz;
    const double q = rx * wx + ry * wy + rz * wz;
    const double f = nu > 0 ? nu / (nu + 2 * q) : 1.0;
    if (grad != nullptr) {
      double sx = nu > 0 ? 2 * wx * f : 2 * wx, sy = nu > 0 ? 2 * wy * f : 2 * wy, sz = nu > 0 ? 2 * wz * f : 2 * wz;
      const int end = corner_offsets_[i + 1];
      if (h_only) {
        // Corner k of face t: h_t × (p_(k+2) − p_(k+1)), the operations of the 9-per-face products below.
        for (int q = corner_offsets_[i]; q < end; ++q) {
          const double* h = contributions + 3 * static_cast<size_t>(corners_[static_cast<size_t>(q)] / 3);
          const double* p1 = x + 3 * static_cast<size_t>(corner_edges_[2 * static_cast<size_t>(q)]);
          const double* p2 = x + 3 * static_cast<size_t>(corner_edges_[2 * static_cast<size_t>(q) + 1]);
          const double ex = p2[0] - p1[0], ey = p2[1] - p1[1], ez = p2[2] - p1[2];
          sx += h[1] * ez - h[2] * ey;
          sy += h[2] * ex - h[0] * ez;
          sz += h[0] * ey - h[1] * ex;
        }
      } else {
        for (int q = corner_offsets_[i]; q < end; ++q) {
          const double* c = contributions + 3 * static_cast<size_t>(corners_[static_cast<size_t>(q)]);
          sx += c[0];
          sy += c[1];
          sz += c[2];
        }
      }
      grad[3 * i] = sx;
      grad[3 * i + 1] = sy;
      grad[3 * i + 2] = sz;
    }
    return nu > 0 ? 0.5 * nu * std::log1p(2 * q / nu) : q;
  });
}

void SmoothingEnergy::SetRobustData(double nu) {
  RB_CHECK(nu >= 0 && nu <= 1e6 && std::isfinite(nu), "smoothing: robust data nu ", nu, " is outside {0} ∪ (0, 1e6]");
  data_nu_ = nu;
}

void SmoothingEnergy::ApplyDataInverse(const Eigen::VectorXd& v, Eigen::VectorXd* out) const {
  out->resize(v.size());
  const double* in = v.data();
  double* o = out->data();
  tbb::parallel_for(tbb::blocked_range<int>(0, num_vertices_, kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i != r.end(); ++i) {
      double b[6];
      Information(i, b);
      const double a0 = in[3 * i], a1 = in[3 * i + 1], a2 = in[3 * i + 2];
      // (2W)⁻¹ by cofactors; W_i is positive definite (Smooth raises its eigenvalues to 1e-6 of the largest).
      const double c00 = b[3] * b[5] - b[4] * b[4], c01 = b[2] * b[4] - b[1] * b[5], c02 = b[1] * b[4] - b[2] * b[3];
      const double c11 = b[0] * b[5] - b[2] * b[2], c12 = b[1] * b[2] - b[0] * b[4], c22 = b[0] * b[3] - b[1] * b[1];
      const double det = b[0] * c00 + b[1] * c01 + b[2] * c02;
      if (!(det > 0) || !std::isfinite(det)) {
        o[3 * i] = a0;  // not positive definite (a caller-built W): leave this vertex unpreconditioned
        o[3 * i + 1] = a1;
        o[3 * i + 2] = a2;
        continue;
      }
      const double s = 0.5 / det;
      o[3 * i] = s * (c00 * a0 + c01 * a1 + c02 * a2);
      o[3 * i + 1] = s * (c01 * a0 + c11 * a1 + c12 * a2);
      o[3 * i + 2] = s * (c02 * a0 + c12 * a1 + c22 * a2);
    }
  });
}

namespace {

// The distinct vertices of the pair (t, s): t's three corners, then s's corners that t lacks.
int PairVertices(const Faces& faces, int t, int s, int* verts) {
  int m = 0;
  for (int f : {t, s}) {
    for (int k = 0; k < 3; ++k) {
      const int v = faces(f, k);
      int j = 0;
      while (j < m && verts[j] != v) ++j;
      if (j == m) verts[m++] = v;
    }
  }
  return m;
}

}  // namespace

SmoothingEnergy::RayPattern SmoothingEnergy::RayGaussNewtonPattern() const {
  const int nf = num_faces(), nv = num_vertices_;
  RayPattern pattern;
  pattern.entries.reserve(static_cast<size_t>(nv) + 5 * neighbours_.size());
  for (int i = 0; i < nv; ++i) pattern.entries.emplace_back(i, i);
  pattern.face_offsets.resize(static_cast<size_t>(nf) + 1);
  for (int t = 0; t < nf; ++t) {
    pattern.face_offsets[static_cast<size_t>(t)] = pattern.entries.size();
    for (int q = neighbour_offsets_[t]; q < neighbour_offsets_[t + 1]; ++q) {
      const int s = neighbours_[static_cast<size_t>(q)];
      if (s < t) continue;
      int verts[6];
      const int m = PairVertices(faces_, t, s, verts);
      for (int i = 0; i < m; ++i) {
        for (int j = 0; j < m; ++j) {
          if (verts[i] <= verts[j]) pattern.entries.emplace_back(verts[i], verts[j]);
        }
      }
    }
  }
  pattern.face_offsets[static_cast<size_t>(nf)] = pattern.entries.size();
  return pattern;
}

namespace {
// The pair's weight w = φ'(d)/d: H = w I majorises the potential's curvature in u (the IRLS model).
double PairWeight(const Potential& potential, const SqrtPotential* sqrt_potential, double e2,
                  const Eigen::Vector3d& u) {
  if (sqrt_potential != nullptr) return 1.0 / std::sqrt(u.squaredNorm() + e2);
  double value, weight;
  potential.EvaluateWeight(u.norm(), &value, &weight);
  return std::max(weight, 0.0);
}
}  // namespace

double SmoothingEnergy::PairEpsilonSquared(const SqrtPotential* sqrt_potential, int t, int s) const {
  if (sqrt_potential == nullptr) return 0.0;
  if (face_epsilon_squared_.empty()) return sqrt_potential->epsilon_squared();
  return 0.5 * (face_epsilon_squared_[static_cast<size_t>(t)] + face_epsilon_squared_[static_cast<size_t>(s)]);
}

void SmoothingEnergy::RayGaussNewton(const Eigen::VectorXd& x_vector, const std::vector<double>& rays,
                                     const RayPattern& pattern, std::vector<double>* values_out) const {
  const int nf = num_faces(), nv = num_vertices_;
  RB_CHECK(pattern.face_offsets.size() == static_cast<size_t>(nf) + 1, "RayGaussNewton: the pattern is of another mesh");
  const double* x = x_vector.data();
  ComputeNormals(x);
  // Per face and corner k: ∂n_t/∂t_v = P_t (e_k × r_v) / |c_t|, e_k = x_(k−1) − x_(k+1).
  std::vector<double> a(9 * static_cast<size_t>(nf), 0.0);
  tbb::parallel_for(tbb::blocked_range<int>(0, nf, kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int f = r.begin(); f != r.end(); ++f) {
      const double inv = inverse_length_[static_cast<size_t>(f)];
      if (inv == 0) continue;
      const Eigen::Vector3d n(&normals_[3 * static_cast<size_t>(f)]);
      for (int k = 0; k < 3; ++k) {
        const int v = faces_(f, k);
        const Eigen::Vector3d e = Position(x, faces_(f, (k + 2) % 3)) - Position(x, faces_(f, (k + 1) % 3));
        const Eigen::Vector3d ray(&rays[3 * static_cast<size_t>(v)]);
        const Eigen::Vector3d dc = e.cross(ray);
        const Eigen::Vector3d dn = (dc - n * n.dot(dc)) * inv;
        for (int j = 0; j < 3; ++j) a[9 * static_cast<size_t>(f) + 3 * k + j] = dn[j];
      }
    }
  });
  std::vector<double>& values = *values_out;
  values.resize(pattern.face_offsets.back());
  tbb::parallel_for(tbb::blocked_range<int>(0, nv, kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i != r.end(); ++i) {
      const Eigen::Vector3d ray(&rays[3 * static_cast<size_t>(i)]);
      values[static_cast<size_t>(i)] = 2 * ray.dot(InformationMatrix(i) * ray);
    }
  });
  const auto* sqrt_potential = dynamic_cast<const SqrtPotential*>(potential_);
  const double beta = prior_weight_;
  // Each face's pairs write their own run of values (pattern.face_offsets): parallel and in a fixed order.
  tbb::parallel_for(tbb::blocked_range<int>(0, nf, kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int t = r.begin(); t != r.end(); ++t) {
      size_t out = pattern.face_offsets[static_cast<size_t>(t)];
      for (int q = neighbour_offsets_[t]; q < neighbour_offsets_[t + 1]; ++q) {
        const int s = neighbours_[static_cast<size_t>(q)];
        if (s < t) continue;
        const Eigen::Vector3d u = Eigen::Vector3d(&normals_[3 * static_cast<size_t>(t)]) -
                                  Eigen::Vector3d(&normals_[3 * static_cast<size_t>(s)]);
        Eigen::Matrix3d hu;
        if (sqrt_potential != nullptr) {
          const double phi2 = u.squaredNorm() + PairEpsilonSquared(sqrt_potential, t, s), phi = std::sqrt(phi2);
          hu = (Eigen::Matrix3d::Identity() - u * u.transpose() / phi2) / phi;
        } else {
          double value, weight;
          potential_->EvaluateWeight(u.norm(), &value, &weight);
          hu = std::max(weight, 0.0) * Eigen::Matrix3d::Identity();
        }
        // Columns of J_u over the (up to 4) vertices of the pair.
        int verts[6];
        const int m = PairVertices(faces_, t, s, verts);
        Eigen::Vector3d cols[6];
        for (int i = 0; i < m; ++i) cols[i].setZero();
        for (int k = 0; k < 3; ++k) {
          for (int i = 0; i < m; ++i) {
            if (verts[i] == faces_(t, k)) cols[i] += Eigen::Vector3d(&a[9 * static_cast<size_t>(t) + 3 * k]);
            if (verts[i] == faces_(s, k)) cols[i] -= Eigen::Vector3d(&a[9 * static_cast<size_t>(s) + 3 * k]);
          }
        }
        for (int i = 0; i < m; ++i) {
          const Eigen::Vector3d hc = hu * cols[i];
          for (int j = 0; j < m; ++j) {
            if (verts[i] <= verts[j]) values[out++] = beta * hc.dot(cols[j]);
          }
        }
      }
    }
  });
}

void SmoothingEnergy::StiffVertices(const Eigen::VectorXd& x_vector, double relative_cut, std::vector<int>* vertices,
                                    std::vector<Eigen::Matrix3d>* blocks) const {
  const int nf = num_faces(), nv = num_vertices_;
  const double* x = x_vector.data();
  vertices->clear();
  blocks->clear();
  ComputeNormals(x);
  const auto* sqrt_potential = dynamic_cast<const SqrtPotential*>(potential_);
  // Per face: β w_t / |c_t|², w_t = Σ_s w_ts over its neighbours.
  std::vector<double> face_weight(static_cast<size_t>(nf), 0.0);
  tbb::parallel_for(tbb::blocked_range<int>(0, nf, kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int t = r.begin(); t != r.end(); ++t) {
      const double inv = inverse_length_[static_cast<size_t>(t)];
      if (inv == 0) continue;
      double w = 0;
      for (int q = neighbour_offsets_[t]; q < neighbour_offsets_[t + 1]; ++q) {
        const int s = neighbours_[static_cast<size_t>(q)];
        const Eigen::Vector3d u = Eigen::Vector3d(&normals_[3 * static_cast<size_t>(t)]) -
                                  Eigen::Vector3d(&normals_[3 * static_cast<size_t>(s)]);
        w += PairWeight(*potential_, sqrt_potential, PairEpsilonSquared(sqrt_potential, t, s), u);
      }
      face_weight[static_cast<size_t>(t)] = prior_weight_ * w * inv * inv;
    }
  });
  // The opposite edge of corner k of face t.
  auto edge = [&](int t, int k) {
    return Eigen::Vector3d(Position(x, faces_(t, (k + 2) % 3)) - Position(x, faces_(t, (k + 1) % 3)));
  };
  // Each block's trace: ‖P_t [e_k]_×‖²_F = |e_k|², e_k lying in t's plane.
  std::vector<double> trace(static_cast<size_t>(nv), 0.0);
  tbb::parallel_for(tbb::blocked_range<int>(0, nv, kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int i = r.begin(); i != r.end(); ++i) {
      for (int q = corner_offsets_[i]; q < corner_offsets_[i + 1]; ++q) {
        const int t = corners_[static_cast<size_t>(q)] / 3, k = corners_[static_cast<size_t>(q)] % 3;
        trace[static_cast<size_t>(i)] += face_weight[static_cast<size_t>(t)] * edge(t, k).squaredNorm();
      }
    }
  });
  std::vector<double> positive;
  positive.reserve(trace.size());
  for (double value : trace) {
    if (value > 0 && std::isfinite(value)) positive.push_back(value);
  }
  if (positive.empty()) return;
  const auto middle = positive.begin() + static_cast<std::ptrdiff_t>(positive.size() / 2);
  std::nth_element(positive.begin(), middle, positive.end());
  const double cut = relative_cut * *middle;
  for (int i = 0; i < nv; ++i) {
    if (!(trace[static_cast<size_t>(i)] > cut) || !std::isfinite(trace[static_cast<size_t>(i)])) continue;
    Eigen::Matrix3d block = Eigen::Matrix3d::Zero();
    for (int q = corner_offsets_[i]; q < corner_offsets_[i + 1]; ++q) {
      const int t = corners_[static_cast<size_t>(q)] / 3, k = corners_[static_cast<size_t>(q)] % 3;
      const Eigen::Vector3d n(&normals_[3 * static_cast<size_t>(t)]), e = edge(t, k);
      Eigen::Matrix3d cross;
      cross << 0, -e.z(), e.y(), e.z(), 0, -e.x(), -e.y(), e.x(), 0;
      const Eigen::Matrix3d a = (Eigen::Matrix3d::Identity() - n * n.transpose()) * cross;
      block += face_weight[static_cast<size_t>(t)] * a.transpose() * a;
    }
    vertices->push_back(i);
    blocks->push_back(block);
  }
}

double SmoothingEnergy::LowerBound() const {
  if (potential_ == nullptr) return 0.0;
  double lowest = 0.0;
  for (int k = 0; k <= 400; ++k) {
    double value = 0, derivative = 0;
    potential_->Evaluate(0.005 * k, &value, &derivative);
    lowest = std::min(lowest, value);
  }
  return prior_weight_ * num_pairs() * lowest;
}

double SmoothingEnergy::UniformDataInverseScale() const {
  if (!uniform_isotropic_ || information_.empty() || !(information_[0] > 0)) return 0.0;
  return 0.5 / information_[0];
}

double SmoothingEnergy::DataCurvature(const Eigen::VectorXd& p) const {
  return DeterministicSum(num_vertices_, [&](int i) {
    double w[6];
      Information(i, w);
    const double px = p[3 * i], py = p[3 * i + 1], pz = p[3 * i + 2];
    return 2 * (px * (w[0] * px + w[1] * py + w[2] * pz) + py * (w[1] * px + w[3] * py + w[4] * pz) +
                pz * (w[2] * px + w[4] * py + w[5] * pz));
  });
}

Normals SmoothingEnergy::FaceNormals(const Eigen::VectorXd& x) const {
  Normals normals = Normals::Zero(num_faces(), 3);
  tbb::parallel_for(tbb::blocked_range<int>(0, num_faces(), kGrain), [&](const tbb::blocked_range<int>& r) {
    for (int f = r.begin(); f != r.end(); ++f) {
      if (!active_[static_cast<size_t>(f)]) continue;
      const Eigen::Vector3d pa = Position(x.data(), faces_(f, 0));
      const Eigen::Vector3d c = (Position(x.data(), faces_(f, 1)) - pa).cross(Position(x.data(), faces_(f, 2)) - pa);
      const double length = c.norm();
      if (length > 0 && std::isfinite(length)) normals.row(f) = c.transpose() / length;
    }
  });
  return normals;
}

int SmoothingEnergy::CountFoldedFaces(const Eigen::VectorXd& x) const {
  const Normals normals = FaceNormals(x);
  return static_cast<int>(DeterministicSum(num_faces(), [&](int t) {
    if (neighbour_offsets_[t] == neighbour_offsets_[t + 1]) return 0.0;
    Eigen::RowVector3d sum = Eigen::RowVector3d::Zero();
    for (int q = neighbour_offsets_[t]; q < neighbour_offsets_[t + 1]; ++q) sum += normals.row(neighbours_[static_cast<size_t>(q)]);
    return normals.row(t).dot(sum) < 0 ? 1.0 : 0.0;
  }));
}

}  // namespace rangebayes
