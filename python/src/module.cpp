// The cairn extension module (_cairn): cairn.Error, then one file per area (detect.cpp,
// map.cpp, io.cpp). python/cairn/__init__.py puts the pure-Python layer on top.
#include <cmath>
#include <string>

#include "common.hpp"

namespace cairn::python {

void RegisterError(py::module_& m) {
  // A subclass of both ValueError (bad input, bad files) and RuntimeError, so that callers
  // that catch either catch it; created by hand because py::register_exception takes one base.
  static py::handle error_type;  // NOLINT: lives as long as the interpreter holds the module
  py::object bases = py::make_tuple(py::handle(PyExc_ValueError), py::handle(PyExc_RuntimeError));
  error_type = PyErr_NewExceptionWithDoc(
      "cairn.Error",
      "An error of the cairn library: bad input, a bad file or a bad setting. The message is "
      "the library's, word for word what the command line prints.",
      bases.ptr(), nullptr);
  if (error_type.ptr() == nullptr) throw py::error_already_set();
  m.attr("Error") = error_type;
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const CairnError& e) {
      PyErr_SetString(error_type.ptr(), e.what());
    }
  });
}

PointsIn ReadPointsArray(const InArray<float>& array, const std::string& name) {
  if (array.ndim() != 2 || (array.shape(1) != 3 && array.shape(1) != 4)) {
    std::string shape = "(";
    for (py::ssize_t d = 0; d < array.ndim(); ++d) {
      shape += (d > 0 ? ", " : "") + std::to_string(array.shape(d));
    }
    shape += array.ndim() == 1 ? ",)" : ")";
    throw CairnError(name + ": expected an (N, 3) or (N, 4) array of x, y, z [m] (and "
                     "intensity) per point, got shape " + shape);
  }
  const py::ssize_t n = array.shape(0), k = array.shape(1);
  if (n == 0) throw CairnError(name + ": no points");
  PointsIn out;
  out.points.resize(static_cast<std::size_t>(n));
  out.intensity.assign(static_cast<std::size_t>(n), 0.0f);
  const float* data = array.data();
  for (py::ssize_t i = 0; i < n; ++i) {
    const float* p = data + i * k;
    Eigen::Vector3f v(p[0], p[1], p[2]);
    if (!v.allFinite()) {
      if (std::isnan(p[0]) && std::isnan(p[1]) && std::isnan(p[2])) {
        v.setZero();  // an organised cloud's no return, as the point readers store it
      } else {
        throw CairnError(name + ": point " + std::to_string(i) +
                         " has a non-finite coordinate (only all-NaN x, y, z means no return)");
      }
    }
    out.points[static_cast<std::size_t>(i)] = v;
    if (k == 4) {
      if (!std::isfinite(p[3])) {
        throw CairnError(name + ": point " + std::to_string(i) + " has a non-finite intensity");
      }
      out.intensity[static_cast<std::size_t>(i)] = p[3];
    }
  }
  return out;
}

Eigen::Isometry3d ReadPose(const InArray<double>& array, const std::string& name) {
  if (array.ndim() != 2 || array.shape(0) != 4 || array.shape(1) != 4) {
    throw CairnError(name + ": expected a (4, 4) homogeneous transform");
  }
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) m(r, c) = array.at(r, c);
  }
  if (!m.allFinite()) throw CairnError(name + ": non-finite value");
  if (m.row(3) != Eigen::RowVector4d(0, 0, 0, 1)) {
    throw CairnError(name + ": the last row must be 0 0 0 1");
  }
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  if (!(R.transpose() * R).isApprox(Eigen::Matrix3d::Identity(), 1e-6) || R.determinant() < 0) {
    throw CairnError(name + ": the rotation is not orthonormal (to 1e-6)");
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.matrix() = m;
  return T;
}

Eigen::Vector3d ReadVector3(const std::vector<double>& values, const std::string& name) {
  if (values.size() != 3) throw CairnError(name + ": expected three numbers x, y, z");
  return {values[0], values[1], values[2]};
}

od::PinholeModel PinholeOf(const InArray<float>& depth_m, double fx, double fy, double cx,
                           double cy) {
  od::PinholeModel model;
  model.height = static_cast<int>(depth_m.shape(0));
  model.width = static_cast<int>(depth_m.shape(1));
  model.fx = fx;
  model.fy = fy;
  model.cx = cx;
  model.cy = cy;
  return model;
}

py::array_t<float> ImageXyz(const od::RangeImage& image) {
  std::vector<float> xyz(static_cast<std::size_t>(image.size()) * 3);
  for (int i = 0; i < image.size(); ++i) {
    xyz[3 * i] = image.x()[i];
    xyz[3 * i + 1] = image.y()[i];
    xyz[3 * i + 2] = image.z()[i];
  }
  return Take(std::move(xyz), {image.height(), image.width(), 3});
}

}  // namespace cairn::python

PYBIND11_MODULE(_cairn, m) {
  m.doc() =
      "cairn: obstacle detection (Talukder et al. 2002 cone detector, column baseline) and "
      "multi-frame mapping (OctoMap + 2.5-D nav2 cost grid). Metres, radians, seconds.";
  m.attr("__version__") = CAIRN_VERSION;
  cairn::python::RegisterError(m);
  cairn::python::RegisterDetect(m);
  cairn::python::RegisterMap(m);
  cairn::python::RegisterIo(m);
  cairn::python::RegisterEval(m);
}
