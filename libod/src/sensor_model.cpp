#include "cairn/od/sensor_model.hpp"

#include <cmath>
#include <string>

namespace cairn::od {

Status PinholeModel::Validate() const {
  auto bad = [](const char* field, const std::string& expected) {
    return Error{std::string("pinhole model: field '") + field + "' must be " + expected};
  };
  if (width <= 0) return bad("width", "a positive number of columns");
  if (height <= 0) return bad("height", "a positive number of rows");
  if (!std::isfinite(fx) || fx <= 0.0) return bad("fx", "a finite focal length > 0 [px]");
  if (!std::isfinite(fy) || fy <= 0.0) return bad("fy", "a finite focal length > 0 [px]");
  if (!std::isfinite(cx)) return bad("cx", "a finite principal point column [px]");
  if (!std::isfinite(cy)) return bad("cy", "a finite principal point row [px]");
  return Status::Ok();
}

}  // namespace cairn::od
