// The _rangebayes extension: rangebayes from Python (python/rangebayes/__init__.py re-exports it).
#include <pybind11/pybind11.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <exception>
#include <memory>
#include <opencv2/core.hpp>

#include "core/allocator.h"
#include "core/error.h"
#include "python/src/bindings.h"

namespace rangebayes::python {

ProgressCallback PythonProgress(py::object function, bool interruptible) {
  if (function.is_none()) {
    if (!interruptible) return {};
    // No Python function: the callback only lets Ctrl-C stop the call. It takes the GIL at most every 50 ms.
    auto last = std::make_shared<std::atomic<std::int64_t>>(0);
    return [last](double, std::string_view) {
      const std::int64_t now = std::chrono::duration_cast<std::chrono::milliseconds>(
                                   std::chrono::steady_clock::now().time_since_epoch())
                                   .count();
      if (now - last->load() < 50) return;
      last->store(now);
      py::gil_scoped_acquire gil;
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
    };
  }
  if (!PyCallable_Check(function.ptr())) throw py::type_error("progress: expected a callable (fraction, stage)");
  std::shared_ptr<py::object> held(new py::object(std::move(function)), [](py::object* f) {
    py::gil_scoped_acquire gil;
    delete f;
  });
  return [held](double fraction, std::string_view stage) {
    py::gil_scoped_acquire gil;
    (*held)(fraction, py::str(stage.data(), stage.size()));
    // Ctrl-C during the call: KeyboardInterrupt (Python's handler runs here when this is the main thread).
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
  };
}

py::object PopKeyword(py::dict& kwargs, const char* name) {
  if (!kwargs.contains(name)) return py::none();
  py::object value = kwargs[name];
  PyDict_DelItemString(kwargs.ptr(), name);
  return value;
}

void WarnNotices(const std::vector<std::string>& notices, const std::string& what) {
  for (const std::string& notice : notices) {
    const std::string text = what.empty() ? notice : what + ": " + notice;
    if (PyErr_WarnEx(PyExc_UserWarning, text.c_str(), 1) < 0) throw py::error_already_set();
  }
}

bool IsPathLike(py::handle value) { return py::isinstance(value, py::module_::import("os").attr("PathLike")); }

}  // namespace rangebayes::python

PYBIND11_MODULE(_rangebayes, m) {
  namespace rp = rangebayes::python;
  m.doc() = "rangebayes: stereo range scanning to clean, compact meshes (C++ library bindings)";
  // The CLI's malloc settings (core/allocator.h): "applied", or "user tunables" when GLIBC_TUNABLES sets them.
  m.attr("_malloc") = rangebayes::ConfigureMallocForRepeatedBuffers() == rangebayes::MallocConfiguration::kApplied
                          ? "applied"
                          : "user tunables";
  // rangebayes.Error: every rangebayes::Error, same message; a subclass of RuntimeError.
  static pybind11::handle error = pybind11::register_exception<rangebayes::Error>(m, "Error", PyExc_RuntimeError);
  // OpenCV's own errors (from a stage the library hands an image to) are library errors too.
  pybind11::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const cv::Exception& e) {
      PyErr_SetString(error.ptr(), e.what());
    }
  });
  rp::BindCore(m);
  rp::BindBayes(m);
  rp::BindStereo(m);
  rp::BindPipeline(m);
  rp::BindFusion(m);
  rp::BindCalibration(m);
}
