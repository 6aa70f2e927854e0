#include "cairn/eval/plane_fit.hpp"

#include <Eigen/Dense>
#include <cmath>

namespace cairn::eval {

PlaneFit FitPlane(std::vector<Eigen::Vector3d> points, int trim_rounds) {
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

}  // namespace cairn::eval
