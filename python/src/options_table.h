// Options structs as Python keywords: one table of fields per struct, from which the keyword setter, the
// validation of unknown keywords and the dict of defaults are all derived.
#pragma once

#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <functional>
#include <limits>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace rangebayes::python {

namespace py = pybind11;

// Names of the values of an enum, as Python strings (specialised with RB_PY_ENUM_NAMES).
template <typename T>
struct EnumNames;

#define RB_PY_ENUM_NAMES(Enum, ...)                                              \
  template <>                                                                     \
  struct EnumNames<Enum> {                                                        \
    static const std::vector<std::pair<const char*, Enum>>& Values() {            \
      static const std::vector<std::pair<const char*, Enum>> values = __VA_ARGS__; \
      return values;                                                              \
    }                                                                             \
  }

template <typename T>
std::string EnumChoices() {
  std::string out;
  for (const auto& [name, value] : EnumNames<T>::Values()) out += (out.empty() ? "'" : ", '") + std::string(name) + "'";
  return out;
}

// Python value -> field value. Strict: a float is no int, an int no bool, a string names an enum value.
template <typename T>
T FieldFromPython(py::handle value, const std::string& name) {
  if constexpr (std::is_enum_v<T>) {
    if (py::isinstance<py::str>(value)) {
      const std::string s = py::cast<std::string>(value);
      for (const auto& [n, v] : EnumNames<T>::Values()) {
        if (s == n) return v;
      }
      throw py::value_error(name + ": '" + s + "' is not one of " + EnumChoices<T>());
    }
    throw py::type_error(name + ": expected a string, one of " + EnumChoices<T>());
  } else if constexpr (std::is_same_v<T, bool>) {
    if (py::isinstance<py::bool_>(value) || py::str(py::type::of(value).attr("__name__")).cast<std::string>() == "bool_") {
      return py::cast<bool>(value);
    }
    throw py::type_error(name + ": expected a bool");
  } else if constexpr (std::is_integral_v<T>) {
    if (py::isinstance<py::bool_>(value) || !py::hasattr(value, "__index__")) {
      throw py::type_error(name + ": expected an int");
    }
    const py::object index = py::reinterpret_steal<py::object>(PyNumber_Index(value.ptr()));
    if (!index) throw py::error_already_set();
    // Checked here: pybind11's own failure says only "Unable to cast Python instance to C++ type".
    const auto big = py::cast<py::int_>(index);
    if (big < py::int_(std::numeric_limits<T>::min()) || big > py::int_(std::numeric_limits<T>::max())) {
      throw py::value_error(name + ": " + py::str(index).cast<std::string>() + " is out of range [" +
                            std::to_string(std::numeric_limits<T>::min()) + ", " +
                            std::to_string(std::numeric_limits<T>::max()) + "]");
    }
    return py::cast<T>(index);
  } else if constexpr (std::is_floating_point_v<T>) {
    if (py::isinstance<py::bool_>(value) || PyNumber_Check(value.ptr()) == 0 || py::isinstance<py::str>(value)) {
      throw py::type_error(name + ": expected a number");
    }
    return py::cast<T>(py::float_(py::reinterpret_borrow<py::object>(value)));
  } else {
    try {
      return py::cast<T>(value);
    } catch (const py::cast_error&) {
      throw py::type_error(name + ": cannot convert " + py::str(py::type::of(value)).cast<std::string>());
    }
  }
}

template <typename T>
py::object FieldToPython(const T& value) {
  if constexpr (std::is_enum_v<T>) {
    for (const auto& [n, v] : EnumNames<T>::Values()) {
      if (v == value) return py::str(n);
    }
    return py::none();
  } else {
    return py::cast(value);
  }
}

template <typename Options>
struct Field {
  std::string name;
  std::function<void(Options&, py::handle)> set;
  std::function<py::object(const Options&)> get;
};

template <typename Options, typename T>
Field<Options> MakeField(const char* name, T Options::*member) {
  return {name, [name, member](Options& o, py::handle v) { o.*member = FieldFromPython<T>(v, name); },
          [member](const Options& o) { return FieldToPython(o.*member); }};
}

template <typename Options>
using FieldTable = std::vector<Field<Options>>;

// RB_PY_FIELD(SmoothOptions, max_iterations) -> a table row named "max_iterations".
#define RB_PY_FIELD(Options, member) ::rangebayes::python::MakeField<Options>(#member, &Options::member)

template <typename Options>
std::string FieldNames(const FieldTable<Options>& table) {
  std::string out;
  for (const auto& f : table) out += (out.empty() ? "" : ", ") + f.name;
  return out;
}

template <typename Options>
const Field<Options>* FindField(const FieldTable<Options>& table, const std::string& name) {
  for (const auto& f : table) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

// Sets every keyword of `kwargs` on `options`; TypeError naming the valid keywords for an unknown one.
// `what` names the call in messages ("smooth").
template <typename Options>
void ApplyKeywords(const FieldTable<Options>& table, const py::dict& kwargs, Options* options, const std::string& what,
                   const std::string& extra_names = "") {
  for (const auto& [key, value] : kwargs) {
    const std::string name = py::cast<std::string>(key);
    const Field<Options>* f = FindField(table, name);
    if (f == nullptr) {
      throw py::type_error(what + "() got an unexpected keyword argument '" + name + "'; valid: " +
                           (extra_names.empty() ? "" : extra_names + ", ") + FieldNames(table));
    }
    f->set(*options, value);
  }
}

// Pops `name` from kwargs (None when absent).
py::object PopKeyword(py::dict& kwargs, const char* name);

// Pops kwargs[name], a dict of `table`'s keywords for a nested Options struct (replay(sgbm={...}),
// fuse(registration={...})), and sets them on *options; absent or None leaves *options as it is. `call` names
// the function in messages.
template <typename Options>
void ApplyNestedKeywords(py::dict& kwargs, const char* name, const FieldTable<Options>& table, Options* options,
                         const std::string& call) {
  py::object value = PopKeyword(kwargs, name);
  if (value.is_none()) return;
  if (!py::isinstance<py::dict>(value)) throw py::type_error(call + ": " + name + " must be a dict");
  ApplyKeywords(table, value.cast<py::dict>(), options, call + "(" + name + "=...)");
}

// {field: value} of `options` (e.g. the defaults of Options{}).
template <typename Options>
py::dict FieldsToDict(const FieldTable<Options>& table, const Options& options) {
  py::dict d;
  for (const auto& f : table) d[py::str(f.name)] = f.get(options);
  return d;
}

}  // namespace rangebayes::python
