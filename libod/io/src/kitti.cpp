#include "cairn/od/io/kitti.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <charconv>
#include <cmath>
#include <map>
#include <string_view>

#include "cairn/util/yaml.hpp"
#include "text_fields.hpp"

namespace cairn::od::io {
namespace {

constexpr double kRotationTolerance = 1e-3;  // KITTI prints rotations to 7 digits or more

using detail::Tokens;

// A whole field as a finite number.
bool ParseFinite(std::string_view token, double* value) {
  return detail::ParseNumber(token, value) && std::isfinite(*value);
}

// Calls `per_line(line_number, line)` for every line of `text`, stopping at an error.
template <typename F>
Status ForEachLine(const std::string& text, F per_line) {
  std::size_t pos = 0;
  int line_number = 0;
  while (pos < text.size()) {
    std::size_t eol = text.find('\n', pos);
    if (eol == std::string::npos) eol = text.size();
    ++line_number;
    if (Status s = per_line(line_number, std::string_view(text.data() + pos, eol - pos)); !s) {
      return s;
    }
    pos = eol + 1;
  }
  return Status::Ok();
}

// 12 numbers, row-major, into a 3x4 matrix.
Expected<Eigen::Matrix<double, 3, 4>> Parse3x4(const std::vector<std::string_view>& tokens,
                                               std::size_t first, const std::string& where) {
  const std::size_t count = tokens.size() - first;
  if (count != 12) {
    return Error{where + ": " + std::to_string(count) +
                 " values, expected 12 (a row-major 3x4 matrix)"};
  }
  Eigen::Matrix<double, 3, 4> m;
  for (int k = 0; k < 12; ++k) {
    double v = 0.0;
    if (!ParseFinite(tokens[first + k], &v)) {
      return Error{where + ": value " + std::to_string(k + 1) + " '" +
                   std::string(tokens[first + k]) + "' is not a finite number"};
    }
    m(k / 4, k % 4) = v;
  }
  return m;
}

// [R | t] as a rigid transform, R checked for orthonormality.
Expected<Eigen::Isometry3d> RigidFrom3x4(const Eigen::Matrix<double, 3, 4>& m,
                                         const std::string& where) {
  const Eigen::Matrix3d R = m.leftCols<3>();
  const double error = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!(error <= kRotationTolerance) || R.determinant() < 0.0) {
    return Error{where + ": the 3x3 part is not a rotation (|R^T R - I| = " +
                 std::to_string(error) + ", det " + std::to_string(R.determinant()) +
                 "), expected an orthonormal matrix with det +1"};
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = m.col(3);
  return T;
}

}  // namespace

Expected<KittiCalibration> ReadKittiCalibration(const std::filesystem::path& path) {
  const std::string name = path.string();
  Expected<std::string> text = util::ReadTextFile(path);
  if (!text) return text.error();
  std::map<std::string, Eigen::Matrix<double, 3, 4>> matrices;
  std::map<std::string, int> lines;
  Status parsed = ForEachLine(*text, [&](int line_number, std::string_view line) -> Status {
    const std::vector<std::string_view> t = Tokens(line);
    if (t.empty()) return Status::Ok();
    const std::string where = name + ": line " + std::to_string(line_number);
    if (t[0].size() < 2 || t[0].back() != ':') {
      return Error{where + ": expected 'KEY: 12 numbers', got '" + std::string(t[0]) + "'"};
    }
    const std::string key(t[0].substr(0, t[0].size() - 1));
    if (key != "P0" && key != "P1" && key != "P2" && key != "P3" && key != "Tr") {
      return Status::Ok();
    }
    if (matrices.count(key)) {
      return Error{where + ": key '" + key + "' appears twice (first on line " +
                   std::to_string(lines[key]) + ")"};
    }
    Expected<Eigen::Matrix<double, 3, 4>> m = Parse3x4(t, 1, where + " (" + key + ")");
    if (!m) return m.error();
    matrices[key] = *m;
    lines[key] = line_number;
    return Status::Ok();
  });
  if (!parsed) return parsed.error();
  KittiCalibration calibration;
  for (int k = 0; k < 4; ++k) {
    const std::string key = "P" + std::to_string(k);
    if (!matrices.count(key)) {
      return Error{name + ": key '" + key +
                   "' is missing (expected 'P0:' .. 'P3:' and 'Tr:', "
                   "each with 12 numbers)"};
    }
    calibration.P[k] = matrices[key];
  }
  if (!matrices.count("Tr")) {
    return Error{name + ": key 'Tr' is missing (the velodyne -> cam0 transform, 12 numbers)"};
  }
  Expected<Eigen::Isometry3d> Tr =
      RigidFrom3x4(matrices["Tr"], name + ": line " + std::to_string(lines["Tr"]) + " (Tr)");
  if (!Tr) return Tr.error();
  calibration.T_cam0_velodyne = *Tr;
  return calibration;
}

Expected<std::vector<Eigen::Isometry3d>> ReadKittiPoses(const std::filesystem::path& path) {
  const std::string name = path.string();
  Expected<std::string> text = util::ReadTextFile(path);
  if (!text) return text.error();
  std::vector<Eigen::Isometry3d> poses;
  Status parsed = ForEachLine(*text, [&](int line_number, std::string_view line) -> Status {
    const std::vector<std::string_view> t = Tokens(line);
    if (t.empty()) return Status::Ok();
    const std::string where = name + ": line " + std::to_string(line_number);
    if (static_cast<int>(poses.size()) + 1 != line_number) {
      return Error{where +
                   ": a pose after an empty line (expected one pose per line, frame "
                   "k on line k + 1)"};
    }
    Expected<Eigen::Matrix<double, 3, 4>> m = Parse3x4(t, 0, where);
    if (!m) return m.error();
    Expected<Eigen::Isometry3d> T = RigidFrom3x4(*m, where);
    if (!T) return T.error();
    poses.push_back(*T);
    return Status::Ok();
  });
  if (!parsed) return parsed.error();
  if (poses.empty()) return Error{name + ": no poses (expected 12 numbers per line)"};
  return poses;
}

Expected<std::vector<double>> ReadKittiTimes(const std::filesystem::path& path) {
  const std::string name = path.string();
  Expected<std::string> text = util::ReadTextFile(path);
  if (!text) return text.error();
  std::vector<double> times;
  Status parsed = ForEachLine(*text, [&](int line_number, std::string_view line) -> Status {
    const std::vector<std::string_view> t = Tokens(line);
    if (t.empty()) return Status::Ok();
    const std::string where = name + ": line " + std::to_string(line_number);
    if (static_cast<int>(times.size()) + 1 != line_number) {
      return Error{where + ": a stamp after an empty line (expected one stamp per line)"};
    }
    double v = 0.0;
    if (t.size() != 1 || !ParseFinite(t[0], &v)) {
      return Error{where + ": expected one finite time stamp [s], got '" + std::string(line) + "'"};
    }
    if (!times.empty() && v < times.back()) {
      return Error{where + ": stamp " + std::string(t[0]) + " is earlier than the line before"};
    }
    times.push_back(v);
    return Status::Ok();
  });
  if (!parsed) return parsed.error();
  if (times.empty()) return Error{name + ": no time stamps (expected one number per line)"};
  return times;
}

Expected<KittiSequence> OpenKittiSequence(const std::filesystem::path& folder) {
  std::error_code ec;
  if (!std::filesystem::is_directory(folder, ec)) {
    return Error{folder.string() +
                 ": not a folder (expected a KITTI sequence: velodyne/, "
                 "calib.txt, times.txt, poses.txt)"};
  }
  const std::filesystem::path velodyne = folder / "velodyne";
  if (!std::filesystem::is_directory(velodyne, ec)) {
    return Error{velodyne.string() + ": no such folder (expected the scans NNNNNN.bin)"};
  }
  KittiSequence sequence;
  sequence.folder = folder;
  for (const auto& entry : std::filesystem::directory_iterator(velodyne, ec)) {
    const std::filesystem::path& p = entry.path();
    if (p.extension() != ".bin") continue;
    const std::string stem = p.stem().string();
    int index = -1;
    const std::from_chars_result r = std::from_chars(stem.data(), stem.data() + stem.size(), index);
    if (stem.empty() || r.ec != std::errc() || r.ptr != stem.data() + stem.size() || index < 0) {
      return Error{p.string() + ": scan name is not a frame number (expected NNNNNN.bin)"};
    }
    KittiFrame frame;
    frame.index = index;
    frame.scan = p;
    sequence.frames.push_back(frame);
  }
  if (ec) return Error{velodyne.string() + ": cannot list: " + ec.message()};
  if (sequence.frames.empty()) return Error{velodyne.string() + ": no scans (NNNNNN.bin)"};
  std::sort(sequence.frames.begin(), sequence.frames.end(),
            [](const KittiFrame& a, const KittiFrame& b) { return a.index < b.index; });
  const int last = sequence.frames.back().index;

  Expected<KittiCalibration> calibration = ReadKittiCalibration(folder / "calib.txt");
  if (!calibration) return calibration.error();
  sequence.calibration = *calibration;
  Expected<std::vector<double>> times = ReadKittiTimes(folder / "times.txt");
  if (!times) return times.error();
  if (static_cast<int>(times->size()) <= last) {
    return Error{(folder / "times.txt").string() + ": " + std::to_string(times->size()) +
                 " stamps, but scan " + std::to_string(last) + " needs line " +
                 std::to_string(last + 1)};
  }
  std::vector<Eigen::Isometry3d> poses;
  if (std::filesystem::exists(folder / "poses.txt", ec)) {
    Expected<std::vector<Eigen::Isometry3d>> read = ReadKittiPoses(folder / "poses.txt");
    if (!read) return read.error();
    if (static_cast<int>(read->size()) <= last) {
      return Error{(folder / "poses.txt").string() + ": " + std::to_string(read->size()) +
                   " poses, but scan " + std::to_string(last) + " needs line " +
                   std::to_string(last + 1)};
    }
    poses = std::move(*read);
    sequence.has_poses = true;
  }
  const Eigen::Isometry3d& Tr = sequence.calibration.T_cam0_velodyne;
  const Eigen::Isometry3d Tr_inverse = Tr.inverse();
  for (KittiFrame& frame : sequence.frames) {
    frame.stamp_s = (*times)[frame.index];
    if (!sequence.has_poses) continue;
    const Eigen::Isometry3d& pose = poses[frame.index];
    frame.T_cam0start_cam0 = pose;
    frame.T_cam0start_velodyne = pose * Tr;
    frame.T_map_velodyne = Tr_inverse * pose * Tr;
  }
  return sequence;
}

Expected<std::vector<KittiFrame>> SelectKittiFrames(const KittiSequence& sequence,
                                                    const std::string& range) {
  const auto bad = [&](const std::string& why) {
    return Error{"--frames '" + range + "': " + why + " (expected A:B, A:, :B or A)"};
  };
  int first = std::numeric_limits<int>::min(), last = std::numeric_limits<int>::max();
  auto parse = [](std::string_view text, int* value) {
    const std::from_chars_result r =
        std::from_chars(text.data(), text.data() + text.size(), *value);
    return !text.empty() && r.ec == std::errc() && r.ptr == text.data() + text.size() &&
           *value >= 0;
  };
  const std::size_t colon = range.find(':');
  if (colon == std::string::npos) {
    if (!parse(range, &first)) return bad("not a frame number");
    last = first;
  } else {
    const std::string_view a(range.data(), colon);
    const std::string_view b(range.data() + colon + 1, range.size() - colon - 1);
    if (!a.empty() && !parse(a, &first))
      return bad("'" + std::string(a) + "' is not a frame number");
    if (!b.empty() && !parse(b, &last))
      return bad("'" + std::string(b) + "' is not a frame number");
  }
  if (first > last) return bad("the first frame is after the last");
  std::vector<KittiFrame> selected;
  for (const KittiFrame& frame : sequence.frames) {
    if (frame.index >= first && frame.index <= last) selected.push_back(frame);
  }
  if (selected.empty()) {
    return bad("no scan of " + sequence.folder.string() + " in that range (it has frames " +
               std::to_string(sequence.frames.front().index) + " to " +
               std::to_string(sequence.frames.back().index) + ")");
  }
  return selected;
}

}  // namespace cairn::od::io
