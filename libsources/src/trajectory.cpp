#include "cairn/sources/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iomanip>
#include <map>
#include <sstream>

#include "cairn/od/units.hpp"
#include "cairn/util/atomic_file.hpp"
#include "cairn/util/format.hpp"

namespace cairn::sources {
namespace {

constexpr const char* kAction3D = "CActionRobotMovement3D";

std::string Seconds(double s, int decimals = 3) { return util::Fixed(s, decimals); }

/// Heading of a body rotation (Z-Y-X yaw), well defined unless the body points straight up.
double YawOf(const Eigen::Matrix3d& R) { return std::atan2(R(1, 0), R(0, 0)); }

Eigen::Matrix3d FromYawPitchRoll(double yaw, double pitch, double roll) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

/// a + f (b - a) for angles, through the shorter way round.
double LerpAngle(double a, double b, double f) { return a + f * std::remainder(b - a, 2 * kPi); }

/// The pose a fraction f of the way from a to b (f outside [0, 1] extrapolates at the same
/// velocity): position linear, rotation along the geodesic.
Eigen::Isometry3d Blend(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double f) {
  const Eigen::Quaterniond qa(a.linear()), qb(b.linear());
  const Eigen::AngleAxisd step(qa.conjugate() * qb);  // rotation from a to b, in a's frame
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = (qa * Eigen::AngleAxisd(step.angle() * f, step.axis())).toRotationMatrix();
  out.translation() = a.translation() + f * (b.translation() - a.translation());
  return out;
}

}  // namespace

Status TrajectoryOptions::Validate() const {
  const auto check = [](double v, const char* name) -> Status {
    if (!std::isfinite(v) || v < 0.0) {
      return Error{std::string("trajectory options: ") + name + ": expected a finite value >= 0"};
    }
    return {};
  };
  if (Status s = check(max_extrapolation_s, "max_extrapolation_s"); !s) return s;
  if (Status s = check(max_gap_s, "max_gap_s"); !s) return s;
  return check(max_imu_age_s, "max_imu_age_s");
}

Expected<Trajectory> Trajectory::FromOdometry(const std::vector<OdometrySample>& odometry,
                                              const std::vector<ImuAttitude>& imu,
                                              const TrajectoryOptions& options) {
  if (Status s = options.Validate(); !s) return s.error();
  if (odometry.empty()) return Error{"odometry: no samples (the recording has no odometry)"};
  // By stamp; a later sample with the same stamp wins (std::map keeps the last assignment).
  std::map<double, const OdometrySample*> by_stamp;
  for (std::size_t k = 0; k < odometry.size(); ++k) {
    const OdometrySample& s = odometry[k];
    if (!std::isfinite(s.stamp_s)) {
      return Error{"odometry sample " + std::to_string(k) + " ('" + s.source + "'): no time stamp"};
    }
    if (!s.T_odom_body.matrix().allFinite()) {
      return Error{"odometry sample " + std::to_string(k) + " ('" + s.source +
                   "', t = " + Seconds(s.stamp_s, 6) + " s): pose is not finite"};
    }
    by_stamp[s.stamp_s] = &s;
  }
  std::map<double, ImuAttitude> imu_by_stamp;
  for (std::size_t k = 0; k < imu.size(); ++k) {
    const ImuAttitude& a = imu[k];
    if (!std::isfinite(a.stamp_s) || !std::isfinite(a.roll_rad) || !std::isfinite(a.pitch_rad)) {
      return Error{"IMU sample " + std::to_string(k) + " ('" + a.label +
                   "'): stamp, roll or pitch not finite"};
    }
    imu_by_stamp[a.stamp_s] = a;
  }

  Trajectory t;
  t.options_ = options;
  for (const auto& [stamp, a] : imu_by_stamp) t.imu_.push_back(a);
  std::vector<bool> planar;
  std::string odometry_source;
  for (const auto& [stamp, s] : by_stamp) {
    t.samples_.push_back({stamp, s->T_odom_body});
    planar.push_back(s->source != kAction3D);
    if (odometry_source.empty()) odometry_source = s->source;
  }

  // Planar odometry climbs with the IMU's pitch: z_k = z_k-1 - d tan(pitch), d the step's
  // horizontal length along the mean heading, pitch the mean of the IMU's at both ends.
  if (options.height_from_imu && !t.imu_.empty()) {
    double z = t.samples_.front().T_world_x.translation().z();
    for (std::size_t k = 1; k < t.samples_.size(); ++k) {
      StampedPose& cur = t.samples_[k];
      const StampedPose& prev = t.samples_[k - 1];
      // `prev` already holds the integrated height; the raw step of 3-D odometry is kept.
      const double raw_dz = cur.T_world_x.translation().z() -
                            by_stamp.at(prev.stamp_s)->T_odom_body.translation().z();
      double dz = raw_dz;
      if (planar[k] && planar[k - 1]) {
        double roll = 0.0, pitch_a = 0.0, pitch_b = 0.0;
        const bool has_a = t.ImuTiltAt(prev.stamp_s, &roll, &pitch_a);
        const bool has_b = t.ImuTiltAt(cur.stamp_s, &roll, &pitch_b);
        if (has_a || has_b) {
          const double pitch = has_a && has_b ? 0.5 * (pitch_a + pitch_b)
                               : has_a        ? pitch_a
                                              : pitch_b;
          const double yaw =
              LerpAngle(YawOf(prev.T_world_x.linear()), YawOf(cur.T_world_x.linear()), 0.5);
          const Eigen::Vector3d step = cur.T_world_x.translation() - prev.T_world_x.translation();
          const double d = step.x() * std::cos(yaw) + step.y() * std::sin(yaw);
          dz = -d * std::tan(pitch);
        } else {
          dz = 0.0;  // no tilt known: planar odometry says level
        }
      }
      z += dz;
      cur.T_world_x.translation().z() = z;
    }
  }

  std::string source = "odometry '" + odometry_source + "'";
  if (!t.imu_.empty()) source += " + IMU '" + t.imu_.front().label + "'";
  t.source_ = source;
  return t;
}

Expected<Trajectory> Trajectory::FromPoses(const std::vector<StampedPose>& poses,
                                           const std::string& source,
                                           const TrajectoryOptions& options) {
  if (Status s = options.Validate(); !s) return s.error();
  if (poses.empty()) return Error{source + ": no poses"};
  std::map<double, Eigen::Isometry3d> by_stamp;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    if (!std::isfinite(poses[k].stamp_s) || !poses[k].T_world_x.matrix().allFinite()) {
      return Error{source + ": pose " + std::to_string(k) + ": stamp or pose not finite"};
    }
    by_stamp[poses[k].stamp_s] = poses[k].T_world_x;
  }
  Trajectory t;
  t.options_ = options;
  for (const auto& [stamp, T] : by_stamp) t.samples_.push_back({stamp, T});
  t.source_ = source;
  return t;
}

Expected<Trajectory> Trajectory::FromKitti(const od::io::KittiSequence& sequence,
                                           const TrajectoryOptions& options) {
  const std::string source = (sequence.folder / "poses.txt").string();
  if (!sequence.has_poses) {
    return Error{source + ": missing (test sequences have no poses; give poses another way)"};
  }
  std::vector<StampedPose> poses;
  for (const od::io::KittiFrame& f : sequence.frames) {
    if (!f.T_map_velodyne) {
      return Error{source + ": no pose for scan " + std::to_string(f.index)};
    }
    poses.push_back({f.stamp_s, *f.T_map_velodyne});
  }
  return FromPoses(poses, source, options);
}

bool Trajectory::ImuTiltAt(double stamp_s, double* roll_rad, double* pitch_rad) const {
  if (imu_.empty()) return false;
  const auto after = std::lower_bound(imu_.begin(), imu_.end(), stamp_s,
                                      [](const ImuAttitude& a, double t) { return a.stamp_s < t; });
  const double age = options_.max_imu_age_s;
  const ImuAttitude* b = after != imu_.end() && after->stamp_s - stamp_s <= age ? &*after : nullptr;
  const ImuAttitude* a = after != imu_.begin() && stamp_s - std::prev(after)->stamp_s <= age
                             ? &*std::prev(after)
                             : nullptr;
  if (b != nullptr && b->stamp_s == stamp_s) a = nullptr;  // exact
  if (a != nullptr && b != nullptr) {
    const double f = (stamp_s - a->stamp_s) / (b->stamp_s - a->stamp_s);
    *roll_rad = LerpAngle(a->roll_rad, b->roll_rad, f);
    *pitch_rad = a->pitch_rad + f * (b->pitch_rad - a->pitch_rad);
    return true;
  }
  const ImuAttitude* near = a != nullptr ? a : b;
  if (near == nullptr) return false;
  *roll_rad = near->roll_rad;
  *pitch_rad = near->pitch_rad;
  return true;
}

Expected<BodyPose> Trajectory::PoseAt(double stamp_s) const {
  if (!std::isfinite(stamp_s)) return Error{"no time stamp, so no pose"};
  BodyPose out;
  const double start = start_s(), end = end_s();
  const std::string span =
      "the poses (" + source_ + ") span " + Seconds(start, 6) + " .. " + Seconds(end, 6) + " s";
  if (stamp_s < start || stamp_s > end) {
    out.extrapolated_s = stamp_s < start ? start - stamp_s : stamp_s - end;
    if (out.extrapolated_s > options_.max_extrapolation_s) {
      return Error{"t = " + Seconds(stamp_s, 6) + " s lies " + Seconds(out.extrapolated_s) + " s " +
                   (stamp_s < start ? "before" : "after") + " " + span + " (extrapolation limit " +
                   Seconds(options_.max_extrapolation_s) + " s)"};
    }
    if (samples_.size() == 1) {
      out.T_world_body = samples_.front().T_world_x;
    } else if (stamp_s < start) {
      const StampedPose& a = samples_[0];
      const StampedPose& b = samples_[1];
      out.T_world_body =
          Blend(a.T_world_x, b.T_world_x, (stamp_s - a.stamp_s) / (b.stamp_s - a.stamp_s));
    } else {
      const StampedPose& a = samples_[samples_.size() - 2];
      const StampedPose& b = samples_.back();
      out.T_world_body =
          Blend(a.T_world_x, b.T_world_x, (stamp_s - a.stamp_s) / (b.stamp_s - a.stamp_s));
    }
  } else {
    const auto after =
        std::lower_bound(samples_.begin(), samples_.end(), stamp_s,
                         [](const StampedPose& p, double t) { return p.stamp_s < t; });
    if (after->stamp_s != stamp_s) {
      const double gap = after->stamp_s - std::prev(after)->stamp_s;
      if (options_.max_gap_s > 0.0 && gap > options_.max_gap_s) {
        return Error{"t = " + Seconds(stamp_s, 6) + " s falls in a gap of " + Seconds(gap) +
                     " s between two poses (" + Seconds(std::prev(after)->stamp_s, 6) + " and " +
                     Seconds(after->stamp_s, 6) + " s; limit " + Seconds(options_.max_gap_s) +
                     " s) of " + source_};
      }
    }
    if (after->stamp_s == stamp_s) {
      out.T_world_body = after->T_world_x;
    } else {
      const StampedPose& a = *std::prev(after);
      out.T_world_body = Blend(a.T_world_x, after->T_world_x,
                               (stamp_s - a.stamp_s) / (after->stamp_s - a.stamp_s));
    }
  }
  double roll = 0.0, pitch = 0.0;
  if (ImuTiltAt(stamp_s, &roll, &pitch)) {
    out.T_world_body.linear() = FromYawPitchRoll(YawOf(out.T_world_body.linear()), pitch, roll);
    out.tilt_from_imu = true;
  }
  return out;
}

Expected<Eigen::Isometry3d> Trajectory::T_world_sensor(const Frame& frame) const {
  Expected<BodyPose> body = PoseAt(frame.stamp_s);
  if (!body) {
    std::vector<std::string> about;
    if (!frame.label.empty()) about.push_back("'" + frame.label + "'");
    if (frame.entry >= 0) about.push_back("entry " + std::to_string(frame.entry));
    std::string name = "frame " + std::to_string(frame.index);
    for (std::size_t k = 0; k < about.size(); ++k) name += (k == 0 ? " (" : ", ") + about[k];
    if (!about.empty()) name += ")";
    return Error{name + ": " + body.error().message};
  }
  return body->T_world_body * frame.T_body_sensor;
}

double Trajectory::PathLength() const {
  double length = 0.0;
  for (std::size_t k = 1; k < samples_.size(); ++k) {
    length +=
        (samples_[k].T_world_x.translation() - samples_[k - 1].T_world_x.translation()).norm();
  }
  return length;
}

Expected<std::vector<StampedPose>> ReadTumPoses(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) return Error{path.string() + ": cannot open"};
  std::vector<StampedPose> poses;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const std::size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::string where = path.string() + ":" + std::to_string(number) + ": ";
    std::istringstream fields(line);
    double v[8];
    for (double& x : v) fields >> x;
    std::string rest;
    if (!fields || (fields >> rest)) {
      return Error{where + "expected 8 numbers 'stamp tx ty tz qx qy qz qw', got '" + line + "'"};
    }
    for (const double x : v) {
      if (!std::isfinite(x)) return Error{where + "a value is not finite"};
    }
    const Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      return Error{where + "quaternion norm " + Seconds(q.norm(), 6) + ", expected 1"};
    }
    if (!poses.empty() && !(v[0] > poses.back().stamp_s)) {
      return Error{where + "stamp " + Seconds(v[0], 6) + " s is not after the previous one (" +
                   Seconds(poses.back().stamp_s, 6) + " s)"};
    }
    StampedPose pose;
    pose.stamp_s = v[0];
    pose.T_world_x.linear() = q.normalized().toRotationMatrix();
    pose.T_world_x.translation() << v[1], v[2], v[3];
    poses.push_back(pose);
  }
  if (in.bad()) return Error{path.string() + ": read error"};
  if (poses.empty()) return Error{path.string() + ": no poses"};
  return poses;
}

std::string TumLine(const StampedPose& p) {
  Eigen::Quaterniond q(p.T_world_x.linear());
  q.normalize();
  if (q.w() < 0.0) q.coeffs() *= -1.0;
  const Eigen::Vector3d t = p.T_world_x.translation();
  char line[256];
  std::snprintf(line, sizeof(line), "%.6f %.6f %.6f %.6f %.9f %.9f %.9f %.9f", p.stamp_s, t.x(),
                t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
  return line;
}

Status WriteTumPoses(const std::filesystem::path& path, const std::vector<StampedPose>& poses,
                     const std::string& comment) {
  std::string text;
  std::istringstream lines(comment);
  for (std::string line; std::getline(lines, line);) text += "# " + line + "\n";
  text += "# timestamp tx ty tz qx qy qz qw\n";
  for (const StampedPose& p : poses) text += TumLine(p) + "\n";
  return util::WriteFileAtomic(path, text);
}

Expected<Trajectory> ReadTumTrajectory(const std::filesystem::path& path,
                                       const TrajectoryOptions& options) {
  Expected<std::vector<StampedPose>> poses = ReadTumPoses(path);
  if (!poses) return poses.error();
  return Trajectory::FromPoses(*poses, path.string(), options);
}

}  // namespace cairn::sources
