// The parts of the _rangebayes extension, one function per layer (python/src/bind_*.cpp).
#pragma once

#include <pybind11/eigen.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl/filesystem.h>

#include <algorithm>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
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

// A bound class whose fields pickle (multiprocessing, copy.deepcopy): each field is bound and added to the pickled
// state by one call, so a field bound is a field pickled. The state is a dict by field name (and the instance's
// __dict__ for classes with py::dynamic_attr); a state with other names (another version of the module) is
// refused naming them. Call Pickle() once all fields are added.
template <typename Class>
class PickledFields {
 public:
  explicit PickledFields(py::class_<Class>& cls) : cls_(cls) {}

  template <typename Member, typename... Extra>
  PickledFields& ReadOnly(const char* name, Member Class::*member, const Extra&... extra) {
    cls_.def_readonly(name, member, extra...);
    return State(name, member);
  }
  template <typename Member, typename... Extra>
  PickledFields& ReadWrite(const char* name, Member Class::*member, const Extra&... extra) {
    cls_.def_readwrite(name, member, extra...);
    return State(name, member);
  }
  // An Eigen member read as a copy (EigenCopyField).
  template <typename Matrix, typename... Extra>
  PickledFields& EigenCopy(const char* name, Matrix Class::*member, const Extra&... extra) {
    EigenCopyField(cls_, name, member, extra...);
    return State(name, member);
  }
  // A property with a getter and a setter of one value type, pickled through them.
  template <typename Get, typename Set, typename... Extra>
  PickledFields& Property(const char* name, Get get, Set set, const Extra&... extra) {
    using Value = std::decay_t<decltype(get(std::declval<const Class&>()))>;
    cls_.def_property(name, get, set, extra...);
    return State(
        name, [get](const Class& object) { return py::cast(get(object)); },
        [set](Class& object, py::handle value) { set(object, value.cast<Value>()); });
  }
  // A member pickled as it is, under `name`, without a property (one whose property converts it).
  template <typename Member>
  PickledFields& State(const char* name, Member Class::*member) {
    return State(
        name, [member](const Class& object) { return py::cast(object.*member); },
        [member](Class& object, py::handle value) { object.*member = value.cast<Member>(); });
  }
  // State that no single member holds: `get` gives it as a Python object, `set` puts it back.
  PickledFields& State(const char* name, std::function<py::object(const Class&)> get,
                       std::function<void(Class&, py::handle)> set) {
    fields_->push_back({name, std::move(get), std::move(set)});
    return *this;
  }

  void Pickle() {
    const std::shared_ptr<const std::vector<Field>> fields = fields_;
    const std::string type_name = py::str(cls_.attr("__name__")).cast<std::string>();
    cls_.def(py::pickle(
        [fields](py::object self) {
          const Class& object = self.cast<const Class&>();
          py::dict state;
          for (const Field& f : *fields) state[py::str(f.name)] = f.get(object);
          py::dict attributes;
          if (py::hasattr(self, "__dict__")) attributes = self.attr("__dict__");
          return py::make_tuple(state, attributes);
        },
        [fields, type_name](const py::tuple& saved) {
          if (saved.size() != 2 || !py::isinstance<py::dict>(saved[0]) || !py::isinstance<py::dict>(saved[1])) {
            throw py::value_error("cannot unpickle " + type_name + ": not a state this module wrote");
          }
          const py::dict state = saved[0].cast<py::dict>();
          std::string missing, unknown;
          for (const Field& f : *fields) {
            if (!state.contains(f.name)) missing += (missing.empty() ? "" : ", ") + f.name;
          }
          for (const auto& item : state) {
            const std::string key = py::str(item.first).cast<std::string>();
            const bool known =
                std::any_of(fields->begin(), fields->end(), [&](const Field& f) { return f.name == key; });
            if (!known) unknown += (unknown.empty() ? "" : ", ") + key;
          }
          if (!missing.empty() || !unknown.empty()) {
            throw py::value_error("cannot unpickle " + type_name + " (pickled by another version of rangebayes?):" +
                                  (missing.empty() ? "" : " missing " + missing) +
                                  (unknown.empty() ? "" : " unknown " + unknown));
          }
          Class object{};
          for (const Field& f : *fields) f.set(object, state[py::str(f.name)]);
          return std::make_pair(std::move(object), saved[1].cast<py::dict>());
        }));
  }

 private:
  struct Field {
    std::string name;
    std::function<py::object(const Class&)> get;
    std::function<void(Class&, py::handle)> set;
  };
  py::class_<Class>& cls_;
  std::shared_ptr<std::vector<Field>> fields_ = std::make_shared<std::vector<Field>>();
};

}  // namespace rangebayes::python
