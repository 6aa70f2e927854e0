// The ASL ("EuRoC") folder layout that many visual-inertial data sets share:
//
//   mav0/imu0/data.csv      #timestamp [ns], w_RS_S_x, w_RS_S_y, w_RS_S_z [rad/s],
//                           a_RS_S_x, a_RS_S_y, a_RS_S_z [m/s^2]   (IMU frame S)
//   mav0/imu0/sensor.yaml   T_BS (IMU on the body), rate_hz, noise densities
//   mav0/camN/data.csv      #timestamp [ns], filename   (images in camN/data/)
//   mav0/camN/sensor.yaml   T_BS, rate_hz, resolution, intrinsics [fu, fv, cu, cv],
//                           distortion_model, distortion_coefficients
// and OpenVINS' ground-truth CSV (ov_data/euroc_mav/*.csv):
//   time(ns), px, py, pz [m], qw, qx, qy, qz, vx, vy, vz [m/s], bwx, bwy, bwz [rad/s],
//   bax, bay, baz [m/s^2]: the IMU/body pose in a gravity-aligned world (z up), Hamilton
//   quaternion body -> world (p_W = R(q) p_B), its world velocity and the IMU biases.
//
// Stamps are kept as the files give them (ns since the Unix epoch) and as seconds.
// T_BS maps sensor points into the body: p_B = T_BS p_S. Camera frames are optical (x
// right, y down, z forward). The accelerometer gives specific force, gravity included
// (+9.8 m/s^2 along up at rest). No MRPT or OpenCV here; images are listed, not read.
// Bad input gives an error naming the file, the line and the field.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"

namespace cairn::sources {

struct AslImuSample {
  std::int64_t stamp_ns = 0;
  double stamp_s = 0.0;
  Eigen::Vector3d angular_rate_radps = Eigen::Vector3d::Zero();   ///< w_RS_S
  Eigen::Vector3d specific_force_mps2 = Eigen::Vector3d::Zero();  ///< a_RS_S
};

struct AslImu {
  std::vector<AslImuSample> samples;  ///< in file order, stamps strictly increasing
  Eigen::Isometry3d T_body_imu = Eigen::Isometry3d::Identity();  ///< T_BS
  double rate_hz = 0.0;
  double gyro_noise_density = 0.0;   ///< [rad/s/sqrt(Hz)], 0 when not given
  double accel_noise_density = 0.0;  ///< [m/s^2/sqrt(Hz)], 0 when not given
};

struct AslImage {
  std::int64_t stamp_ns = 0;
  double stamp_s = 0.0;
  std::filesystem::path path;  ///< camN/data/<filename>
  bool exists = false;         ///< the listing may name images a trimmed copy lacks
};

struct AslCamera {
  std::string name;  ///< "cam0"
  std::vector<AslImage> images;
  Eigen::Isometry3d T_body_camera = Eigen::Isometry3d::Identity();  ///< T_BS
  double rate_hz = 0.0;
  int width = 0, height = 0;
  double fx = 0.0, fy = 0.0, cx = 0.0, cy = 0.0;  ///< pinhole intrinsics [px]
  std::string distortion_model;                  ///< "radial-tangential", ...
  std::vector<double> distortion;                ///< as the file lists them
};

struct AslGroundTruth {
  std::int64_t stamp_ns = 0;
  double stamp_s = 0.0;
  Eigen::Vector3d p_world_body = Eigen::Vector3d::Zero();  ///< [m]
  Eigen::Quaterniond q_world_body = Eigen::Quaterniond::Identity();
  Eigen::Vector3d v_world_mps = Eigen::Vector3d::Zero();
  Eigen::Vector3d gyro_bias_radps = Eigen::Vector3d::Zero();
  Eigen::Vector3d accel_bias_mps2 = Eigen::Vector3d::Zero();
};

struct AslDataset {
  std::filesystem::path mav0;
  AslImu imu;
  std::vector<AslCamera> cameras;  ///< cam0, cam1, ... as present
};

/// imu0/data.csv and imu0/sensor.yaml under `mav0`.
Expected<AslImu> ReadAslImu(const std::filesystem::path& mav0);
/// camN/data.csv and camN/sensor.yaml under `mav0`.
Expected<AslCamera> ReadAslCamera(const std::filesystem::path& mav0, const std::string& name);
/// The IMU and every camN folder present.
Expected<AslDataset> ReadAslDataset(const std::filesystem::path& mav0);
/// OpenVINS' ground-truth CSV (17 columns, see above); the quaternion is normalised and
/// must not be zero.
Expected<std::vector<AslGroundTruth>> ReadOpenVinsGroundTruth(const std::filesystem::path& csv);

}  // namespace cairn::sources
