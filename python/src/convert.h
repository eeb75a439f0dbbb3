// numpy <-> rangebayes data: meshes, covariances and images. What copies and what does not is stated per
// function; the bindings repeat it in their docstrings.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/mesh.h"

namespace rangebayes::python {

namespace py = pybind11;

// Copies an (n, 3) array of any real dtype, any strides, into positions (one memcpy when C-contiguous float64).
// TypeError/ValueError naming `what` on another shape or dtype.
Vertices VerticesFromArray(py::handle array, const std::string& what);
// Copies an (m, 3) integer array into faces (int32; larger values are a ValueError).
Faces FacesFromArray(py::handle array, const std::string& what);
// Copies an (n, 3, 3) array into one 3×3 matrix per vertex.
std::vector<Eigen::Matrix3d> CovariancesFromArray(py::handle array, const std::string& what);

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
