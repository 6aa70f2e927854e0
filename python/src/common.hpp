// Shared by the binding files: library errors as cairn.Error, and numpy <-> C++ copies.
//
// Arrays come in as any numeric numpy array (pybind11's forcecast converts dtypes and makes
// it C-contiguous when it is not); results go out zero-copy where the C++ result owns a
// contiguous buffer (the array's base keeps the owner alive).
#pragma once

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "cairn/od/expected.hpp"
#include "cairn/od/range_image.hpp"
#include "cairn/od/sensor_model.hpp"

namespace cairn::python {

namespace py = pybind11;

/// A library error on its way to Python: raised there as cairn.Error with the message as it
/// is, the same words the command line prints after "cairn <subcommand>: error: ".
class CairnError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

template <typename T>
T Unwrap(Expected<T> result) {
  if (!result) throw CairnError(result.error().message);
  return std::move(*result);
}
inline void Check(const Status& status) {
  if (!status) throw CairnError(status.message());
}

/// Registers cairn.Error (a subclass of ValueError and RuntimeError) and its translator.
void RegisterError(py::module_& m);

template <typename T>
using InArray = py::array_t<T, py::array::c_style | py::array::forcecast>;

/// Points of an (N, 3) or (N, 4) array (x, y, z [m], optional intensity) as the point
/// readers give them: a point whose x, y and z are all NaN is a no return, stored as
/// (0, 0, 0); any other non-finite coordinate fails naming the point.
struct PointsIn {
  std::vector<Eigen::Vector3f> points;
  std::vector<float> intensity;  ///< one per point, 0 without a fourth column
};
PointsIn ReadPointsArray(const InArray<float>& array, const std::string& name);

/// A 4x4 rigid transform from a (4, 4) array; fails unless its last row is 0 0 0 1 and its
/// rotation is orthonormal (to 1e-6).
Eigen::Isometry3d ReadPose(const InArray<double>& array, const std::string& name);

/// A unit-free 3-vector from a sequence of three numbers.
Eigen::Vector3d ReadVector3(const std::vector<double>& values, const std::string& name);

/// A read-only numpy array over a vector's storage, kept alive by `owner` (zero-copy).
template <typename T>
py::array_t<T> View(const std::vector<T>& data, std::vector<py::ssize_t> shape, py::handle owner) {
  py::array_t<T> view(shape, data.data(), owner);
  // Read-only: the result is shared by every view of it.
  view.attr("setflags")(py::arg("write") = false);
  return view;
}

/// A numpy array that takes the vector over (no copy of the elements).
template <typename T>
py::array_t<T> Take(std::vector<T>&& data, std::vector<py::ssize_t> shape) {
  auto* owned = new std::vector<T>(std::move(data));
  py::capsule free(owned, [](void* p) { delete static_cast<std::vector<T>*>(p); });
  return py::array_t<T>(shape, owned->data(), free);
}

/// The pinhole model of an (H, W) depth array [px].
od::PinholeModel PinholeOf(const InArray<float>& depth_m, double fx, double fy, double cx,
                           double cy);

/// A range image's points as an (H, W, 3) float32 array, sensor frame [m].
py::array_t<float> ImageXyz(const od::RangeImage& image);

void RegisterDetect(py::module_& m);
void RegisterMap(py::module_& m);
void RegisterIo(py::module_& m);
void RegisterEval(py::module_& m);

}  // namespace cairn::python
