// core/: Mesh, NoisyMesh, mesh files and pictures of meshes.
#include <pybind11/numpy.h>
#include <pybind11/stl.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "python/src/bindings.h"
#include "python/src/convert.h"
#include "python/src/library.h"
#include "python/src/option_tables.h"

namespace rangebayes::python {
namespace {

// A 3-vector keyword (view_direction, up, colours): any sequence of three finite numbers.
template <typename Vector>
Vector Vector3(py::handle value, const std::string& what) {
  std::vector<double> v;
  try {
    v = value.cast<std::vector<double>>();
  } catch (const py::cast_error&) {
    throw py::type_error(what + ": expected three numbers");
  }
  if (v.size() != 3) throw py::value_error(what + ": expected three numbers, got " + std::to_string(v.size()));
  for (double x : v) {
    if (!std::isfinite(x)) throw py::value_error(what + ": not finite");
  }
  return Vector(static_cast<typename Vector::Scalar>(v[0]), static_cast<typename Vector::Scalar>(v[1]),
                static_cast<typename Vector::Scalar>(v[2]));
}

// render()'s defaults: the library's, in a 640×480 picture seen obliquely.
RenderOptions PythonRenderDefaults() {
  RenderOptions options;
  options.width_px = 640;
  options.height_px = 480;
  options.view_direction = Eigen::Vector3d(-0.6, -0.5, -1.0);
  return options;
}

// A (h, w, 3) uint8 array from an RgbImage (a copy).
py::array ArrayFromRgb(const RgbImage& image) {
  py::array_t<std::uint8_t> out(
      {static_cast<py::ssize_t>(image.height), static_cast<py::ssize_t>(image.width), py::ssize_t{3}});
  std::copy(image.rgb.begin(), image.rgb.end(), out.mutable_data());
  return out;
}

// Normals: None gives (0, 3); else (n, 3) for n vertices (any n when num_vertices < 0).
Normals NormalsFromArray(py::handle obj, Eigen::Index num_vertices) {
  if (obj.is_none()) return Normals(0, 3);
  Normals N = VerticesFromArray(obj, "N");
  if (num_vertices >= 0 && N.rows() != 0 && N.rows() != num_vertices) {
    throw py::value_error("N: " + std::to_string(N.rows()) + " normals for " + std::to_string(num_vertices) +
                          " vertices (give one per vertex, or None)");
  }
  return N;
}

std::vector<Eigen::Matrix3d> CovariancesFor(py::handle obj, Eigen::Index num_vertices) {
  std::vector<Eigen::Matrix3d> covariance = CovariancesFromArray(obj, "covariances");
  if (!covariance.empty() && static_cast<Eigen::Index>(covariance.size()) != num_vertices) {
    throw py::value_error("covariances: " + std::to_string(covariance.size()) + " matrices for " +
                          std::to_string(num_vertices) + " vertices (give one per vertex, or None)");
  }
  return covariance;
}

// The storage of an array that already holds values keeps its size (numpy views of it stay valid).
void CheckSameRows(Eigen::Index rows, Eigen::Index new_rows, const std::string& what) {
  if (rows != 0 && rows != new_rows) {
    throw py::value_error(what + ": the storage has " + std::to_string(rows) + " rows, the new value " +
                          std::to_string(new_rows) + "; assign one with as many rows (views of the storage stay " +
                          "valid) or build a new mesh");
  }
}

// mesh.N = array: in place when N has values (checked against the vertex count first).
void AssignNormals(py::handle a, Mesh* mesh) {
  if (a.is_none()) {
    CheckSameRows(mesh->N.rows(), 0, "N");
    return;
  }
  const py::tuple shape = py::module_::import("numpy").attr("shape")(a);
  const Eigen::Index rows = shape.empty() ? -1 : shape[0].cast<Eigen::Index>();
  if (rows != 0 && rows != mesh->V.rows()) {
    throw py::value_error("N: " + std::to_string(rows) + " normals for " + std::to_string(mesh->V.rows()) +
                          " vertices (give one per vertex, or None)");
  }
  AssignVertices(a, "N", &mesh->N);
}

// noisy.mesh = mesh: copies into the existing storage (Eigen reallocates only on another size, refused here).
void AssignMesh(const Mesh& from, Mesh* to) {
  CheckSameRows(to->V.rows(), from.V.rows(), "mesh.V");
  CheckSameRows(to->F.rows(), from.F.rows(), "mesh.F");
  CheckSameRows(to->N.rows(), from.N.rows(), "mesh.N");
  *to = from;
}

// A Mesh from arrays: V first, so that F's indices and N's rows are checked against it.
Mesh MeshFromArrays(py::handle V, py::handle F, py::handle N) {
  Mesh mesh;
  mesh.V = VerticesFromArray(V, "V");
  mesh.F = FacesFromArray(F, "F", mesh.V.rows());
  mesh.N = NormalsFromArray(N, mesh.V.rows());
  return mesh;
}

MeshWriteOptions WriteOptions(const std::string& ply_encoding) {
  MeshWriteOptions options;
  if (ply_encoding == "binary") {
    options.ply_encoding = PlyEncoding::kBinaryLittleEndian;
  } else if (ply_encoding == "ascii") {
    options.ply_encoding = PlyEncoding::kAscii;
  } else {
    throw py::value_error("ply_encoding: expected 'binary' or 'ascii', got '" + ply_encoding + "'");
  }
  return options;
}

}  // namespace

void BindCore(py::module_& m) {
  py::class_<Mesh>(m, "Mesh", R"(A triangle mesh: V (n, 3) float64 positions in model units (metres for our cameras),
F (m, 3) int32 vertex indices (counter-clockwise seen from outside), N (n, 3) or (0, 3) optional normals.

Mesh(V, F, N=None) copies the arrays in one pass (the C++ mesh owns its storage): float64 V and int32 F of
any strides are read in place, other real / integer dtypes are converted by numpy first; the copy runs
without the GIL. ValueError for NaN or infinite values, face indices
outside [0, n) or N with another number of rows; TypeError for another dtype kind.
Reading mesh.V / mesh.F / mesh.N gives a writable numpy view of the C++ storage (no copy) that keeps the
mesh alive. Assigning mesh.V = array (or F, or NoisyMesh.covariances) of the same shape copies into the
existing storage: no allocation, views stay valid and see the new values, all values are checked before any
is written. An array that holds values never changes its size (its views would dangle): another shape is a
ValueError; build a new Mesh instead. Empty arrays (N of (0, 3), no covariances) take any size. Library calls check the mesh again (values
written through views) and raise ValueError for a mesh they could not use.)")
      .def(py::init(&MeshFromArrays), py::arg("V"), py::arg("F"), py::arg("N") = py::none())
      .def_property(
          "V", [](py::object self) { return VerticesView(self.cast<Mesh&>().V, self); },
          [](Mesh& mesh, py::handle a) { AssignVertices(a, "V", &mesh.V); }, "(n, 3) float64 positions (view)")
      .def_property(
          "F", [](py::object self) { return FacesView(self.cast<Mesh&>().F, self); },
          [](Mesh& mesh, py::handle a) { AssignFaces(a, "F", mesh.V.rows(), &mesh.F); }, "(m, 3) int32 faces (view)")
      .def_property(
          "N", [](py::object self) { return VerticesView(self.cast<Mesh&>().N, self); },
          [](Mesh& mesh, py::handle a) { AssignNormals(a, &mesh); },
          "(n, 3) float64 vertex normals, (0, 3) when absent (view)")
      .def_property_readonly("num_vertices", &Mesh::num_vertices)
      .def_property_readonly("num_faces", &Mesh::num_faces)
      .def(
          "copy", [](const Mesh& mesh) { return Mesh(mesh); }, "A deep copy.")
      // Pickled as the constructor's arguments (copies), so an unpickled mesh is checked as Mesh(...) checks.
      .def(py::pickle(
          [](const Mesh& mesh) {
            return py::make_tuple(mesh.V, mesh.F, mesh.N.rows() > 0 ? py::cast(mesh.N) : py::object(py::none()));
          },
          [](const py::tuple& state) {
            if (state.size() != 3) throw py::value_error("cannot unpickle Mesh: not a state this module wrote");
            return MeshFromArrays(state[0], state[1], state[2]);
          }))
      .def("__repr__", [](const Mesh& mesh) {
        return "<rangebayes.Mesh " + std::to_string(mesh.num_vertices()) + " vertices, " +
               std::to_string(mesh.num_faces()) + " faces>";
      });

  py::class_<NoisyMesh>(m, "NoisyMesh",
                        R"(A mesh whose vertices are noisy measurements: covariances (n, 3, 3) float64, one 3×3
covariance per vertex in model units squared (empty (0, 3, 3) when not known), pixel (n, 2) float32 image
positions the vertices were triangulated from (or (0, 2)).

NoisyMesh(V, F, covariances=None) and NoisyMesh(mesh, covariances=None) copy as Mesh(...) does (one pass,
GIL released; covariances of any strides, one per vertex, finite). V, F, N, covariances and pixel read as
writable views of the C++ storage (no copy); assignment copies.)")
      // The Mesh overload first: the array overload accepts any object.
      .def(py::init([](const Mesh& mesh, py::handle covariances) {
             NoisyMesh noisy;
             noisy.mesh = mesh;
             if (!covariances.is_none()) noisy.covariance = CovariancesFor(covariances, mesh.V.rows());
             return noisy;
           }),
           py::arg("mesh"), py::arg("covariances") = py::none())
      .def(py::init([](py::handle V, py::handle F, py::handle covariances) {
             NoisyMesh noisy;
             noisy.mesh = MeshFromArrays(V, F, py::none());
             if (!covariances.is_none()) noisy.covariance = CovariancesFor(covariances, noisy.mesh.V.rows());
             return noisy;
           }),
           py::arg("V"), py::arg("F"), py::arg("covariances") = py::none())
      .def_property(
          "mesh", [](NoisyMesh& noisy) -> Mesh& { return noisy.mesh; },
          [](NoisyMesh& noisy, const Mesh& mesh) { AssignMesh(mesh, &noisy.mesh); },
          py::return_value_policy::reference_internal, "the Mesh inside (a reference: changes show in both)")
      .def_property(
          "V", [](py::object self) { return VerticesView(self.cast<NoisyMesh&>().mesh.V, self); },
          [](NoisyMesh& n, py::handle a) { AssignVertices(a, "V", &n.mesh.V); }, "(n, 3) float64 positions (view)")
      .def_property(
          "F", [](py::object self) { return FacesView(self.cast<NoisyMesh&>().mesh.F, self); },
          [](NoisyMesh& n, py::handle a) { AssignFaces(a, "F", n.mesh.V.rows(), &n.mesh.F); },
          "(m, 3) int32 faces (view)")
      .def_property(
          "N", [](py::object self) { return VerticesView(self.cast<NoisyMesh&>().mesh.N, self); },
          [](NoisyMesh& n, py::handle a) { AssignNormals(a, &n.mesh); }, "(n, 3) float64 normals (view)")
      .def_property(
          "covariances", [](py::object self) { return CovariancesView(self.cast<NoisyMesh&>().covariance, self); },
          [](NoisyMesh& n, py::handle a) {
            if (a.is_none()) {
              CheckSameRows(static_cast<Eigen::Index>(n.covariance.size()), 0, "covariances");
              return;
            }
            const py::tuple shape = py::module_::import("numpy").attr("shape")(a);
            const Eigen::Index count = shape.empty() ? -1 : shape[0].cast<Eigen::Index>();
            if (count != 0 && count != n.mesh.V.rows()) {
              throw py::value_error("covariances: " + std::to_string(count) + " matrices for " +
                                    std::to_string(n.mesh.V.rows()) + " vertices (give one per vertex, or None)");
            }
            AssignCovariances(a, "covariances", &n.covariance);
          },
          "(n, 3, 3) float64 covariances, model units² (view; strides (72, 8, 24): each 3×3 is column-major)")
      .def_property(
          "pixel", [](py::object self) { return PixelsView(self.cast<NoisyMesh&>().pixel, self); },
          [](NoisyMesh& n, py::handle a) {
            const auto pixel = PixelsFromArray(a, "pixel");
            if (pixel.rows() != 0 && pixel.rows() != n.mesh.V.rows()) {
              throw py::value_error("pixel: " + std::to_string(pixel.rows()) + " rows for " +
                                    std::to_string(n.mesh.V.rows()) + " vertices");
            }
            CheckSameRows(n.pixel.rows(), pixel.rows(), "pixel");
            n.pixel = pixel;  // a copy into the same storage (or into empty storage)
          },
          "(n, 2) float32 (u, v) pixel of each vertex, or (0, 2) (view)")
      .def_property_readonly("has_covariance", &NoisyMesh::has_covariance)
      .def_property_readonly("num_vertices", [](const NoisyMesh& n) { return n.mesh.num_vertices(); })
      .def_property_readonly("num_faces", [](const NoisyMesh& n) { return n.mesh.num_faces(); })
      .def(
          "copy", [](const NoisyMesh& n) { return NoisyMesh(n); }, "A deep copy.")
      .def(py::pickle(
          [](py::object self) {
            const NoisyMesh& n = self.cast<const NoisyMesh&>();
            const py::object copy = py::module_::import("numpy").attr("array");
            return py::make_tuple(n.mesh.V, n.mesh.F, n.mesh.N.rows() > 0 ? py::cast(n.mesh.N) : py::object(py::none()),
                                  copy(self.attr("covariances")), copy(self.attr("pixel")));
          },
          [](const py::tuple& state) {
            if (state.size() != 5) throw py::value_error("cannot unpickle NoisyMesh: not a state this module wrote");
            NoisyMesh noisy;
            noisy.mesh = MeshFromArrays(state[0], state[1], state[2]);
            noisy.covariance = CovariancesFor(state[3], noisy.mesh.V.rows());
            noisy.pixel = PixelsFromArray(state[4], "pixel");
            if (noisy.pixel.rows() != 0 && noisy.pixel.rows() != noisy.mesh.V.rows()) {
              throw py::value_error("cannot unpickle NoisyMesh: " + std::to_string(noisy.pixel.rows()) +
                                    " pixel rows for " + std::to_string(noisy.mesh.V.rows()) + " vertices");
            }
            return noisy;
          }))
      .def("__repr__", [](const NoisyMesh& n) {
        return "<rangebayes.NoisyMesh " + std::to_string(n.mesh.num_vertices()) + " vertices, " +
               std::to_string(n.mesh.num_faces()) + " faces, " + (n.has_covariance() ? "with" : "without") +
               " covariances>";
      });

  m.def(
      "read_mesh",
      [](const PathArg& path) -> py::object {
        NoisyMesh noisy;
        MeshReadSummary summary;
        {
          py::gil_scoped_release nogil;
          noisy = ReadMeshOrRangeGrid(path.string(), &summary);
        }
        WarnNotices(summary.notices, path.string());  // not summary.range_grid: the docstring says so
        if (noisy.has_covariance()) return py::cast(std::move(noisy));
        return py::cast(std::move(noisy.mesh));
      },
      py::arg("path"),
      R"(Reads a PLY / OBJ / OFF mesh (by extension). Returns a NoisyMesh when the file has per-vertex covariances
(PLY cov_xx..cov_zz), else a Mesh. A PLY range-grid scan without faces (the Stanford scans) is triangulated as the
CLI reads it, with the scanner's covariances: a NoisyMesh. Raises rangebayes.Error naming the file and line on
bad input; what the reader left out or changed (polygons triangulated, normals, colours or texture coordinates ignored) is a UserWarning, as
the CLI prints it.)");
  m.def(
      "read_noisy_mesh",
      [](const PathArg& path) {
        NoisyMesh noisy;
        MeshReadSummary summary;
        {
          py::gil_scoped_release nogil;
          noisy = ReadMeshOrRangeGrid(path.string(), &summary);
        }
        WarnNotices(summary.notices, path.string());
        return noisy;
      },
      py::arg("path"),
      "Reads a mesh as a NoisyMesh (covariances empty when the file has none; range grids as read_mesh reads them).");
  m.def(
      "write_mesh",
      [](const PathArg& path_arg, py::handle mesh, const std::string& ply_encoding) {
        const std::string path = path_arg.string();
        MeshWriteOptions options = WriteOptions(ply_encoding);
        if (py::isinstance<NoisyMesh>(mesh)) {
          const NoisyMesh noisy = mesh.cast<NoisyMesh>();
          CheckNoisyMeshForLibrary(noisy, "write_mesh");
          py::gil_scoped_release nogil;
          WriteNoisyMesh(noisy, path, options);
        } else if (py::isinstance<Mesh>(mesh)) {
          const Mesh plain = mesh.cast<Mesh>();
          CheckMeshForLibrary(plain, "write_mesh");
          py::gil_scoped_release nogil;
          WriteMesh(plain, path, options);
        } else if (py::hasattr(mesh, "corner_normals") && py::hasattr(mesh, "mesh")) {
          const Mesh plain = mesh.attr("mesh").cast<Mesh>();
          options.corner_normals = mesh.attr("corner_normals").cast<CornerNormals>();
          py::gil_scoped_release nogil;
          WriteMesh(plain, path, options);
        } else {
          throw py::type_error("write_mesh: expected a Mesh, NoisyMesh or DecimatedMesh");
        }
      },
      py::arg("path"), py::arg("mesh"), py::arg("ply_encoding") = "binary",
      R"(Writes a Mesh (as `rangebayes convert` / `smooth` write it), a NoisyMesh (PLY: with its covariances) or a
DecimatedMesh (with its per-corner normals). Format by extension (.ply/.obj/.off); ply_encoding 'binary'
(default) or 'ascii'.)");

  py::class_<CornerNormals>(m, "CornerNormals", "Per-corner shading normals: normals (k, 3), normal_index (m, 3).")
      .def(py::init<>())
      .def_property_readonly("normals",
                             [](py::object self) { return VerticesView(self.cast<CornerNormals&>().normals, self); })
      .def_property_readonly("normal_index",
                             [](py::object self) { return FacesView(self.cast<CornerNormals&>().normal_index, self); })
      .def(py::pickle([](const CornerNormals& c) { return py::make_tuple(c.normals, c.normal_index); },
                      [](const py::tuple& state) {
                        if (state.size() != 2) {
                          throw py::value_error("cannot unpickle CornerNormals: not a state this module wrote");
                        }
                        CornerNormals c;
                        c.normals = VerticesFromArray(state[0], "normals");
                        c.normal_index = FacesFromArray(state[1], "normal_index", c.normals.rows());
                        return c;
                      }));
  m.def(
      "render",
      [](py::handle mesh, py::kwargs kwargs) {
        py::dict kw = py::dict(kwargs);
        RenderOptions options = PythonRenderDefaults();
        for (const auto& [name, field] :
             {std::pair<const char*, Eigen::Vector3d*>{"view_direction", &options.view_direction},
              {"up", &options.up},
              {"light_in_camera", &options.light_in_camera}}) {
          py::object value = PopKeyword(kw, name);
          if (!value.is_none()) *field = Vector3<Eigen::Vector3d>(value, std::string("render: ") + name);
        }
        for (const auto& [name, field] : {std::pair<const char*, Eigen::Vector3f*>{"base_color", &options.base_color},
                                          {"background", &options.background}}) {
          py::object value = PopKeyword(kw, name);
          if (!value.is_none()) *field = Vector3<Eigen::Vector3f>(value, std::string("render: ") + name);
        }
        py::object frame_like = PopKeyword(kw, "frame_like");
        ApplyKeywords(RenderOptionFields(), kw, &options, "render",
                      "view_direction, up, light_in_camera, base_color, background, frame_like");
        // The mesh, and a decimated mesh's patch normal fields for smooth shading.
        NoisyMesh noisy;
        if (py::isinstance<DecimatedMesh>(mesh)) {
          const DecimatedMesh& d = mesh.cast<const DecimatedMesh&>();
          noisy.mesh = d.mesh;
          if (options.shading == Shading::kSmooth && !d.corner_normals.empty()) {
            options.corner_normals = CornerNormalRows(d.corner_normals);
          }
        } else {
          noisy = ToNoisyMesh(mesh, "render");
        }
        // The framing: a depth image's mesh as its camera saw it, any other from view_direction, fitted to the
        // mesh, or to frame_like (so that pictures of a mesh and of its smoothed or decimated result match).
        if (frame_like.is_none()) {
          FitView(noisy, &options);
        } else {
          FitView(ToNoisyMesh(frame_like, "render: frame_like"), &options);
        }
        options.Check(noisy.mesh);
        RgbImage image;
        {
          py::gil_scoped_release nogil;
          image = RenderMesh(noisy.mesh, options);
        }
        return ArrayFromRgb(image);
      },
      py::arg("mesh"),
      R"(A picture of a mesh (Mesh, NoisyMesh or DecimatedMesh) with the renderer of the CLI's --png pictures (their
sizes and views differ by command; give width_px, height_px, view_direction to match one): (h, w, 3) uint8
RGB, z-buffered, Lambert-shaded, headless. A mesh from a depth image is seen as its camera saw it, any other along
view_direction (default (-0.6, -0.5, -1)); frame_like: frame the view on another mesh (the noisy input of a
smoothed result, so both pictures match). Keywords: rangebayes.RENDER_OPTIONS (width_px 640, height_px 480,
shading 'flat' or 'smooth' (a DecimatedMesh: its patch normal fields), projection, ...), view_direction, up,
light_in_camera, base_color, background (three numbers each). GIL released.)");
  m.attr("RENDER_OPTIONS") = FieldsToDict(RenderOptionFields(), PythonRenderDefaults());
  m.def(
      "write_png",
      [](const PathArg& path, py::handle image) {
        if (!py::isinstance<py::array_t<std::uint8_t>>(image)) {
          throw py::type_error("write_png: expected an (h, w, 3) uint8 RGB array");
        }
        const auto a = py::array_t<std::uint8_t, py::array::c_style>::ensure(image);
        if (!a || a.ndim() != 3 || a.shape(2) != 3 || a.shape(0) < 1 || a.shape(1) < 1) {
          throw py::type_error("write_png: expected an (h, w, 3) uint8 RGB array");
        }
        RgbImage rgb(static_cast<int>(a.shape(1)), static_cast<int>(a.shape(0)));
        std::copy(a.data(), a.data() + a.size(), rgb.rgb.begin());
        py::gil_scoped_release nogil;
        WritePng(rgb, path.string());
      },
      py::arg("path"), py::arg("image"), "Writes an (h, w, 3) uint8 RGB array (render()'s pictures) as a PNG.");
}

}  // namespace rangebayes::python
