// A least-squares plane through 3-D points, for tests that check an up vector measured on a
// real frame's floor: the normal (the smallest principal axis, turned to -y: up in a camera's
// optical frame), the RMS distance of the points to it and the camera origin's height above
// it. `trim_rounds` rounds each keep only the points within 2 RMS and fit again.
#pragma once

#include <Eigen/Dense>

#include <cmath>
#include <vector>

namespace cairn::test {

struct PlaneFit {
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  double rms_m = 0.0;
  double height_m = 0.0;  ///< of the origin above the plane, along the normal
  int points = 0;
};

inline PlaneFit FitPlane(std::vector<Eigen::Vector3d> points, int trim_rounds = 0) {
  PlaneFit fit;
  for (int round = 0; round <= trim_rounds && points.size() >= 3; ++round) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const Eigen::Vector3d& p : points) mean += p;
    mean /= static_cast<double>(points.size());
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (const Eigen::Vector3d& p : points) scatter += (p - mean) * (p - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(scatter);
    Eigen::Vector3d n = eigen.eigenvectors().col(0);
    if (n.y() > 0.0) n = -n;
    double sum2 = 0.0;
    for (const Eigen::Vector3d& p : points) sum2 += std::pow(n.dot(p - mean), 2);
    fit.normal = n;
    fit.rms_m = std::sqrt(sum2 / static_cast<double>(points.size()));
    fit.height_m = -n.dot(mean);
    fit.points = static_cast<int>(points.size());
    if (round == trim_rounds) break;
    std::vector<Eigen::Vector3d> kept;
    for (const Eigen::Vector3d& p : points) {
      if (std::abs(n.dot(p - mean)) < 2.0 * fit.rms_m) kept.push_back(p);
    }
    points.swap(kept);
  }
  return fit;
}

}  // namespace cairn::test
