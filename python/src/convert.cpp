#include "python/src/convert.h"

#include <sys/mman.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <system_error>
#include <thread>

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
  for (size_t i = 0; i < shape.size(); ++i) want += (i ? ", " : "") + (shape[i] < 0 ? std::string("n") : std::to_string(shape[i]));
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
// as numpy also asks for its own large arrays) turn ~500 page faults per MB into a few.
void AdviseHugePages(void* data, size_t bytes) {
  constexpr std::uintptr_t kHuge = std::uintptr_t{2} << 20;
  if (data == nullptr || bytes < 4 * kHuge) return;
  const std::uintptr_t begin = (reinterpret_cast<std::uintptr_t>(data) + kHuge - 1) & ~(kHuge - 1);
  const std::uintptr_t end = (reinterpret_cast<std::uintptr_t>(data) + bytes) & ~(kHuge - 1);
  if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
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

// One thread does not reach the memory bandwidth of a copy into fresh pages (the kernel zeroes each page in
// the thread that first touches it), so large copies are split into row ranges on a few threads.
constexpr size_t kBytesPerCopyThread = size_t{8} << 20;
constexpr unsigned kMaxCopyThreads = 4;

// Runs rows(begin, end), which returns the first bad row in [begin, end) or -1, over [0, n); returns the
// first bad row of all, or -1. Call without the GIL; rows must not throw.
template <typename Rows>
py::ssize_t ForRowRanges(py::ssize_t n, size_t bytes, const Rows& rows) {
  unsigned threads = static_cast<unsigned>(std::min<size_t>(bytes / kBytesPerCopyThread + 1, kMaxCopyThreads));
  threads = std::min(threads, std::max(1u, std::thread::hardware_concurrency()));
  if (threads <= 1 || n < static_cast<py::ssize_t>(threads)) return rows(0, n);
  std::vector<py::ssize_t> bad(threads, -1);
  auto range = [&](unsigned t) { bad[t] = rows(n * t / threads, n * (t + 1) / threads); };
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) {
    try {
      pool.emplace_back(range, t);
    } catch (const std::system_error&) {
      range(t);  // no thread to be had: this one does the range
    }
  }
  range(0);
  for (std::thread& thread : pool) thread.join();
  for (py::ssize_t b : bad) {
    if (b >= 0) return b;
  }
  return -1;
}

// Rows [b, e) of an (n, kCols) float64 array with byte strides (s0, s1) into row-major dst; returns the first
// row with a non-finite value, or -1.
template <int kCols>
py::ssize_t CopyDoubleRows(const char* src, py::ssize_t s0, py::ssize_t s1, double* dst, py::ssize_t b,
                           py::ssize_t e) {
  bool bad = false;
  if (s1 == sizeof(double) && s0 == kCols * static_cast<py::ssize_t>(sizeof(double))) {
    const char* in = src + b * s0;
    double* out = dst + b * kCols;
    const py::ssize_t count = (e - b) * kCols;
    for (py::ssize_t k = 0; k < count; ++k) {
      const double x = Load<double>(in + k * static_cast<py::ssize_t>(sizeof(double)));
      out[k] = x;
      bad |= NonFinite(x);
    }
  } else {
    for (py::ssize_t i = b; i < e; ++i) {
      for (int c = 0; c < kCols; ++c) {
        const double x = Load<double>(src + i * s0 + c * s1);
        dst[i * kCols + c] = x;
        bad |= NonFinite(x);
      }
    }
  }
  if (!bad) return -1;
  for (py::ssize_t i = b; i < e; ++i) {
    for (int c = 0; c < kCols; ++c) {
      if (NonFinite(dst[i * kCols + c])) return i;
    }
  }
  return -1;
}

// Element (r, c) of the 3×3 at `block` with byte strides (s1, s2), into column-major out.
inline bool CopyCovariance(const char* block, py::ssize_t s1, py::ssize_t s2, double* out) {
  bool bad = false;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      const double x = Load<double>(block + r * s1 + c * s2);
      out[3 * c + r] = x;
      bad |= NonFinite(x);
    }
  }
  return bad;
}

py::ssize_t CopyCovarianceRows(const char* src, py::ssize_t s0, py::ssize_t s1, py::ssize_t s2, double* dst,
                               py::ssize_t b, py::ssize_t e) {
  constexpr py::ssize_t d = sizeof(double);
  bool bad = false;
  if (s0 == 9 * d && s1 == 3 * d && s2 == d) {  // C order: constant strides, so the compiler unrolls
    for (py::ssize_t i = b; i < e; ++i) bad |= CopyCovariance(src + i * 9 * d, 3 * d, d, dst + 9 * i);
  } else {
    for (py::ssize_t i = b; i < e; ++i) bad |= CopyCovariance(src + i * s0, s1, s2, dst + 9 * i);
  }
  if (!bad) return -1;
  for (py::ssize_t i = b; i < e; ++i) {
    for (int k = 0; k < 9; ++k) {
      if (NonFinite(dst[9 * i + k])) return i;
    }
  }
  return -1;
}

// Rows [b, e) of an (m, 3) integer array of Int into row-major int faces; returns the first row with an index
// outside [lo, hi), or -1.
template <typename Int>
py::ssize_t CopyFaceRows(const char* src, py::ssize_t s0, py::ssize_t s1, int* dst, py::ssize_t b, py::ssize_t e,
                         long long lo, long long hi) {
  bool bad = false;
  for (py::ssize_t i = b; i < e; ++i) {
    for (int c = 0; c < 3; ++c) {
      const long long v = Load<Int>(src + i * s0 + c * s1);
      dst[3 * i + c] = static_cast<int>(v);
      bad |= (v < lo) | (v >= hi);
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

std::string RowText(const py::array& a, py::ssize_t row) {
  return py::str(a[py::int_(row)]).cast<std::string>();
}

}  // namespace

Vertices VerticesFromArray(py::handle obj, const std::string& what) {
  const py::array a = RealArray(obj, {-1, 3}, what);
  const py::ssize_t n = a.shape(0);
  Vertices V(n, 3);
  const size_t bytes = sizeof(double) * static_cast<size_t>(V.size());
  AdviseHugePages(V.data(), bytes);
  const char* src = static_cast<const char*>(a.data());
  const py::ssize_t s0 = a.strides(0), s1 = a.strides(1);
  double* dst = V.data();
  py::ssize_t bad;
  {
    py::gil_scoped_release nogil;
    bad = ForRowRanges(n, bytes, [&](py::ssize_t b, py::ssize_t e) { return CopyDoubleRows<3>(src, s0, s1, dst, b, e); });
  }
  if (bad >= 0) {
    throw py::value_error(what + ": row " + std::to_string(bad) + " is not finite: " + RowText(a, bad));
  }
  return V;
}

Faces FacesFromArray(py::handle obj, const std::string& what, Eigen::Index num_vertices) {
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
  Faces F(m, 3);
  const size_t bytes = sizeof(int) * static_cast<size_t>(F.size());
  AdviseHugePages(F.data(), bytes);
  const char* src = static_cast<const char*>(a.data());
  const py::ssize_t s0 = a.strides(0), s1 = a.strides(1);
  int* dst = F.data();
  py::ssize_t bad;
  {
    py::gil_scoped_release nogil;
    bad = ForRowRanges(m, bytes, [&](py::ssize_t b, py::ssize_t e) {
      return int32 ? CopyFaceRows<std::int32_t>(src, s0, s1, dst, b, e, lo, hi)
                   : CopyFaceRows<std::int64_t>(src, s0, s1, dst, b, e, lo, hi);
    });
  }
  if (bad >= 0) {
    const std::string row = what + ": row " + std::to_string(bad) + " " + RowText(a, bad);
    if (num_vertices >= 0) {
      throw py::value_error(row + " has an index outside [0, " + std::to_string(num_vertices) + ") (the mesh has " +
                            std::to_string(num_vertices) + " vertices)");
    }
    throw py::value_error(row + " has an index that does not fit in int32");
  }
  return F;
}

std::vector<Eigen::Matrix3d> CovariancesFromArray(py::handle obj, const std::string& what) {
  const py::array a = RealArray(obj, {-1, 3, 3}, what);
  const py::ssize_t n = a.shape(0);
  std::vector<Eigen::Matrix3d> out(static_cast<size_t>(n));  // Eigen leaves the elements uninitialised
  const size_t bytes = sizeof(Eigen::Matrix3d) * out.size();
  AdviseHugePages(out.data(), bytes);
  static_assert(sizeof(Eigen::Matrix3d) == 9 * sizeof(double), "the copy writes 9 doubles per vertex");
  const char* src = static_cast<const char*>(a.data());
  const py::ssize_t s0 = a.strides(0), s1 = a.strides(1), s2 = a.strides(2);
  double* dst = n > 0 ? out[0].data() : nullptr;
  py::ssize_t bad;
  {
    py::gil_scoped_release nogil;
    bad = ForRowRanges(n, bytes,
                       [&](py::ssize_t b, py::ssize_t e) { return CopyCovarianceRows(src, s0, s1, s2, dst, b, e); });
  }
  if (bad >= 0) {
    throw py::value_error(what + ": matrix " + std::to_string(bad) + " is not finite: " + RowText(a, bad));
  }
  return out;
}

Eigen::Matrix<float, Eigen::Dynamic, 2, Eigen::RowMajor> PixelsFromArray(py::handle obj, const std::string& what) {
  const py::array a = RealArray(obj, {-1, 2}, what);
  const py::ssize_t n = a.shape(0);
  Eigen::Matrix<double, Eigen::Dynamic, 2, Eigen::RowMajor> wide(n, 2);
  const py::ssize_t bad =
      CopyDoubleRows<2>(static_cast<const char*>(a.data()), a.strides(0), a.strides(1), wide.data(), 0, n);
  if (bad >= 0) throw py::value_error(what + ": row " + std::to_string(bad) + " is not finite: " + RowText(a, bad));
  return wide.cast<float>();
}

void CheckMeshForLibrary(const Mesh& mesh, const std::string& what) {
  const Eigen::Index n = mesh.V.rows();
  for (Eigen::Index i = 0; i < n; ++i) {
    if (!mesh.V.row(i).allFinite()) {
      throw py::value_error(what + ": vertex " + std::to_string(i) + " is not finite (written through a view?)");
    }
  }
  for (Eigen::Index f = 0; f < mesh.F.rows(); ++f) {
    for (int c = 0; c < 3; ++c) {
      const int v = mesh.F(f, c);
      if (v < 0 || v >= n) {
        throw py::value_error(what + ": face " + std::to_string(f) + " refers to vertex " + std::to_string(v) +
                              " of " + std::to_string(n));
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
  int depth = -1;
  if (a.dtype().is(py::dtype::of<std::uint8_t>())) depth = CV_8U;
  if (a.dtype().is(py::dtype::of<std::uint16_t>())) depth = CV_16U;
  if (a.dtype().is(py::dtype::of<float>())) depth = CV_32F;
  if (a.dtype().is(py::dtype::of<double>())) depth = CV_64F;
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
    case CV_8U: dtype = py::dtype::of<std::uint8_t>(); break;
    case CV_8S: dtype = py::dtype::of<std::int8_t>(); break;
    case CV_16U: dtype = py::dtype::of<std::uint16_t>(); break;
    case CV_16S: dtype = py::dtype::of<std::int16_t>(); break;
    case CV_32S: dtype = py::dtype::of<std::int32_t>(); break;
    case CV_32F: dtype = py::dtype::of<float>(); break;
    default: dtype = py::dtype::of<double>(); break;
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
