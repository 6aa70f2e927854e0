// cairn info FILE: what a recording holds. MRPT rawlogs (either format): objects per class,
// the sensors with their counts, rates and data sizes, the time span, the odometry.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>

#include "cairn/sources/rawlog_summary.hpp"
#include "subcommands.hpp"

namespace cairn::apps {
namespace {

namespace fs = std::filesystem;

int InfoFail(const std::string& message) { return CommandFailure("info", message); }

std::string Bytes(std::uintmax_t bytes) {
  std::ostringstream out;
  out << std::fixed << std::setprecision(1);
  if (bytes >= (1u << 20)) {
    out << bytes / 1048576.0 << " MiB";
  } else if (bytes >= 1024) {
    out << bytes / 1024.0 << " KiB";
  } else {
    out << bytes << " B";
  }
  return out.str();
}

std::string Utc(double unix_s) {
  if (!std::isfinite(unix_s)) return "-";
  const auto whole = static_cast<std::time_t>(std::floor(unix_s));
  std::tm tm{};
  gmtime_r(&whole, &tm);
  char text[64];
  std::strftime(text, sizeof(text), "%Y-%m-%d %H:%M:%S", &tm);
  char fraction[16];
  std::snprintf(fraction, sizeof(fraction), "%.3f", unix_s - static_cast<double>(whole));
  return std::string(text) + (fraction + 1) + " UTC";
}

// A guess at what a file that is no rawlog is, to say what to do with it.
std::string Hint(const fs::path& path) {
  const std::string ext = path.extension().string();
  if (ext == ".bin") return " (a KITTI-layout LiDAR scan? try `cairn detect --points`)";
  if (ext == ".png" || ext == ".tif" || ext == ".tiff") {
    return " (a depth image? try `cairn detect --depth ... --intrinsics ...`)";
  }
  if (ext == ".yaml" || ext == ".yml") return " (a settings or world file?)";
  return "";
}

std::string Size(const sources::SensorSummary& s) {
  std::ostringstream out;
  if (s.width > 0) out << s.width << "x" << s.height << " px";
  if (s.points_max > 0) {
    if (out.tellp() > 0) out << ", ";
    if (s.points_min == s.points_max) {
      out << s.points_max << " points";
    } else {
      out << std::fixed << std::setprecision(0) << s.points_min << ".." << s.points_max
          << " points (mean " << s.points_mean << ")";
    }
  }
  if (s.rings > 0) out << ", " << s.rings << " rings";
  return out.str();
}

int RunInfo(const std::string& file) {
  Expected<sources::RawlogSummary> summary = sources::SummarizeRawlog(file);
  if (!summary) {
    std::string message = summary.error().message;
    if (message.find("entry 0:") != std::string::npos) message += Hint(file);
    return InfoFail(message);
  }
  const sources::RawlogSummary& s = *summary;
  if (s.format == sources::RawlogFormat::kEmpty) {
    return InfoFail(file + ": empty file, no MRPT object in it");
  }
  std::cout << std::fixed;
  std::cout << file << ": MRPT rawlog, " << Bytes(s.file_bytes)
            << (s.gzip ? " (gzip-compressed)" : " (uncompressed)") << "\n"
            << "  format:    " << sources::FormatName(s.format) << ", " << s.entries
            << " top-level objects\n";
  if (std::isfinite(s.first_stamp_s)) {
    std::cout << "  time span: " << Utc(s.first_stamp_s) << " .. " << Utc(s.last_stamp_s) << " ("
              << std::setprecision(3) << s.last_stamp_s - s.first_stamp_s << " s)\n";
  } else {
    std::cout << "  time span: no timestamps\n";
  }
  std::cout << "  objects:\n";
  for (const auto& [cls, count] : s.class_counts) {
    std::cout << "    " << std::left << std::setw(34) << cls << std::right << std::setw(8) << count
              << "\n";
  }
  // The label column fits the longest label, with two spaces before the class.
  std::size_t label_width = 18;
  for (const sources::SensorSummary& sensor : s.sensors) {
    label_width = std::max(label_width, sensor.label.size());
  }
  const int lw = static_cast<int>(label_width) + 2;
  std::cout << "  sensors:\n"
            << "    " << std::left << std::setw(lw) << "label" << std::setw(32) << "class"
            << std::right << std::setw(7) << "count" << std::setw(11) << "rate [Hz]"
            << "  data\n";
  for (const sources::SensorSummary& sensor : s.sensors) {
    std::ostringstream rate;
    if (std::isfinite(sensor.rate_hz)) {
      rate << std::fixed << std::setprecision(2) << sensor.rate_hz;
    } else {
      rate << "-";
    }
    std::cout << "    " << std::left << std::setw(lw)
              << (sensor.label.empty() ? std::string("(no label)") : sensor.label) << std::setw(32)
              << sensor.mrpt_class << std::right << std::setw(7) << sensor.count << std::setw(11)
              << rate.str() << "  " << Size(sensor) << "\n";
    if (sensor.problems > 0) {
      std::cout << "      cannot decode " << sensor.problems << " of them: " << sensor.problem
                << "\n";
    }
  }
  if (s.odometry_poses > 0) {
    std::cout << "  odometry:  " << s.odometry_poses << " poses, path " << std::setprecision(2)
              << s.odometry_path_m << " m\n";
  }
  return kExitOk;
}

}  // namespace

Subcommand AddInfoCommand(CLI::App& parent) {
  auto file = std::make_shared<std::string>();
  CLI::App* app = parent.add_subcommand(
      "info",
      "Say what a recording holds: MRPT rawlog objects per class, sensors with counts, rates "
      "and sizes, time span, format, odometry");
  app->add_option("file", *file, "MRPT rawlog (observations or sensory-frame format)")
      ->required()
      ->type_name("FILE.rawlog");
  return {app, [file] { return RunInfo(*file); }};
}

}  // namespace cairn::apps
