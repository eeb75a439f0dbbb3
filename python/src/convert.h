// numpy <-> rangebayes data: meshes, covariances and images. What copies and what does not is stated per
// function; the bindings repeat it in their docstrings.
//
// numpy -> C++ is one pass over the input (the library's types own their storage, so a copy cannot be
// avoided): a float64 / int32 array of any strides is read in place, other dtypes are first converted by
// numpy. The pass runs without the GIL (on one thread) and checks values as it copies
// (non-finite numbers, face indices out of range), so bad input is a ValueError naming the array and row,
// never a crash in the library.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/mesh.h"

namespace rangebayes::python {

namespace py = pybind11;

// Copies an (n, 3) array of any real dtype, any strides, into positions. TypeError/ValueError naming `what`
// on another shape or dtype, ValueError on a NaN or infinite value.
Vertices VerticesFromArray(py::handle array, const std::string& what);
// Copies an (m, 3) integer array into faces. ValueError when an index does not fit in int32 or, with
// num_vertices ≥ 0, lies outside [0, num_vertices).
Faces FacesFromArray(py::handle array, const std::string& what, Eigen::Index num_vertices = -1);
// Copies an (n, 3, 3) array into one 3×3 matrix per vertex (ValueError on a non-finite value).
std::vector<Eigen::Matrix3d> CovariancesFromArray(py::handle array, const std::string& what);
// Assignment from Python (mesh.V = array, ...) with the same checks. Into empty storage: fresh storage. Into
// storage of as many rows: in place (no allocation, so numpy views of it stay valid; all values are checked
// before any is written, so an error leaves it as it was; through a temporary when the array is a view of
// it). Storage with values never changes size (its views would dangle): ValueError.
void AssignVertices(py::handle array, const std::string& what, Vertices* V);
void AssignFaces(py::handle array, const std::string& what, Eigen::Index num_vertices, Faces* F);
void AssignCovariances(py::handle array, const std::string& what, std::vector<Eigen::Matrix3d>* covariance);
// Copies an (n, 2) array into float32 pixel positions.
Eigen::Matrix<float, Eigen::Dynamic, 2, Eigen::RowMajor> PixelsFromArray(py::handle array, const std::string& what);

// Checks what a library call needs of a mesh whose arrays may have been written through views since it was
// made: finite positions, face indices in [0, #V), normals and covariances absent or one per vertex.
// ValueError naming `what` (the call) otherwise.
void CheckMeshForLibrary(const Mesh& mesh, const std::string& what);
void CheckNoisyMeshForLibrary(const NoisyMesh& noisy, const std::string& what);

// A copy of the C++ mesh behind a Python Mesh or NoisyMesh (the calls run without the GIL, so they must not share
// storage that Python threads may resize), checked as above. TypeError naming `what` for any other object.
NoisyMesh ToNoisyMesh(py::handle mesh, const char* what);
Mesh ToMesh(py::handle mesh, const char* what);

// Views (no copy) of the C++ storage, kept alive by `owner` (a Python object that owns the storage).
py::array VerticesView(Vertices& V, py::handle owner);
py::array FacesView(Faces& F, py::handle owner);
// covariance[i](r, c) is view[i, r, c] (strides (72, 8, 24): the 3×3 blocks are column-major in memory).
py::array CovariancesView(std::vector<Eigen::Matrix3d>& covariance, py::handle owner);
py::array PixelsView(Eigen::Matrix<float, Eigen::Dynamic, 2, Eigen::RowMajor>& pixel, py::handle owner);

// An image as a cv::Mat header over the array's memory (no copy) when it is C-contiguous, else over a
// contiguous copy; `keep` holds whichever array the header points into. dtypes uint8, uint16, float32, float64;
// shape (h, w) or (h, w, c), c in 1..4.
struct ImageIn {
  py::array keep;
  cv::Mat mat;
};
ImageIn ImageFromArray(py::handle array, const std::string& what);
// A numpy array over the cv::Mat's data (no copy; the array holds a reference to the Mat's buffer).
// An empty Mat gives None.
py::object ArrayFromMat(const cv::Mat& mat);

}  // namespace rangebayes::python
