#include "cairn/sources/asl_dataset.hpp"

#include <yaml-cpp/yaml.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <system_error>

namespace cairn::sources {
namespace {

namespace fs = std::filesystem;

std::string Trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  const auto e = s.find_last_not_of(" \t\r");
  return s.substr(b, e - b + 1);
}

std::vector<std::string> SplitCommas(const std::string& line) {
  std::vector<std::string> out;
  std::string field;
  std::istringstream in(line);
  while (std::getline(in, field, ',')) out.push_back(Trim(field));
  if (!line.empty() && line.back() == ',') out.emplace_back();
  return out;
}

// A CSV file read line by line: '#' lines are comments (the header), blank lines skipped.
// Each row comes with its line number and its fields; errors name file:line and the field.
struct CsvRow {
  int line = 0;
  std::vector<std::string> fields;
};

Expected<std::vector<CsvRow>> ReadCsv(const fs::path& path, const std::vector<std::string>& names) {
  std::ifstream in(path);
  if (!in) return Error{path.string() + ": cannot open (expected an ASL CSV file)"};
  std::vector<CsvRow> rows;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const std::string t = Trim(line);
    if (t.empty() || t[0] == '#') continue;
    CsvRow row{number, SplitCommas(t)};
    if (row.fields.size() != names.size()) {
      return Error{path.string() + ":" + std::to_string(number) + ": expected " +
                   std::to_string(names.size()) + " comma-separated fields (" + names.front() +
                   " .. " + names.back() + "), got " + std::to_string(row.fields.size())};
    }
    rows.push_back(std::move(row));
  }
  if (in.bad()) return Error{path.string() + ": read error"};
  return rows;
}

std::string Where(const fs::path& path, const CsvRow& row, const std::string& field) {
  return path.string() + ":" + std::to_string(row.line) + ": field " + field;
}

Expected<std::int64_t> ParseNs(const fs::path& path, const CsvRow& row, int i,
                               const std::string& name) {
  const std::string& s = row.fields[i];
  std::int64_t v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || v <= 0) {
    return Error{Where(path, row, name) + ": expected a positive integer time in ns, got '" + s +
                 "'"};
  }
  return v;
}

Expected<double> ParseNumber(const fs::path& path, const CsvRow& row, int i,
                             const std::string& name) {
  const std::string& s = row.fields[i];
  double v = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || !std::isfinite(v)) {
    return Error{Where(path, row, name) + ": expected a finite number, got '" + s + "'"};
  }
  return v;
}

// Fields i .. i+2 as a vector.
Expected<Eigen::Vector3d> ParseVector(const fs::path& path, const CsvRow& row, int i,
                                      const std::vector<std::string>& names) {
  Eigen::Vector3d v;
  for (int k = 0; k < 3; ++k) {
    Expected<double> x = ParseNumber(path, row, i + k, names[i + k]);
    if (!x) return x.error();
    v[k] = *x;
  }
  return v;
}

// sensor.yaml: OpenCV's "%YAML:1.0" first line is not YAML 1.2; it is dropped before
// parsing (yaml-cpp reads the rest).
Expected<YAML::Node> LoadSensorYaml(const fs::path& path) {
  std::ifstream in(path);
  if (!in) return Error{path.string() + ": cannot open (expected an ASL sensor.yaml)"};
  std::stringstream text;
  std::string line;
  bool first = true;
  while (std::getline(in, line)) {
    if (first && line.rfind("%YAML", 0) == 0) line = "";
    first = false;
    text << line << '\n';
  }
  try {
    YAML::Node node = YAML::Load(text.str());
    if (!node.IsMap()) return Error{path.string() + ": expected a YAML map"};
    return node;
  } catch (const YAML::Exception& e) {
    return Error{path.string() + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg};
  }
}

Expected<std::vector<double>> Numbers(const fs::path& path, const YAML::Node& node,
                                      const std::string& field, std::size_t count) {
  if (!node || !node.IsSequence() || (count > 0 && node.size() != count)) {
    return Error{path.string() + ": field " + field + ": expected a list of " +
                 (count > 0 ? std::to_string(count) + " " : std::string()) + "numbers"};
  }
  std::vector<double> out;
  for (std::size_t i = 0; i < node.size(); ++i) {
    try {
      out.push_back(node[i].as<double>());
    } catch (const YAML::Exception&) {
      return Error{path.string() + ":" + std::to_string(node[i].Mark().line + 1) + ": field " +
                   field + "[" + std::to_string(i) + "]: expected a number"};
    }
    if (!std::isfinite(out.back())) {
      return Error{path.string() + ": field " + field + "[" + std::to_string(i) +
                   "]: expected a finite number"};
    }
  }
  return out;
}

Expected<double> Number(const fs::path& path, const YAML::Node& map, const std::string& field,
                        bool required) {
  const YAML::Node node = map[field];
  if (!node) {
    if (required) return Error{path.string() + ": field " + field + ": missing (required)"};
    return 0.0;
  }
  try {
    const double v = node.as<double>();
    if (!std::isfinite(v)) throw YAML::Exception(node.Mark(), "not finite");
    return v;
  } catch (const YAML::Exception&) {
    return Error{path.string() + ":" + std::to_string(node.Mark().line + 1) + ": field " + field +
                 ": expected a number"};
  }
}

// T_BS: {cols: 4, rows: 4, data: [16 numbers]}, a rigid transform.
Expected<Eigen::Isometry3d> ReadTbs(const fs::path& path, const YAML::Node& root) {
  const YAML::Node t = root["T_BS"];
  if (!t || !t.IsMap()) return Error{path.string() + ": field T_BS: missing (required)"};
  Expected<std::vector<double>> data = Numbers(path, t["data"], "T_BS.data", 16);
  if (!data) return data.error();
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) M(r, c) = (*data)[4 * r + c];
  }
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-3 || R.determinant() < 0.0 ||
      (M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9) {
    return Error{path.string() + ": field T_BS.data: expected a rigid transform (rotation, "
                                 "translation, last row 0 0 0 1)"};
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  T.translation() = M.topRightCorner<3, 1>();
  return T;
}

Status CheckIncreasing(const fs::path& path, const CsvRow& row, std::int64_t previous,
                       std::int64_t now, const std::string& field) {
  if (previous != 0 && now <= previous) {
    return Error{Where(path, row, field) + ": expected times to increase, got " +
                 std::to_string(now) + " after " + std::to_string(previous)};
  }
  return {};
}

}  // namespace

Expected<AslImu> ReadAslImu(const fs::path& mav0) {
  AslImu imu;
  const fs::path yaml = mav0 / "imu0" / "sensor.yaml";
  Expected<YAML::Node> root = LoadSensorYaml(yaml);
  if (!root) return root.error();
  Expected<Eigen::Isometry3d> T = ReadTbs(yaml, *root);
  if (!T) return T.error();
  imu.T_body_imu = *T;
  Expected<double> rate = Number(yaml, *root, "rate_hz", true);
  if (!rate) return rate.error();
  imu.rate_hz = *rate;
  Expected<double> gyro = Number(yaml, *root, "gyroscope_noise_density", false);
  if (!gyro) return gyro.error();
  imu.gyro_noise_density = *gyro;
  Expected<double> accel = Number(yaml, *root, "accelerometer_noise_density", false);
  if (!accel) return accel.error();
  imu.accel_noise_density = *accel;

  const fs::path csv = mav0 / "imu0" / "data.csv";
  const std::vector<std::string> names = {"timestamp", "w_RS_S_x", "w_RS_S_y", "w_RS_S_z",
                                          "a_RS_S_x",  "a_RS_S_y", "a_RS_S_z"};
  Expected<std::vector<CsvRow>> rows = ReadCsv(csv, names);
  if (!rows) return rows.error();
  imu.samples.reserve(rows->size());
  std::int64_t previous = 0;
  for (const CsvRow& row : *rows) {
    AslImuSample s;
    Expected<std::int64_t> ns = ParseNs(csv, row, 0, names[0]);
    if (!ns) return ns.error();
    if (Status st = CheckIncreasing(csv, row, previous, *ns, names[0]); !st) return st.error();
    previous = *ns;
    s.stamp_ns = *ns;
    s.stamp_s = static_cast<double>(*ns) * 1e-9;
    Expected<Eigen::Vector3d> w = ParseVector(csv, row, 1, names);
    if (!w) return w.error();
    Expected<Eigen::Vector3d> a = ParseVector(csv, row, 4, names);
    if (!a) return a.error();
    s.angular_rate_radps = *w;
    s.specific_force_mps2 = *a;
    imu.samples.push_back(s);
  }
  if (imu.samples.empty()) return Error{csv.string() + ": no samples (expected at least one row)"};
  return imu;
}

Expected<AslCamera> ReadAslCamera(const fs::path& mav0, const std::string& name) {
  AslCamera camera;
  camera.name = name;
  const fs::path yaml = mav0 / name / "sensor.yaml";
  Expected<YAML::Node> root = LoadSensorYaml(yaml);
  if (!root) return root.error();
  Expected<Eigen::Isometry3d> T = ReadTbs(yaml, *root);
  if (!T) return T.error();
  camera.T_body_camera = *T;
  Expected<double> rate = Number(yaml, *root, "rate_hz", true);
  if (!rate) return rate.error();
  camera.rate_hz = *rate;
  Expected<std::vector<double>> resolution = Numbers(yaml, (*root)["resolution"], "resolution", 2);
  if (!resolution) return resolution.error();
  camera.width = static_cast<int>((*resolution)[0]);
  camera.height = static_cast<int>((*resolution)[1]);
  Expected<std::vector<double>> k = Numbers(yaml, (*root)["intrinsics"], "intrinsics", 4);
  if (!k) return k.error();
  camera.fx = (*k)[0];
  camera.fy = (*k)[1];
  camera.cx = (*k)[2];
  camera.cy = (*k)[3];
  if (!(camera.fx > 0.0 && camera.fy > 0.0 && camera.width > 0 && camera.height > 0)) {
    return Error{yaml.string() + ": fields intrinsics/resolution: expected positive focal "
                                 "lengths and size"};
  }
  if (const YAML::Node model = (*root)["distortion_model"]) {
    camera.distortion_model = model.as<std::string>("");
    Expected<std::vector<double>> d =
        Numbers(yaml, (*root)["distortion_coefficients"], "distortion_coefficients", 0);
    if (!d) return d.error();
    camera.distortion = *d;
  }
  const fs::path csv = mav0 / name / "data.csv";
  Expected<std::vector<CsvRow>> rows = ReadCsv(csv, {"timestamp", "filename"});
  if (!rows) return rows.error();
  std::int64_t previous = 0;
  for (const CsvRow& row : *rows) {
    AslImage image;
    Expected<std::int64_t> ns = ParseNs(csv, row, 0, "timestamp");
    if (!ns) return ns.error();
    if (Status st = CheckIncreasing(csv, row, previous, *ns, "timestamp"); !st) return st.error();
    previous = *ns;
    if (row.fields[1].empty()) return Error{Where(csv, row, "filename") + ": expected a file name"};
    image.stamp_ns = *ns;
    image.stamp_s = static_cast<double>(*ns) * 1e-9;
    image.path = mav0 / name / "data" / row.fields[1];
    std::error_code ec;
    image.exists = fs::is_regular_file(image.path, ec);
    camera.images.push_back(std::move(image));
  }
  return camera;
}

Expected<AslDataset> ReadAslDataset(const fs::path& mav0) {
  AslDataset dataset;
  dataset.mav0 = mav0;
  Expected<AslImu> imu = ReadAslImu(mav0);
  if (!imu) return imu.error();
  dataset.imu = std::move(*imu);
  for (int i = 0;; ++i) {
    const std::string name = "cam" + std::to_string(i);
    std::error_code ec;
    if (!fs::is_directory(mav0 / name, ec)) break;
    Expected<AslCamera> camera = ReadAslCamera(mav0, name);
    if (!camera) return camera.error();
    dataset.cameras.push_back(std::move(*camera));
  }
  return dataset;
}

Expected<std::vector<AslGroundTruth>> ReadOpenVinsGroundTruth(const fs::path& csv) {
  const std::vector<std::string> names = {"time(ns)", "px",  "py",  "pz",  "qw",  "qx",
                                          "qy",       "qz",  "vx",  "vy",  "vz",  "bwx",
                                          "bwy",      "bwz", "bax", "bay", "baz"};
  Expected<std::vector<CsvRow>> rows = ReadCsv(csv, names);
  if (!rows) return rows.error();
  std::vector<AslGroundTruth> out;
  out.reserve(rows->size());
  std::int64_t previous = 0;
  for (const CsvRow& row : *rows) {
    AslGroundTruth g;
    Expected<std::int64_t> ns = ParseNs(csv, row, 0, names[0]);
    if (!ns) return ns.error();
    if (Status st = CheckIncreasing(csv, row, previous, *ns, names[0]); !st) return st.error();
    previous = *ns;
    g.stamp_ns = *ns;
    g.stamp_s = static_cast<double>(*ns) * 1e-9;
    double v[16];
    for (int i = 0; i < 16; ++i) {
      Expected<double> x = ParseNumber(csv, row, i + 1, names[i + 1]);
      if (!x) return x.error();
      v[i] = *x;
    }
    g.p_world_body = Eigen::Vector3d(v[0], v[1], v[2]);
    const Eigen::Quaterniond q(v[3], v[4], v[5], v[6]);
    if (!(q.norm() > 0.5)) {
      return Error{Where(csv, row, "qw..qz") + ": expected a unit quaternion, got norm " +
                   std::to_string(q.norm())};
    }
    g.q_world_body = q.normalized();
    g.v_world_mps = Eigen::Vector3d(v[7], v[8], v[9]);
    g.gyro_bias_radps = Eigen::Vector3d(v[10], v[11], v[12]);
    g.accel_bias_mps2 = Eigen::Vector3d(v[13], v[14], v[15]);
    out.push_back(g);
  }
  if (out.empty()) return Error{csv.string() + ": no rows (expected ground-truth poses)"};
  return out;
}

}  // namespace cairn::sources
