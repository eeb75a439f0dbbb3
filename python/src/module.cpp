// The _rangebayes extension: rangebayes from Python (python/rangebayes/__init__.py re-exports it).
#include <pybind11/pybind11.h>

#include <exception>
#include <opencv2/core.hpp>

#include "core/error.h"
#include "python/src/bindings.h"

namespace rangebayes::python {

ProgressCallback PythonProgress(py::object function) {
  if (function.is_none()) return {};
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

}  // namespace rangebayes::python

PYBIND11_MODULE(_rangebayes, m) {
  namespace rp = rangebayes::python;
  m.doc() = "rangebayes: stereo range scanning to clean, compact meshes (C++ library bindings)";
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
}
