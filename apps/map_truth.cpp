// `cairn map`: the map against a synthetic world's truth (--truth, cairn::eval_map's one
// scorer), the fused poses against true poses (--truth-poses), and the overlay figure
// (map_run.hpp).
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string_view>

#include "cairn/eval/map_score.hpp"
#include "cairn/map/map_files.hpp"
#include "cairn/sim/world.hpp"
#include "cairn/sources/trajectory.hpp"
#include "cairn/util/format.hpp"
#include "cairn/util/image_file.hpp"
#include "map_run.hpp"

namespace cairn::apps {
namespace {

namespace fs = std::filesystem;

/// The outline of a set of map cells, as polygons in world xy [m].
std::vector<std::vector<Eigen::Vector2d>> Outline(const std::vector<cairn::eval::MapCell>& cells,
                                                  double cell_size) {
  std::vector<std::vector<Eigen::Vector2d>> out;
  if (cells.empty()) return out;
  int x0 = cells[0].first, y0 = cells[0].second, x1 = x0, y1 = y0;
  for (const cairn::eval::MapCell& c : cells) {
    x0 = std::min(x0, c.first), x1 = std::max(x1, c.first);
    y0 = std::min(y0, c.second), y1 = std::max(y1, c.second);
  }
  // One pixel per cell with a border, y up as rows go down.
  cv::Mat mask = cv::Mat::zeros(y1 - y0 + 3, x1 - x0 + 3, CV_8U);
  for (const cairn::eval::MapCell& c : cells)
    mask.at<std::uint8_t>(y1 - c.second + 1, c.first - x0 + 1) = 255;
  cv::Mat large;  // 2 px per cell, so that the contour runs along the cells' edges
  cv::resize(mask, large, cv::Size(), 2, 2, cv::INTER_NEAREST);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(large, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_SIMPLE);
  for (const std::vector<cv::Point>& contour : contours) {
    std::vector<Eigen::Vector2d> polygon;
    for (const cv::Point& p : contour) {
      polygon.emplace_back((x0 - 1 + (p.x + 0.5) / 2.0) * cell_size,
                           (y1 + 2 - (p.y + 0.5) / 2.0) * cell_size);
    }
    out.push_back(std::move(polygon));
  }
  return out;
}

}  // namespace

Expected<TruthScore> ScoreAgainstWorld(const std::string& world_path,
                                       const map::TerrainMap& terrain) {
  Expected<sim::World> world = sim::LoadWorld(world_path);
  if (!world) return Error{"--truth: " + world.error().message};
  cairn::eval::MapScoreOptions options;
  options.found_within_m = 0.5 + terrain.grid().cell_size();  // drift of a cell or so
  Expected<cairn::eval::MapScore> score = cairn::eval::ScoreMap(world->scene, terrain, options);
  if (!score) return Error{"--truth: " + world_path + ": " + score.error().message};
  return TruthScore{world_path, std::move(*score)};
}

Status WriteOverlay(const fs::path& cost_png, const fs::path& path, const map::TerrainMap& terrain,
                    const std::vector<FrameRecord>& records, const TruthScore* truth) {
  Expected<map::CellBox> box = map::ExportBounds(terrain);
  if (!box) return box.error();
  const cv::Mat cost = cv::imread(cost_png.string(), cv::IMREAD_COLOR);
  if (cost.empty()) return Error{cost_png.string() + ": cannot read back"};
  const int scale = std::clamp(1200 / std::max(cost.cols, cost.rows), 1, 6);
  cv::Mat image;
  cv::resize(cost, image, cv::Size(), scale, scale, cv::INTER_NEAREST);
  const double s = terrain.grid().cell_size();
  // World xy -> pixel of the enlarged image (map_server orientation: +y up).
  const auto pixel = [&](const Eigen::Vector2d& xy) {
    const double col = (xy.x() / s - box->min.x()) * scale;
    const double row = (box->max.y() + 1 - xy.y() / s) * scale;
    return cv::Point(static_cast<int>(std::lround(col)), static_cast<int>(std::lround(row)));
  };
  if (truth != nullptr) {  // the cells where an obstacle rises enough, or any object lies
    for (const cairn::eval::MapObjectScore& t : truth->score.objects) {
      const cv::Scalar colour = t.is_obstacle ? cv::Scalar(0, 150, 0) : cv::Scalar(220, 170, 0);
      for (const std::vector<Eigen::Vector2d>& outline :
           Outline(t.is_obstacle ? t.obstacle_cells : t.cells, s)) {
        std::vector<cv::Point> polygon;
        for (const Eigen::Vector2d& p : outline) polygon.push_back(pixel(p));
        cv::polylines(image, polygon, true, colour, 2, cv::LINE_AA);
      }
    }
  }
  std::vector<cv::Point> path_px;
  for (const FrameRecord& r : records) {
    path_px.push_back(pixel(r.T_world_body.translation().head<2>()));
  }
  if (path_px.size() >= 2) {
    cv::polylines(image, path_px, false, cv::Scalar(200, 80, 0), 2, cv::LINE_AA);
  }
  for (const map::Obstacle& o : terrain.obstacles()) {
    const cv::Point a = pixel(o.footprint_min), b = pixel(o.footprint_max);
    cv::rectangle(image, cv::Point(a.x, b.y), cv::Point(b.x, a.y), cv::Scalar(40, 40, 40), 1);
    cv::putText(image, std::to_string(o.id), cv::Point(b.x + 3, b.y + 2), cv::FONT_HERSHEY_SIMPLEX,
                0.4, cv::Scalar(30, 30, 30), 1, cv::LINE_AA);
  }
  // The key, in a band below the map.
  const int width = std::max(image.cols, 830);
  cv::Mat canvas(image.rows + 64, width, CV_8UC3, cv::Scalar(255, 255, 255));
  image.copyTo(canvas(cv::Rect(0, 0, image.cols, image.rows)));
  const int y0 = image.rows + 8;
  const auto text = [&](const std::string& words, int x, int y) {
    cv::putText(canvas, words, cv::Point(x, y), cv::FONT_HERSHEY_SIMPLEX, 0.42,
                cv::Scalar(30, 30, 30), 1, cv::LINE_AA);
  };
  for (int k = 0; k <= 200; ++k) {  // cost.png's terrain colours, 0 .. 252
    const double t = k / 200.0;
    const double blue = 255.0 * std::max(0.0, 1.0 - 2.0 * t);
    const double green = t <= 0.5 ? 255.0 : 255.0 - 2.0 * (t - 0.5) * 135.0;
    cv::line(canvas, cv::Point(10 + k, y0), cv::Point(10 + k, y0 + 14),
             cv::Scalar(blue, green, 255));
  }
  cv::rectangle(canvas, cv::Rect(10, y0, 201, 15), cv::Scalar(120, 120, 120), 1);
  text("terrain cost 0 .. 252", 10, y0 + 30);
  const struct {
    cv::Scalar colour;
    const char* label;
  } swatches[] = {{cv::Scalar(160, 40, 140), "253 inscribed"},
                  {cv::Scalar(0, 0, 220), "254 lethal"},
                  {cv::Scalar(128, 128, 128), "255 unknown"}};
  for (int k = 0; k < 3; ++k) {
    const int x = 230 + 120 * k;
    cv::rectangle(canvas, cv::Rect(x, y0, 15, 15), swatches[k].colour, cv::FILLED);
    text(swatches[k].label, x + 20, y0 + 12);
  }
  cv::line(canvas, cv::Point(320, y0 + 26), cv::Point(340, y0 + 26), cv::Scalar(200, 80, 0), 2);
  text("path", 346, y0 + 30);
  cv::rectangle(canvas, cv::Rect(400, y0 + 20, 14, 12), cv::Scalar(40, 40, 40), 1);
  text("map obstacle (id)", 420, y0 + 30);
  if (truth != nullptr) {
    cv::line(canvas, cv::Point(570, y0 + 26), cv::Point(590, y0 + 26), cv::Scalar(0, 150, 0), 2);
    text("true obstacle", 596, y0 + 30);
    cv::line(canvas, cv::Point(700, y0 + 26), cv::Point(720, y0 + 26), cv::Scalar(220, 170, 0), 2);
    text("not obstacle", 726, y0 + 30);
  }
  text("1 px = " + util::Fixed(s / scale, 3) + " m, north (+y) up", 10, y0 + 50);
  return util::WriteImageAtomic(path, canvas);
}

Expected<PoseTruth> ScorePoses(const std::string& tum_path,
                               const std::vector<FrameRecord>& records) {
  Expected<sources::Trajectory> truth = sources::ReadTumTrajectory(tum_path);
  if (!truth) return Error{"--truth-poses: " + truth.error().message};
  std::vector<cairn::eval::FusedPose> fused;
  for (const FrameRecord& r : records) fused.push_back({r.index, r.stamp_s, r.T_world_sensor});
  Expected<cairn::eval::PoseScore> score =
      cairn::eval::ScorePoses(*truth, fused, "--truth-poses: " + tum_path);
  if (!score) return score.error();
  PoseTruth out;
  static_cast<cairn::eval::PoseScore&>(out) = *score;
  out.source = tum_path;
  return out;
}

}  // namespace cairn::apps
