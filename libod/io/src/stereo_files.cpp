#include "cairn/od/io/stereo_files.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <exception>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "cairn/od/io/limits.hpp"
#include "cairn/od/leveling.hpp"
#include "cairn/od/units.hpp"
#include "cairn/util/format.hpp"
#include "cairn/util/image_file.hpp"
#include "cairn/util/yaml.hpp"
#include "png.hpp"

namespace cairn::od::io {
namespace {

constexpr double kMaxBaselineM = 10.0;

// ---------------------------------------------------------------------------------------
// cairn's stereo YAML

Expected<double> RequiredNumber(const util::FieldReader& reader, const YAML::Node& node,
                                const std::string& field, const char* what) {
  if (!node) return reader.Fail(field, std::string("missing (expected ") + what + ")");
  return reader.Double(node, field);
}

Expected<int> RequiredSize(const util::FieldReader& reader, const YAML::Node& node,
                           const std::string& field) {
  if (!node) return reader.Fail(field, "missing (expected a positive integer [px])");
  Expected<std::int64_t> v = reader.Integer(node, field);
  if (!v) return v.error();
  if (*v <= 0 || *v > kMaxImageSide) {
    return reader.Fail(field, "expected a positive integer [px] up to " +
                                  std::to_string(kMaxImageSide) + ", got " + util::Describe(node));
  }
  return static_cast<int>(*v);
}

/// up: [x, y, z], or pitch_deg (+ roll_deg), or neither (nullopt).
Expected<std::optional<Eigen::Vector3d>> ReadUp(const util::FieldReader& reader,
                                                const YAML::Node& root) {
  const YAML::Node up_node = root["up"];
  const bool has_pitch = static_cast<bool>(root["pitch_deg"]);
  const bool has_roll = static_cast<bool>(root["roll_deg"]);
  if (up_node && (has_pitch || has_roll)) {
    return reader.Fail(has_pitch ? "pitch_deg" : "roll_deg",
                       "give either up or pitch_deg/roll_deg, not both");
  }
  if (up_node) {
    if (!up_node.IsSequence() || up_node.size() != 3) {
      return reader.Fail("up",
                         "expected a sequence of 3 numbers [x, y, z] in the optical frame, got " +
                             util::Describe(up_node));
    }
    Eigen::Vector3d up;
    for (int i = 0; i < 3; ++i) {
      Expected<double> v = reader.Double(up_node[i], "up[" + std::to_string(i) + "]");
      if (!v) return v.error();
      up[i] = *v;
    }
    if (!(up.norm() > 1e-9)) {
      return reader.Fail("up", "must not be the zero vector (it is gravity's up direction)");
    }
    return std::optional<Eigen::Vector3d>(up.normalized());
  }
  if (has_roll && !has_pitch) {
    return reader.Fail("pitch_deg", "missing: roll_deg is given, pitch_deg must be too");
  }
  if (!has_pitch) return std::optional<Eigen::Vector3d>();
  Expected<double> pitch = util::Angle(reader, root["pitch_deg"], "pitch_deg", 90.0);
  if (!pitch) return pitch.error();
  double roll = 0.0;
  if (has_roll) {
    Expected<double> r = util::Angle(reader, root["roll_deg"], "roll_deg", 90.0);
    if (!r) return r.error();
    roll = *r;
  }
  return std::optional<Eigen::Vector3d>(
      CameraUpFromPitchRoll(*pitch * kDegToRad, roll * kDegToRad));
}

Status CheckBaseline(const std::string& source, const std::string& field, double baseline_m) {
  if (!std::isfinite(baseline_m) || baseline_m <= 0.0) {
    return Error{source + ": " + field + ": expected a positive baseline [m], got " +
                 util::Number(baseline_m)};
  }
  if (baseline_m > kMaxBaselineM) {
    return Error{source + ": " + field + ": baseline " + util::Number(baseline_m) +
                 " is implausible in metres (more than " + util::Number(kMaxBaselineM) +
                 " m); give it in metres (a calibration board measured in millimetres gives "
                 "millimetres: divide by 1000)"};
  }
  return Status::Ok();
}

// ---------------------------------------------------------------------------------------
// OpenCV FileStorage

bool LooksLikeOpenCv(const std::string& text) {
  const std::size_t start = text.find_first_not_of(" \t\r\n");
  if (start == std::string::npos) return false;
  return text.compare(start, 5, "%YAML") == 0 || text.compare(start, 5, "<?xml") == 0 ||
         text.find("opencv-matrix") != std::string::npos ||
         text.find("<opencv_storage>") != std::string::npos;
}

/// Every whitespace-separated token a number: the K.txt layout.
bool LooksLikeNumbers(const std::string& text) {
  std::istringstream in(text);
  std::string token;
  bool any = false;
  while (in >> token) {
    char* end = nullptr;
    std::strtod(token.c_str(), &end);
    if (end != token.c_str() + token.size()) return false;
    any = true;
  }
  return any;
}

Expected<cv::Mat> ReadMatrix(const cv::FileStorage& fs, const std::string& source,
                             const std::string& key, const std::string& expected) {
  const cv::FileNode node = fs[key];
  if (node.empty() || node.isNone()) {
    return Error{source + ": " + key + ": missing (expected " + expected + ")"};
  }
  cv::Mat m;
  if (node.isSeq()) {
    // A plain list of numbers ([k1, k2, p1, p2, k3]; 9 entries of a 3x3 matrix row by row).
    std::vector<double> values;
    for (const cv::FileNode& item : node) {
      if (!item.isReal() && !item.isInt()) {
        return Error{source + ": " + key + ": expected " + expected + ", a list of numbers"};
      }
      values.push_back(static_cast<double>(item));
    }
    m = cv::Mat(values, true).reshape(1, 1);
    if (values.size() == 9 && (key == "M1" || key == "M2" || key == "R")) m = m.reshape(1, 3);
  } else {
    try {
      node >> m;
    } catch (const cv::Exception&) {
      m.release();
    }
  }
  if (m.empty()) {
    return Error{source + ": " + key + ": expected " + expected + ", not readable as a matrix"};
  }
  m.convertTo(m, CV_64F);
  for (auto it = m.begin<double>(); it != m.end<double>(); ++it) {
    if (!std::isfinite(*it)) return Error{source + ": " + key + ": has a non-finite entry"};
  }
  return m;
}

Expected<int> ReadPositiveInt(const cv::FileNode& node, const std::string& source,
                              const std::string& field) {
  if (!node.isInt() && !node.isReal()) {
    return Error{source + ": " + field + ": expected a positive integer [px]"};
  }
  const double v = static_cast<double>(node);
  if (!(v >= 1.0) || v != std::floor(v) || v > kMaxImageSide) {
    return Error{source + ": " + field + ": expected a positive integer [px], got " +
                 util::Number(v)};
  }
  return static_cast<int>(v);
}

Expected<cv::Size> ReadImageSize(const cv::FileStorage& fs, const std::string& source) {
  const cv::FileNode size = fs["image_size"];
  if (!size.empty() && !size.isNone()) {
    if (!size.isSeq() || size.size() != 2) {
      return Error{source + ": image_size: expected [width, height] [px]"};
    }
    Expected<int> w = ReadPositiveInt(size[0], source, "image_size[0]");
    if (!w) return w.error();
    Expected<int> h = ReadPositiveInt(size[1], source, "image_size[1]");
    if (!h) return h.error();
    return cv::Size(*w, *h);
  }
  const cv::FileNode width = fs["image_width"];
  const cv::FileNode height = fs["image_height"];
  if (width.empty() || width.isNone()) {
    return Error{source +
                 ": image_width: missing (expected the raw image size as image_width "
                 "and image_height, or image_size: [width, height] [px])"};
  }
  if (height.empty() || height.isNone()) {
    return Error{source + ": image_height: missing (expected with image_width [px])"};
  }
  Expected<int> w = ReadPositiveInt(width, source, "image_width");
  if (!w) return w.error();
  Expected<int> h = ReadPositiveInt(height, source, "image_height");
  if (!h) return h.error();
  return cv::Size(*w, *h);
}

Status CheckIntrinsicMatrix(const cv::Mat& K, const std::string& source, const std::string& key) {
  const double fx = K.at<double>(0, 0), fy = K.at<double>(1, 1);
  if (!(fx > 0.0) || !(fy > 0.0)) {
    return Error{source + ": " + key + ": focal lengths K[0][0] and K[1][1] must be positive [px]"};
  }
  if (K.at<double>(1, 0) != 0.0 || K.at<double>(2, 0) != 0.0 || K.at<double>(2, 1) != 0.0 ||
      K.at<double>(2, 2) != 1.0) {
    return Error{source + ": " + key +
                 ": expected an upper-triangular intrinsic matrix with K[2][2] = 1"};
  }
  return Status::Ok();
}

std::vector<double> ToVector(const cv::Mat& m) {
  std::vector<double> v;
  for (auto it = m.begin<double>(); it != m.end<double>(); ++it) v.push_back(*it);
  return v;
}

Eigen::Matrix3d ToEigen3(const cv::Mat& m) {
  Eigen::Matrix3d e;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) e(r, c) = m.at<double>(r, c);
  }
  return e;
}

}  // namespace

// -----------------------------------------------------------------------------------------
// Calibration files

Expected<StereoCalibration> ParseStereoCalibrationYaml(const std::string& yaml_text,
                                                       const std::string& source) {
  Expected<YAML::Node> root = util::ParseYaml(yaml_text, source);
  if (!root) return root.error();
  const util::FieldReader reader(source);
  if (Status s = reader.CheckMapping(
          *root, "",
          {"width", "height", "fx", "fy", "cx", "cy", "baseline", "up", "pitch_deg", "roll_deg"});
      !s) {
    return s.error();
  }
  const YAML::Node& node = *root;
  StereoCalibration calib;
  PinholeModel& m = calib.model;
  Expected<int> w = RequiredSize(reader, node["width"], "width");
  if (!w) return w.error();
  Expected<int> h = RequiredSize(reader, node["height"], "height");
  if (!h) return h.error();
  m.width = *w;
  m.height = *h;
  Expected<double> fx = RequiredNumber(reader, node["fx"], "fx", "a focal length [px]");
  if (!fx) return fx.error();
  m.fx = *fx;
  m.fy = *fx;
  if (node["fy"]) {
    Expected<double> fy = reader.Double(node["fy"], "fy");
    if (!fy) return fy.error();
    m.fy = *fy;
  }
  Expected<double> cx = RequiredNumber(reader, node["cx"], "cx", "a principal point column [px]");
  if (!cx) return cx.error();
  Expected<double> cy = RequiredNumber(reader, node["cy"], "cy", "a principal point row [px]");
  if (!cy) return cy.error();
  m.cx = *cx;
  m.cy = *cy;
  if (!(m.fx > 0.0 && m.fx <= 1e6)) {
    return reader.Fail("fx", "expected a focal length in (0, 1e6] px, got " + util::Number(m.fx));
  }
  if (!(m.fy > 0.0 && m.fy <= 1e6)) {
    return reader.Fail("fy", "expected a focal length in (0, 1e6] px, got " + util::Number(m.fy));
  }
  if (!(m.cx >= -m.width && m.cx <= 2.0 * m.width)) {
    return reader.Fail("cx", "expected a principal point column in [-width, 2 width] px, got " +
                                 util::Number(m.cx));
  }
  if (!(m.cy >= -m.height && m.cy <= 2.0 * m.height)) {
    return reader.Fail("cy", "expected a principal point row in [-height, 2 height] px, got " +
                                 util::Number(m.cy));
  }
  Expected<double> baseline =
      RequiredNumber(reader, node["baseline"], "baseline", "the distance between the cameras [m]");
  if (!baseline) return baseline.error();
  if (Status s = CheckBaseline(source, "baseline", *baseline); !s) return s.error();
  calib.baseline_m = *baseline;
  Expected<std::optional<Eigen::Vector3d>> up = ReadUp(reader, node);
  if (!up) return up.error();
  calib.up = *up;
  if (Status s = m.Validate(); !s) return Error{source + ": " + s.message()};
  return calib;
}

Expected<StereoCalibration> ParseFoundationStereoK(const std::string& text,
                                                   const std::string& source) {
  std::vector<std::vector<double>> lines;
  std::istringstream in(text);
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    std::istringstream words(line);
    std::vector<double> values;
    std::string token;
    while (words >> token) {
      char* end = nullptr;
      const double v = std::strtod(token.c_str(), &end);
      if (end != token.c_str() + token.size() || !std::isfinite(v)) {
        return Error{source + ": line " + std::to_string(line_number) + ": '" + token +
                     "' is not a number (K.txt: line 1 the 9 entries of K, line 2 the baseline "
                     "[m])"};
      }
      values.push_back(v);
    }
    if (!values.empty()) lines.push_back(values);
  }
  if (lines.empty() || lines[0].size() != 9) {
    return Error{source + ": line 1: K: expected the 9 entries of the 3x3 intrinsic matrix, got " +
                 std::to_string(lines.empty() ? 0 : lines[0].size()) + " numbers"};
  }
  if (lines.size() < 2) {
    return Error{source + ": line 2: baseline: missing (expected the baseline [m])"};
  }
  if (lines[1].size() != 1 || lines.size() > 2) {
    return Error{source +
                 ": line 2: baseline: expected one number, the baseline [m], and "
                 "nothing after it"};
  }
  const std::vector<double>& k = lines[0];
  StereoCalibration calib;
  calib.model.fx = k[0];
  calib.model.fy = k[4];
  calib.model.cx = k[2];
  calib.model.cy = k[5];
  if (!(k[0] > 0.0) || !(k[4] > 0.0)) {
    return Error{source + ": line 1: K: focal lengths K[0][0] and K[1][1] must be positive [px]"};
  }
  if (k[1] != 0.0 || k[3] != 0.0 || k[6] != 0.0 || k[7] != 0.0 || k[8] != 1.0) {
    return Error{source + ": line 1: K: expected [fx 0 cx; 0 fy cy; 0 0 1] (no skew)"};
  }
  if (Status s = CheckBaseline(source, "line 2: baseline", lines[1][0]); !s) return s.error();
  calib.baseline_m = lines[1][0];
  return calib;
}

Expected<StereoCalibration> ParseOpenCvStereoCalibration(const std::string& text,
                                                         const std::string& source) {
  cv::FileStorage fs;
  try {
    // OpenCV tells YAML from XML and JSON by the first line; plain YAML has no %YAML line.
    const std::size_t start = text.find_first_not_of(" \t\r\n");
    const bool headed = start != std::string::npos && (text.compare(start, 5, "%YAML") == 0 ||
                                                       text[start] == '<' || text[start] == '{');
    fs.open(headed ? text : "%YAML:1.0\n" + text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
  } catch (const cv::Exception& e) {
    return Error{source + ": not a readable OpenCV calibration file (cv::FileStorage: " + e.err +
                 ")"};
  } catch (const std::exception& e) {
    // OpenCV 4.6's YAML parser lets std::length_error and the like escape on some malformed
    // text (found by fuzz_stereo_calib).
    return Error{source + ": not a readable OpenCV calibration file (cv::FileStorage: " + e.what() +
                 ")"};
  }
  if (!fs.isOpened()) return Error{source + ": not a readable OpenCV calibration file"};

  Expected<cv::Mat> M1 = ReadMatrix(fs, source, "M1", "the left 3x3 intrinsic matrix");
  if (!M1) return M1.error();
  Expected<cv::Mat> D1 = ReadMatrix(fs, source, "D1", "the left distortion coefficients");
  if (!D1) return D1.error();
  Expected<cv::Mat> M2 = ReadMatrix(fs, source, "M2", "the right 3x3 intrinsic matrix");
  if (!M2) return M2.error();
  Expected<cv::Mat> D2 = ReadMatrix(fs, source, "D2", "the right distortion coefficients");
  if (!D2) return D2.error();
  Expected<cv::Mat> R =
      ReadMatrix(fs, source, "R", "the 3x3 rotation (or rotation vector) right from left");
  if (!R) return R.error();
  Expected<cv::Mat> T = ReadMatrix(fs, source, "T", "the 3-vector translation right from left [m]");
  if (!T) return T.error();
  Expected<cv::Size> size = ReadImageSize(fs, source);
  if (!size) return size.error();

  for (const auto& [key, m] : {std::pair<const char*, const cv::Mat*>{"M1", &*M1}, {"M2", &*M2}}) {
    if (m->rows != 3 || m->cols != 3) {
      return Error{source + ": " + key + ": expected a 3x3 matrix, got " + std::to_string(m->rows) +
                   "x" + std::to_string(m->cols)};
    }
    if (Status s = CheckIntrinsicMatrix(*m, source, key); !s) return s.error();
  }
  for (const auto& [key, m] : {std::pair<const char*, const cv::Mat*>{"D1", &*D1}, {"D2", &*D2}}) {
    const int n = static_cast<int>(m->total());
    if ((m->rows != 1 && m->cols != 1) || (n != 4 && n != 5 && n != 8 && n != 12 && n != 14)) {
      return Error{source + ": " + key +
                   ": expected a vector of 4, 5, 8, 12 or 14 distortion coefficients, got " +
                   std::to_string(m->rows) + "x" + std::to_string(m->cols)};
    }
  }
  cv::Mat rotation = *R;
  if (rotation.total() == 3 && (rotation.rows == 1 || rotation.cols == 1)) {
    cv::Rodrigues(rotation.reshape(1, 3), rotation);
  } else if (rotation.rows != 3 || rotation.cols != 3) {
    return Error{source + ": R: expected a 3x3 rotation matrix or a 3-vector, got " +
                 std::to_string(rotation.rows) + "x" + std::to_string(rotation.cols)};
  }
  {
    const cv::Mat should_be_identity = rotation * rotation.t();
    if (cv::norm(should_be_identity, cv::Mat::eye(3, 3, CV_64F), cv::NORM_INF) > 1e-4 ||
        cv::determinant(rotation) < 0.0) {
      return Error{source + ": R: not a rotation matrix (R R^T must be I, det R = +1)"};
    }
  }
  if (T->total() != 3 || (T->rows != 1 && T->cols != 1)) {
    return Error{source + ": T: expected a 3-vector, got " + std::to_string(T->rows) + "x" +
                 std::to_string(T->cols)};
  }
  const cv::Mat translation = T->reshape(1, 3);

  cv::Mat R1, R2, P1, P2, Q;
  try {
    cv::stereoRectify(*M1, *D1, *M2, *D2, *size, rotation, translation, R1, R2, P1, P2, Q,
                      cv::CALIB_ZERO_DISPARITY, 0.0);
  } catch (const cv::Exception& e) {
    return Error{source + ": rectification failed: " + e.err};
  }
  const double tx = P2.at<double>(0, 3), ty = P2.at<double>(1, 3);
  if (std::abs(ty) > std::abs(tx)) {
    return Error{source +
                 ": T: the cameras are stacked vertically; only side-by-side rigs are "
                 "supported"};
  }
  const double baseline = -tx / P2.at<double>(0, 0);
  if (!(baseline > 0.0)) {
    return Error{source + ": T: camera 2 is left of camera 1 (T.x = " +
                 util::Number(translation.at<double>(0)) +
                 " > 0); give the left camera as camera 1 (M1, D1) and T with a negative x"};
  }
  if (Status s = CheckBaseline(source, "T", baseline); !s) return s.error();

  StereoCalibration calib;
  calib.model.width = size->width;
  calib.model.height = size->height;
  calib.model.fx = P1.at<double>(0, 0);
  calib.model.fy = P1.at<double>(1, 1);
  calib.model.cx = P1.at<double>(0, 2);
  calib.model.cy = P1.at<double>(1, 2);
  calib.baseline_m = baseline;
  if (Status s = calib.model.Validate(); !s) {
    return Error{source + ": rectified camera: " + s.message()};
  }
  StereoRectification rect;
  rect.raw_width = size->width;
  rect.raw_height = size->height;
  rect.K1 = ToEigen3(*M1);
  rect.K2 = ToEigen3(*M2);
  rect.D1 = ToVector(*D1);
  rect.D2 = ToVector(*D2);
  rect.R1 = ToEigen3(R1);
  rect.R2 = ToEigen3(R2);
  rect.P1 = ToEigen3(P1.colRange(0, 3));
  rect.P2 = ToEigen3(P2.colRange(0, 3));
  calib.rectification = rect;
  return calib;
}

Expected<StereoCalibration> LoadStereoCalibration(const std::filesystem::path& path) {
  Expected<std::string> text = util::ReadTextFile(path);
  if (!text) return text.error();
  const std::string source = path.string();
  if (LooksLikeOpenCv(*text)) return ParseOpenCvStereoCalibration(*text, source);
  if (LooksLikeNumbers(*text)) return ParseFoundationStereoK(*text, source);
  Expected<YAML::Node> root = util::ParseYaml(*text, source);
  if (!root) return root.error();
  if (root->IsMap() && (*root)["M1"]) return ParseOpenCvStereoCalibration(*text, source);
  if (!root->IsMap()) {
    return Error{source +
                 ": not a stereo calibration: expected cairn's stereo YAML (width, "
                 "height, fx, cx, cy, baseline), FoundationStereo's K.txt or an OpenCV "
                 "calibration (M1, D1, M2, D2, R, T)"};
  }
  return ParseStereoCalibrationYaml(*text, source);
}

// -----------------------------------------------------------------------------------------
// Images

Expected<GreyImage> ReadGreyImage(const std::filesystem::path& path) {
  Expected<std::string> bytes = util::ReadTextFile(path);
  if (!bytes) return bytes.error();
  cv::Mat image;
  try {
    const cv::Mat raw(1, static_cast<int>(bytes->size()), CV_8UC1, bytes->data());
    image = cv::imdecode(raw, cv::IMREAD_GRAYSCALE);
  } catch (const cv::Exception& e) {
    return Error{path.string() + ": unreadable image: " + e.err};
  }
  if (image.empty()) {
    return Error{path.string() + ": unreadable image (not a format OpenCV decodes, or corrupt)"};
  }
  return util::GreyGridOf(image);
}

Status WriteGreyPng(const std::filesystem::path& path, const GreyImage& image) {
  if (!image.well_formed()) {
    return Error{path.string() + ": grey image of " + std::to_string(image.data.size()) +
                 " values does not match its size " + std::to_string(image.width) + "x" +
                 std::to_string(image.height)};
  }
  return util::WriteImageAtomic(path, util::GreyMatView(image));
}

Status WriteDisparityPng(const std::filesystem::path& path, const Grid<float>& disparity_px) {
  if (!disparity_px.well_formed()) {
    return Error{path.string() + ": disparity grid does not match its size"};
  }
  cv::Mat image(disparity_px.height, disparity_px.width, CV_16UC1);
  for (int r = 0; r < disparity_px.height; ++r) {
    std::uint16_t* row = image.ptr<std::uint16_t>(r);
    for (int c = 0; c < disparity_px.width; ++c) {
      const double d = disparity_px.at(r, c);
      if (!(d > 0.0)) {
        row[c] = 0;
        continue;
      }
      const double units = std::round(d * 256.0);
      if (units > 65535.0) {
        return Error{path.string() + ": disparity " + util::Number(d) + " px at row " +
                     std::to_string(r) + ", col " + std::to_string(c) +
                     " exceeds the 16-bit range (255.99 px)"};
      }
      row[c] = static_cast<std::uint16_t>(std::max(1.0, units));
    }
  }
  return util::WriteImageAtomic(path, image);
}

Status WriteDisparityColorPng(const std::filesystem::path& path, const Grid<float>& disparity_px,
                              double max_disparity_px) {
  if (!disparity_px.well_formed()) {
    return Error{path.string() + ": disparity grid does not match its size"};
  }
  if (!(max_disparity_px > 0.0)) {
    return Error{path.string() + ": the colour scale needs a positive maximum disparity"};
  }
  cv::Mat grey(disparity_px.height, disparity_px.width, CV_8UC1);
  for (int r = 0; r < disparity_px.height; ++r) {
    for (int c = 0; c < disparity_px.width; ++c) {
      const double d = disparity_px.at(r, c);
      grey.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(
          std::clamp(std::round(d / max_disparity_px * 255.0), 0.0, 255.0));
    }
  }
  cv::Mat colour;
  cv::applyColorMap(grey, colour, cv::COLORMAP_TURBO);
  for (int r = 0; r < disparity_px.height; ++r) {
    for (int c = 0; c < disparity_px.width; ++c) {
      if (!(disparity_px.at(r, c) > 0.0)) colour.at<cv::Vec3b>(r, c) = cv::Vec3b(0, 0, 0);
    }
  }
  return util::WriteImageAtomic(path, colour);
}

}  // namespace cairn::od::io
