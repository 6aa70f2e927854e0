// A least-squares plane through 3-D points, for checking an up vector measured on a real
// frame's floor: the normal (the smallest principal axis, turned to -y: up in a camera's
// optical frame), the RMS distance of the points to it and the camera origin's height above
// it. `trim_rounds` rounds each keep only the points within 2 RMS and fit again.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace cairn::eval {

struct PlaneFit {
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double rms_m = 0.0;
  double height_m = 0.0;  ///< of the origin above the plane, along the normal
  int points = 0;
};

PlaneFit FitPlane(std::vector<Eigen::Vector3d> points, int trim_rounds = 0);

}  // namespace cairn::eval
