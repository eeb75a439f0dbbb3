// The parts of the _rangebayes extension, one function per layer (python/src/bind_*.cpp).
#pragma once

#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl/filesystem.h>

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "core/progress.h"
#include "python/src/library.h"
#include "python/src/options_table.h"

namespace rangebayes::python {

namespace py = pybind11;

// File and folder arguments: a str or any os.PathLike (pathlib.Path), through pybind11's std::filesystem caster.
using PathArg = std::filesystem::path;

void BindCore(py::module_& m);
void BindBayes(py::module_& m);
void BindStereo(py::module_& m);
void BindPipeline(py::module_& m);
void BindFusion(py::module_& m);
void BindCalibration(py::module_& m);

// A ProgressCallback that calls a Python function (fraction, stage) with the GIL held and then lets Python run
// its signal handlers, so Ctrl-C (KeyboardInterrupt) stops the call. None gives a callback that only does the
// latter (at most every 50 ms), or, with interruptible = false, an empty one (replay watches for signals on its
// own thread). Copies of the callback share one reference to the function, so copying it needs no GIL.
ProgressCallback PythonProgress(py::object function, bool interruptible = true);

// The smoothing prior given from Python as smooth(prior=...) and replay(smoothing={"prior": ...}) take it: 'sqrt',
// 'quadratic', 'cauchy', a learned-prior .yaml path or a LearnedPrior. A learned prior becomes
// options->potential (owned by *learned, which must outlive the call) and its β options->prior_weight unless
// beta_given (the rule of `rangebayes smooth --prior` / `replay --prior`). `what` names the call in errors.
void ApplySmoothingPrior(py::handle prior, bool beta_given, SmoothOptions* options,
                         std::unique_ptr<SplinePotential>* learned, const std::string& what);

// Each notice the CLI prints about an input (a recording's missing frames, a mesh's ignored normals) as a Python
// UserWarning "WHAT: notice" ("notice" when `what` is empty: the notice names its input already). Needs the GIL;
// a warning turned into an error (-W error) is raised.
void WarnNotices(const std::vector<std::string>& notices, const std::string& what);

// True for an os.PathLike (pathlib.Path); a str is not one.
bool IsPathLike(py::handle value);

// An Eigen member of a bound class as a property read as a copy and set from any array of its shape.
// def_readwrite returns a view into the object's buffer, which an assignment of another size (a VectorXd)
// frees under the view: an array read earlier then showed freed memory.
template <typename Class, typename Matrix, typename... Extra>
void EigenCopyField(py::class_<Class>& cls, const char* name, Matrix Class::*member, const Extra&... extra) {
  cls.def_property(
      name, [member](const Class& object) { return Matrix(object.*member); },
      [member](Class& object, const Matrix& value) { object.*member = value; }, extra...);
}

}  // namespace rangebayes::python
