#include "python/src/convert.h"

#include <sys/mman.h>

#include <cstdint>
#include <cstring>
#include <limits>

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

// Large fresh buffers are filled once here; transparent huge pages (where the kernel offers them on request,
// as numpy also asks for its own large arrays) turn ~500 page faults per MB into a few.
void AdviseHugePages(void* data, size_t bytes) {
  constexpr std::uintptr_t kHuge = std::uintptr_t{2} << 20;
  if (data == nullptr || bytes < 4 * kHuge) return;
  const std::uintptr_t begin = (reinterpret_cast<std::uintptr_t>(data) + kHuge - 1) & ~(kHuge - 1);
  const std::uintptr_t end = (reinterpret_cast<std::uintptr_t>(data) + bytes) & ~(kHuge - 1);
  if (end > begin) madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
}

char Kind(const py::array& a) { return a.dtype().kind(); }

void CheckReal(const py::array& a, const std::string& what) {
  const char k = Kind(a);
  if (k != 'f' && k != 'i' && k != 'u') {
    throw py::type_error(what + ": expected a real-valued array, got dtype " + py::str(a.dtype()).cast<std::string>());
  }
}

}  // namespace

Vertices VerticesFromArray(py::handle obj, const std::string& what) {
  py::array a = CheckedArray(obj, what);
  CheckShape(a, {-1, 3}, what);
  CheckReal(a, what);
  auto c = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  Vertices V(c.shape(0), 3);
  AdviseHugePages(V.data(), sizeof(double) * static_cast<size_t>(V.size()));
  if (V.size() > 0) std::memcpy(V.data(), c.data(), sizeof(double) * static_cast<size_t>(V.size()));
  return V;
}

Faces FacesFromArray(py::handle obj, const std::string& what) {
  py::array a = CheckedArray(obj, what);
  CheckShape(a, {-1, 3}, what);
  const char k = Kind(a);
  if (k != 'i' && k != 'u') {
    throw py::type_error(what + ": expected an integer array, got dtype " + py::str(a.dtype()).cast<std::string>());
  }
  Faces F(a.shape(0), 3);
  AdviseHugePages(F.data(), sizeof(int) * static_cast<size_t>(F.size()));
  if (a.dtype().is(py::dtype::of<int>())) {
    auto c = py::array_t<int, py::array::c_style>::ensure(a);
    if (F.size() > 0) std::memcpy(F.data(), c.data(), sizeof(int) * static_cast<size_t>(F.size()));
    return F;
  }
  auto c = py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(a);
  const long long* p = c.data();
  for (Eigen::Index i = 0; i < F.size(); ++i) {
    if (p[i] < std::numeric_limits<int>::min() || p[i] > std::numeric_limits<int>::max()) {
      throw py::value_error(what + ": index " + std::to_string(p[i]) + " does not fit in int32");
    }
    F.data()[i] = static_cast<int>(p[i]);
  }
  return F;
}

std::vector<Eigen::Matrix3d> CovariancesFromArray(py::handle obj, const std::string& what) {
  py::array a = CheckedArray(obj, what);
  CheckShape(a, {-1, 3, 3}, what);
  CheckReal(a, what);
  auto c = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(a);
  std::vector<Eigen::Matrix3d> out(static_cast<size_t>(c.shape(0)));
  AdviseHugePages(out.data(), sizeof(Eigen::Matrix3d) * out.size());
  const double* p = c.data();
  for (size_t i = 0; i < out.size(); ++i) out[i] = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(p + 9 * i);
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
