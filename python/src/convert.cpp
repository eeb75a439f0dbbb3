#include "python/src/convert.h"

#include <sys/mman.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>

namespace rangebayes::python {
namespace {

py::array CheckedArray(py::handle obj, const std::string& what) {
  if (!py::isinstance<py::array>(obj)) {
    try {
      return py::module_::import("numpy").attr("asarray")(obj).cast<py::array>();
    } catch (const py::error_already_set&) {
      throw py::type_error(what + ": expected an array, got " + py::str(py::type::of(obj)).cast<std::string>());
    }
  }
  return py::reinterpret_borrow<py::array>(obj);
}

void CheckShape(const py::array& a, const std::vector<py::ssize_t>& shape, const std::string& what) {
  bool ok = a.ndim() == static_cast<py::ssize_t>(shape.size());
  for (size_t i = 0; ok && i < shape.size(); ++i) ok = shape[i] < 0 || a.shape(static_cast<py::ssize_t>(i)) == shape[i];
  if (ok) return;
  std::string want = "(";
  for (size_t i = 0; i < shape.size(); ++i)
    want += (i ? ", " : "") + (shape[i] < 0 ? std::string("n") : std::to_string(shape[i]));
  want += ")";
  std::string got = "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) got += (i ? ", " : "") + std::to_string(a.shape(i));
  got += ")";
  throw py::value_error(what + ": expected an array of shape " + want + ", got " + got);
}

std::string DtypeName(const py::array& a) { return py::str(a.dtype()).cast<std::string>(); }

// An array of native T (any strides) as it is, another real dtype converted by numpy (a C-contiguous copy).
template <typename T>
py::array AsDtype(const py::array& a) {
  if (py::isinstance<py::array_t<T>>(a)) return a;
  return py::array_t<T, py::array::c_style | py::array::forcecast>::ensure(a);
}

py::array RealArray(py::handle obj, const std::vector<py::ssize_t>& shape, const std::string& what) {
  py::array a = CheckedArray(obj, what);
  const char k = a.dtype().kind();
  if (k != 'f' && k != 'i' && k != 'u') {
    throw py::type_error(what + ": expected a real-valued array, got dtype " + DtypeName(a));
  }
  CheckShape(a, shape, what);
  return AsDtype<double>(a);
}

// Large fresh buffers are filled once here; transparent huge pages (where the kernel offers them on request,
// as numpy also asks for its own large arrays) turn ~500 page faults per MB into a few. Only whole 2 MB blocks
// can be huge: the head and tail of the buffer (up to 2 MB each, malloc's blocks are not 2 MB aligned) stay
// small pages, and are populated in one call instead of one fault per 4 kB page (kernels without
// MADV_POPULATE_WRITE, before 5.14, refuse it and fault as before).
void PrepareFreshBuffer(void* data, size_t bytes) {
  constexpr std::uintptr_t kHuge = std::uintptr_t{2} << 20;
  constexpr std::uintptr_t kPage = 4096;
  if (data == nullptr || bytes < 4 * kHuge) return;
  const auto first = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t begin = (first + kHuge - 1) & ~(kHuge - 1);
  const std::uintptr_t end = (first + bytes) & ~(kHuge - 1);
  if (end <= begin) return;
  madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
#ifdef MADV_POPULATE_WRITE
  const std::uintptr_t head = first & ~(kPage - 1);
  const std::uintptr_t tail = (first + bytes + kPage - 1) & ~(kPage - 1);
  if (begin > head) madvise(reinterpret_cast<void*>(head), begin - head, MADV_POPULATE_WRITE);
  if (tail > end) madvise(reinterpret_cast<void*>(end), tail - end, MADV_POPULATE_WRITE);
#endif
}

// NaN and ±inf: all exponent bits set (an integer test, so the copy loops below stay branch-free).
inline bool NonFinite(double x) {
  std::uint64_t u;
  std::memcpy(&u, &x, sizeof u);
  return (u & 0x7ff0000000000000ULL) == 0x7ff0000000000000ULL;
}

template <typename T>
inline T Load(const char* p) {
  T x;
  std::memcpy(&x, p, sizeof x);  // numpy arrays need not be aligned
  return x;
}

// The row functions below copy rows [b, e) of a numpy array into row-major dst (kWrite) or only check them
// (!kWrite, dst unused), and return the first bad row in [b, e) or -1.

// (n, kCols) float64 with byte strides (s0, s1); bad: a non-finite value.
template <int kCols, bool kWrite>
py::ssize_t DoubleRows(const char* src, py::ssize_t s0, py::ssize_t s1, double* dst, py::ssize_t b, py::ssize_t e) {
  constexpr py::ssize_t d = sizeof(double);
  bool bad = false;
  if (s1 == d && s0 == kCols * d) {
    const char* in = src + b * s0;
    const py::ssize_t count = (e - b) * kCols;
    for (py::ssize_t k = 0; k < count; ++k) {
      const double x = Load<double>(in + k * d);
      if constexpr (kWrite) dst[b * kCols + k] = x;
      bad |= NonFinite(x);
    }
  } else {
    for (py::ssize_t i = b; i < e; ++i) {
      for (int c = 0; c < kCols; ++c) {
        const double x = Load<double>(src + i * s0 + c * s1);
        if constexpr (kWrite) dst[i * kCols + c] = x;
        bad |= NonFinite(x);
      }
    }
  }
  if (!bad) return -1;
  for (py::ssize_t i = b; i < e; ++i) {
    for (int c = 0; c < kCols; ++c) {
      if (NonFinite(Load<double>(src + i * s0 + c * s1))) return i;
    }
  }
  return -1;
}

// (n, 3, 3) float64 into column-major 3×3 blocks; bad: a non-finite value.
template <bool kWrite>
inline bool CovarianceBlock(const char* block, py::ssize_t s1, py::ssize_t s2, double* out) {
  bool bad = false;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      const double x = Load<double>(block + r * s1 + c * s2);
      if constexpr (kWrite) out[3 * c + r] = x;
      bad |= NonFinite(x);
    }
  }
  return bad;
}

template <bool kWrite>
py::ssize_t CovarianceRows(const char* src, py::ssize_t s0, py::ssize_t s1, py::ssize_t s2, double* dst, py::ssize_t b,
                           py::ssize_t e) {
  constexpr py::ssize_t d = sizeof(double);
  bool bad = false;
  if (s0 == 9 * d && s1 == 3 * d && s2 == d) {  // C order: constant strides, so the compiler unrolls
    for (py::ssize_t i = b; i < e; ++i) bad |= CovarianceBlock<kWrite>(src + i * 9 * d, 3 * d, d, dst + 9 * i);
  } else {
    for (py::ssize_t i = b; i < e; ++i) bad |= CovarianceBlock<kWrite>(src + i * s0, s1, s2, dst + 9 * i);
  }
  if (!bad) return -1;
  double block[9];
  for (py::ssize_t i = b; i < e; ++i) {
    if (CovarianceBlock<true>(src + i * s0, s1, s2, block)) return i;
  }
  return -1;
}

// (m, 3) integers of type Int; bad: an index outside [lo, hi).
template <typename Int, bool kWrite>
py::ssize_t FaceRows(const char* src, py::ssize_t s0, py::ssize_t s1, int* dst, py::ssize_t b, py::ssize_t e,
                     long long lo, long long hi) {
  constexpr py::ssize_t w = sizeof(Int);
  bool bad = false;
  if (std::is_same_v<Int, std::int32_t> && s1 == w && s0 == 3 * w && lo == 0 &&
      hi <= std::numeric_limits<std::int32_t>::max()) {
    // C-order int32 with the bounds [0, n): one unsigned 32-bit compare, which the compiler vectorises.
    const auto limit = static_cast<std::uint32_t>(hi);
    const char* in = src + b * s0;
    const py::ssize_t count = (e - b) * 3;
    std::uint32_t outside = 0;
    for (py::ssize_t k = 0; k < count; ++k) {
      const auto v = static_cast<std::int32_t>(Load<Int>(in + w * k));
      if constexpr (kWrite) dst[3 * b + k] = v;
      outside |= static_cast<std::uint32_t>(static_cast<std::uint32_t>(v) >= limit);
    }
    bad = outside != 0;
  } else {
    for (py::ssize_t i = b; i < e; ++i) {
      for (int c = 0; c < 3; ++c) {
        const long long v = Load<Int>(src + i * s0 + c * s1);
        if constexpr (kWrite) dst[3 * i + c] = static_cast<int>(v);
        bad |= (v < lo) | (v >= hi);
      }
    }
  }
  if (!bad) return -1;
  for (py::ssize_t i = b; i < e; ++i) {
    for (int c = 0; c < 3; ++c) {
      const long long v = Load<Int>(src + i * s0 + c * s1);
      if (v < lo || v >= hi) return i;
    }
  }
  return -1;
}

std::string RowText(const py::array& a, py::ssize_t row) { return py::str(a[py::int_(row)]).cast<std::string>(); }

// Whether the array's elements may lie in [dst, dst + bytes) (the source is a view of the destination).
bool MayOverlap(const py::array& a, const void* dst, size_t bytes) {
  if (a.size() == 0 || bytes == 0) return false;
  auto lo = reinterpret_cast<std::intptr_t>(a.data());
  std::intptr_t hi = lo + static_cast<std::intptr_t>(a.itemsize());
  for (py::ssize_t k = 0; k < a.ndim(); ++k) {
    const std::intptr_t span = static_cast<std::intptr_t>(a.strides(k)) * (a.shape(k) - 1);
    (span < 0 ? lo : hi) += span;
  }
  const auto d = reinterpret_cast<std::intptr_t>(dst);
  return lo < d + static_cast<std::intptr_t>(bytes) && d < hi;
}

// Fills n rows of `out` with rows(write, out, b, e) without the GIL. With check_first (filling storage that
// holds values already), a first pass checks every row, so a bad value leaves the storage untouched.
// Returns the first bad row or -1.
// One thread: a second one (tried, 2 cores under load) added CPU time and no wall time (BENCHMARKS.md).
template <typename T, typename Rows>
py::ssize_t Fill(py::ssize_t n, T* out, bool check_first, const Rows& rows) {
  py::gil_scoped_release nogil;
  if (check_first) {
    const py::ssize_t bad = rows(std::false_type{}, out, 0, n);
    if (bad >= 0) return bad;
  }
  return rows(std::true_type{}, out, 0, n);
}

// How an array of n rows is copied into storage that has `rows` rows at `data`. Storage that holds values
// never changes its size from Python (numpy views of it would point into freed memory): another non-empty
// size is a ValueError. Same size: in place, through a temporary when the array is a view of the storage.
struct Placement {
  bool in_place;       // into the existing storage
  bool through_fresh;  // via fresh storage (a new size, or a source overlapping the existing storage)
};
Placement Place(const py::array& a, py::ssize_t n, py::ssize_t rows, const void* data, size_t bytes,
                const std::string& what) {
  if (rows != 0 && rows != n) {
    throw py::value_error(what + ": the storage has " + std::to_string(rows) + " rows, the array " + std::to_string(n) +
                          "; assign one with as many rows (views of the storage stay valid) " + "or build a new mesh");
  }
  Placement p;
  p.in_place = n > 0 && rows == n;
  p.through_fresh = !p.in_place || MayOverlap(a, data, bytes);
  return p;
}

}  // namespace

void AssignVertices(py::handle obj, const std::string& what, Vertices* V) {
  const py::array a = RealArray(obj, {-1, 3}, what);
  const py::ssize_t n = a.shape(0);
  const size_t bytes = sizeof(double) * 3 * static_cast<size_t>(n);
  const Placement place = Place(a, n, V->rows(), V->data(), bytes, what);
  Vertices fresh(place.through_fresh ? n : 0, 3);
  PrepareFreshBuffer(fresh.data(), bytes);
  const char* src = static_cast<const char*>(a.data());
  const py::ssize_t s0 = a.strides(0), s1 = a.strides(1);
  const py::ssize_t bad = Fill(n, place.through_fresh ? fresh.data() : V->data(), !place.through_fresh,
                               [&](auto write, double* out, py::ssize_t b, py::ssize_t e) {
                                 return DoubleRows<3, decltype(write)::value>(src, s0, s1, out, b, e);
                               });
  if (bad >= 0) throw py::value_error(what + ": row " + std::to_string(bad) + " is not finite: " + RowText(a, bad));
  if (place.in_place && place.through_fresh) std::memcpy(V->data(), fresh.data(), bytes);
  if (!place.in_place) *V = std::move(fresh);
}

void AssignFaces(py::handle obj, const std::string& what, Eigen::Index num_vertices, Faces* F) {
  py::array a = CheckedArray(obj, what);
  const char k = a.dtype().kind();
  if (k != 'i' && k != 'u') throw py::type_error(what + ": expected an integer array, got dtype " + DtypeName(a));
  CheckShape(a, {-1, 3}, what);
  const bool int32 = py::isinstance<py::array_t<std::int32_t>>(a);
  if (!int32) a = AsDtype<std::int64_t>(a);
  const long long lo = num_vertices >= 0 ? 0 : std::numeric_limits<int>::min();
  const long long hi = num_vertices >= 0 ? static_cast<long long>(num_vertices)
                                         : static_cast<long long>(std::numeric_limits<int>::max()) + 1;
  const py::ssize_t m = a.shape(0);
  const size_t bytes = sizeof(int) * 3 * static_cast<size_t>(m);
  const Placement place = Place(a, m, F->rows(), F->data(), bytes, what);
  Faces fresh(place.through_fresh ? m : 0, 3);
  PrepareFreshBuffer(fresh.data(), bytes);
  const char* src = static_cast<const char*>(a.data());
  const py::ssize_t s0 = a.strides(0), s1 = a.strides(1);
  const py::ssize_t bad = Fill(m, place.through_fresh ? fresh.data() : F->data(), !place.through_fresh,
                               [&](auto write, int* out, py::ssize_t b, py::ssize_t e) {
                                 constexpr bool kWrite = decltype(write)::value;
                                 return int32 ? FaceRows<std::int32_t, kWrite>(src, s0, s1, out, b, e, lo, hi)
                                              : FaceRows<std::int64_t, kWrite>(src, s0, s1, out, b, e, lo, hi);
                               });
  if (bad >= 0) {
    const std::string row = what + ": row " + std::to_string(bad) + " " + RowText(a, bad);
    if (num_vertices >= 0) {
      throw py::value_error(row + " has an index outside [0, " + std::to_string(num_vertices) + ") (the mesh has " +
                            std::to_string(num_vertices) + " vertices)");
    }
    throw py::value_error(row + " has an index that does not fit in int32");
  }
  if (place.in_place && place.through_fresh) std::memcpy(F->data(), fresh.data(), bytes);
  if (!place.in_place) *F = std::move(fresh);
}

void AssignCovariances(py::handle obj, const std::string& what, std::vector<Eigen::Matrix3d>* covariance) {
  static_assert(sizeof(Eigen::Matrix3d) == 9 * sizeof(double), "the copy writes 9 doubles per vertex");
  const py::array a = RealArray(obj, {-1, 3, 3}, what);
  const py::ssize_t n = a.shape(0);
  const size_t bytes = sizeof(Eigen::Matrix3d) * static_cast<size_t>(n);
  const Placement place = Place(a, n, static_cast<py::ssize_t>(covariance->size()), covariance->data(), bytes, what);
  // Eigen leaves the elements uninitialised, so the pages are first touched by the copy.
  std::vector<Eigen::Matrix3d> fresh(place.through_fresh ? static_cast<size_t>(n) : 0);
  PrepareFreshBuffer(fresh.data(), bytes);
  const char* src = static_cast<const char*>(a.data());
  const py::ssize_t s0 = a.strides(0), s1 = a.strides(1), s2 = a.strides(2);
  double* out = place.through_fresh ? (fresh.empty() ? nullptr : fresh[0].data()) : (*covariance)[0].data();
  const py::ssize_t bad = Fill(n, out, !place.through_fresh, [&](auto write, double* o, py::ssize_t b, py::ssize_t e) {
    return CovarianceRows<decltype(write)::value>(src, s0, s1, s2, o, b, e);
  });
  if (bad >= 0) {
    throw py::value_error(what + ": matrix " + std::to_string(bad) + " is not finite: " + RowText(a, bad));
  }
  if (place.in_place && place.through_fresh) std::memcpy((*covariance)[0].data(), fresh[0].data(), bytes);
  if (!place.in_place) *covariance = std::move(fresh);
}

Vertices VerticesFromArray(py::handle obj, const std::string& what) {
  Vertices V(0, 3);
  AssignVertices(obj, what, &V);
  return V;
}

Faces FacesFromArray(py::handle obj, const std::string& what, Eigen::Index num_vertices) {
  Faces F(0, 3);
  AssignFaces(obj, what, num_vertices, &F);
  return F;
}

std::vector<Eigen::Matrix3d> CovariancesFromArray(py::handle obj, const std::string& what) {
  std::vector<Eigen::Matrix3d> covariance;
  AssignCovariances(obj, what, &covariance);
  return covariance;
}

Eigen::Matrix<float, Eigen::Dynamic, 2, Eigen::RowMajor> PixelsFromArray(py::handle obj, const std::string& what) {
  const py::array a = RealArray(obj, {-1, 2}, what);
  const py::ssize_t n = a.shape(0);
  Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> wide(n, 2);
  const py::ssize_t bad =
      DoubleRows<2, true>(static_cast<const char*>(a.data()), a.strides(0), a.strides(1), wide.data(), 0, n);
  if (bad >= 0) throw py::value_error(what + ": row " + std::to_string(bad) + " is not finite: " + RowText(a, bad));
  return wide.cast<float>();
}

void CheckMeshForLibrary(const Mesh& mesh, const std::string& what) {
  const Eigen::Index n = mesh.V.rows();
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!mesh.V.row(i).allFinite()) {
      throw py::value_error(what + ": vertex " + std::to_string(i) +
                            " is not finite (in the file read, or written through a view)");
    }
  }
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const int v = mesh.F(f, c);
      if (v < 0 || v >= n) {
        throw py::value_error(what + ": face " + std::to_string(f) + " refers to vertex " + std::to_string(v) + " of " +
                              std::to_string(n));
      }
    }
  }
  if (mesh.N.rows() != 0 && mesh.N.rows() != n) {
    throw py::value_error(what + ": the mesh has " + std::to_string(mesh.N.rows()) + " normals for " +
                          std::to_string(n) + " vertices");
  }
}

void CheckNoisyMeshForLibrary(const NoisyMesh& noisy, const std::string& what) {
  CheckMeshForLibrary(noisy.mesh, what);
  const auto n = static_cast<size_t>(noisy.mesh.V.rows());
  if (!noisy.covariance.empty() && noisy.covariance.size() != n) {
    throw py::value_error(what + ": the mesh has " + std::to_string(noisy.covariance.size()) + " covariances for " +
                          std::to_string(n) + " vertices");
  }
  if (noisy.pixel.rows() != 0 && static_cast<size_t>(noisy.pixel.rows()) != n) {
    throw py::value_error(what + ": the mesh has " + std::to_string(noisy.pixel.rows()) + " pixel positions for " +
                          std::to_string(n) + " vertices");
  }
  for (size_t i = 0; i < noisy.covariance.size(); ++i) {
    if (!noisy.covariance[i].allFinite()) {
      throw py::value_error(what + ": the covariance of vertex " + std::to_string(i) + " is not finite");
    }
  }
}

NoisyMesh ToNoisyMesh(py::handle mesh, const char* what) {
  NoisyMesh noisy;
  if (py::isinstance<NoisyMesh>(mesh)) {
    noisy = mesh.cast<NoisyMesh>();
  } else if (py::isinstance<Mesh>(mesh)) {
    noisy.mesh = mesh.cast<Mesh>();
  } else {
    throw py::type_error(std::string(what) + ": expected a Mesh or NoisyMesh, got " +
                         py::str(py::type::of(mesh)).cast<std::string>());
  }
  CheckNoisyMeshForLibrary(noisy, what);
  return noisy;
}

Mesh ToMesh(py::handle mesh, const char* what) {
  Mesh out;
  if (py::isinstance<Mesh>(mesh)) {
    out = mesh.cast<Mesh>();
  } else if (py::isinstance<NoisyMesh>(mesh)) {
    out = mesh.cast<const NoisyMesh&>().mesh;
  } else {
    throw py::type_error(std::string(what) + ": expected a Mesh or NoisyMesh, got " +
                         py::str(py::type::of(mesh)).cast<std::string>());
  }
  CheckMeshForLibrary(out, what);
  return out;
}

py::array VerticesView(Vertices& V, py::handle owner) {
  return py::array_t<double>({V.rows(), Eigen::Index{3}}, {3 * sizeof(double), sizeof(double)}, V.data(), owner);
}

py::array FacesView(Faces& F, py::handle owner) {
  return py::array_t<int>({F.rows(), Eigen::Index{3}}, {3 * sizeof(int), sizeof(int)}, F.data(), owner);
}

py::array CovariancesView(std::vector<Eigen::Matrix3d>& covariance, py::handle owner) {
  const auto n = static_cast<py::ssize_t>(covariance.size());
  const py::ssize_t d = sizeof(double);
  return py::array_t<double>({n, py::ssize_t{3}, py::ssize_t{3}}, {9 * d, d, 3 * d},
                             n > 0 ? covariance[0].data() : nullptr, owner);
}

py::array PixelsView(Eigen::Matrix<float, Eigen::Dynamic, 2, Eigen::RowMajor>& pixel, py::handle owner) {
  return py::array_t<float>({pixel.rows(), Eigen::Index{2}}, {2 * sizeof(float), sizeof(float)}, pixel.data(), owner);
}

ImageIn ImageFromArray(py::handle obj, const std::string& what) {
  py::array a = CheckedArray(obj, what);
  if (a.ndim() != 2 && a.ndim() != 3) {
    throw py::value_error(what + ": expected an image of shape (h, w) or (h, w, channels)");
  }
  const int channels = a.ndim() == 3 ? static_cast<int>(a.shape(2)) : 1;
  if (channels < 1 || channels > 4) throw py::value_error(what + ": expected 1 to 4 channels");
  // By numpy's equality, not identity: an array that came through pickle (multiprocessing) carries its own
  // instance of the dtype, and one of the other byte order is another dtype.
  const auto is = [&](const py::dtype& dtype) { return a.dtype().attr("__eq__")(dtype).cast<bool>(); };
  int depth = -1;
  if (is(py::dtype::of<std::uint8_t>())) depth = CV_8U;
  if (is(py::dtype::of<std::uint16_t>())) depth = CV_16U;
  if (is(py::dtype::of<float>())) depth = CV_32F;
  if (is(py::dtype::of<double>())) depth = CV_64F;
  if (depth < 0) {
    throw py::type_error(what + ": expected dtype uint8, uint16, float32 or float64, got " +
                         py::str(a.dtype()).cast<std::string>());
  }
  if (!(a.flags() & py::array::c_style)) {
    a = py::module_::import("numpy").attr("ascontiguousarray")(a).cast<py::array>();
  }
  ImageIn in;
  in.keep = a;
  in.mat = cv::Mat(static_cast<int>(a.shape(0)), static_cast<int>(a.shape(1)), CV_MAKETYPE(depth, channels),
                   const_cast<void*>(a.data()));
  return in;
}

py::object ArrayFromMat(const cv::Mat& mat) {
  if (mat.empty()) return py::none();
  auto* held = new cv::Mat(mat);  // shares the buffer (reference counted)
  py::capsule owner(held, [](void* p) { delete static_cast<cv::Mat*>(p); });
  py::dtype dtype;
  switch (mat.depth()) {
    case CV_8U:
      dtype = py::dtype::of<std::uint8_t>();
      break;
    case CV_8S:
      dtype = py::dtype::of<std::int8_t>();
      break;
    case CV_16U:
      dtype = py::dtype::of<std::uint16_t>();
      break;
    case CV_16S:
      dtype = py::dtype::of<std::int16_t>();
      break;
    case CV_32S:
      dtype = py::dtype::of<std::int32_t>();
      break;
    case CV_32F:
      dtype = py::dtype::of<float>();
      break;
    default:
      dtype = py::dtype::of<double>();
      break;
  }
  const auto elem = static_cast<py::ssize_t>(mat.elemSize1());
  std::vector<py::ssize_t> shape = {mat.rows, mat.cols};
  std::vector<py::ssize_t> strides = {static_cast<py::ssize_t>(mat.step[0]), static_cast<py::ssize_t>(mat.step[1])};
  if (mat.channels() > 1) {
    shape.push_back(mat.channels());
    strides.push_back(elem);
  }
  return py::array(dtype, shape, strides, mat.data, owner);
}

}  // namespace rangebayes::python
