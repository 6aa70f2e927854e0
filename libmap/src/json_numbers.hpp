// Internal: numbers and fixed-length arrays of numbers in the resume states' JSON (nlohmann),
// read back to the last bit. Non-finite numbers are written as null and read back as NaN.
#pragma once

#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

namespace cairn::map::internal {

inline nlohmann::json Number(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}
inline double NumberFrom(const nlohmann::json& j) { return j.is_null() ? NAN : j.get<double>(); }

inline nlohmann::json Array(const double* v, int n) {
  nlohmann::json a = nlohmann::json::array();
  for (int i = 0; i < n; ++i) a.push_back(Number(v[i]));
  return a;
}
/// Reads n numbers of `j` into v; throws std::runtime_error naming `what` on another
/// length, and nlohmann's exceptions on another type.
inline void ArrayFrom(const nlohmann::json& j, double* v, int n, const char* what) {
  if (!j.is_array() || static_cast<int>(j.size()) != n) {
    throw std::runtime_error(std::string("'") + what + "' must be an array of " +
                             std::to_string(n) + " numbers");
  }
  for (int i = 0; i < n; ++i) v[i] = NumberFrom(j.at(i));
}

}  // namespace cairn::map::internal
