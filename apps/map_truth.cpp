// `cairn map`: the map against a synthetic world's truth (--truth), and the overlay figure
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

#include "cairn/map/map_files.hpp"
#include "cairn/sources/trajectory.hpp"
#include "cairn/util/image_file.hpp"
#include "map_run.hpp"
#ifdef CAIRN_HAVE_SYNTH
#include "cairn/sim/shapes.hpp"
#include "cairn/sim/world.hpp"
#include "cairn/util/format.hpp"
#endif

namespace cairn::apps {
namespace {

namespace fs = std::filesystem;

#ifdef CAIRN_HAVE_SYNTH
/// Distance from `xy` to a footprint polygon: 0 inside [m].
double DistanceToFootprint(const std::vector<cv::Point2f>& polygon, const Eigen::Vector2d& xy) {
  const double signed_distance = cv::pointPolygonTest(
      polygon, cv::Point2f(static_cast<float>(xy.x()), static_cast<float>(xy.y())), true);
  return std::max(0.0, -signed_distance);
}

/// A rotated ellipse or rectangle as a polygon.
void AddEllipse(std::vector<cv::Point2f>& out, const Eigen::Vector2d& c, double a, double b,
                double yaw) {
  for (int k = 0; k < 32; ++k) {
    const double t = 2 * M_PI * k / 32;
    const Eigen::Vector2d local(a * std::cos(t), b * std::sin(t));
    const Eigen::Vector2d p = c + Eigen::Rotation2Dd(yaw) * local;
    out.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  }
}
void AddRectangle(std::vector<cv::Point2f>& out, const Eigen::Vector2d& c, double x_lo, double x_hi,
                  double y_lo, double y_hi, double yaw) {
  for (const Eigen::Vector2d& local : {Eigen::Vector2d(x_lo, y_lo), Eigen::Vector2d(x_hi, y_lo),
                                       Eigen::Vector2d(x_hi, y_hi), Eigen::Vector2d(x_lo, y_hi)}) {
    const Eigen::Vector2d p = c + Eigen::Rotation2Dd(yaw) * local;
    out.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  }
}

/// The horizontal footprint of a solid as a convex polygon (terrain features have none).
std::vector<cv::Point2f> Footprint(const sim::Shape& shape) {
  std::vector<cv::Point2f> points;
  if (sim::IsTerrainFeature(shape)) return points;
  if (const auto* c = std::get_if<sim::Cylinder>(&shape)) {
    AddEllipse(points, c->base_centre.head<2>(), c->radius_m, c->radius_m, 0.0);
  } else if (const auto* e = std::get_if<sim::Ellipsoid>(&shape)) {
    AddEllipse(points, e->centre.head<2>(), e->radii.x(), e->radii.y(), e->yaw_rad);
  } else if (const auto* b = std::get_if<sim::Box>(&shape)) {
    AddRectangle(points, b->centre.head<2>(), -b->size.x() / 2, b->size.x() / 2, -b->size.y() / 2,
                 b->size.y() / 2, b->yaw_rad);
  } else if (const auto* r = std::get_if<sim::Ridge>(&shape)) {
    const double half_length = r->top_length_m / 2 + r->height_m / std::tan(r->end_slope_rad);
    AddRectangle(points, r->base_centre.head<2>(), -half_length, half_length,
                 -r->top_width_m / 2 - r->height_m / std::tan(r->right_slope_rad),
                 r->top_width_m / 2 + r->height_m / std::tan(r->left_slope_rad), r->yaw_rad);
  } else if (const auto* rod = std::get_if<sim::Rod>(&shape)) {
    AddEllipse(points, rod->start.head<2>(), rod->radius_m, rod->radius_m, 0.0);
    AddEllipse(points, rod->end.head<2>(), rod->radius_m, rod->radius_m, 0.0);
  } else if (const auto* k = std::get_if<sim::Cluster>(&shape)) {
    for (const sim::Ellipsoid& part : k->parts) {
      AddEllipse(points, part.centre.head<2>(), part.radii.x(), part.radii.y(), part.yaw_rad);
    }
  }
  std::vector<cv::Point2f> hull;
  cv::convexHull(points, hull);
  return hull;
}
#endif

}  // namespace

Expected<TruthScore> ScoreAgainstWorld(const std::string& world_path,
                                       const map::TerrainMap& terrain, double tolerance_m) {
#ifndef CAIRN_HAVE_SYNTH
  (void)world_path;
  (void)terrain;
  (void)tolerance_m;
  return Error{"--truth needs cairn built with libsim (cairn synth)"};
#else
  Expected<sim::World> world = sim::LoadWorld(world_path);
  if (!world) return Error{"--truth: " + world.error().message};
  TruthScore score;
  score.world = world_path;
  std::vector<std::vector<cv::Point2f>> polygons;
  for (const sim::Object& o : world->scene.objects()) {
    std::vector<cv::Point2f> polygon = Footprint(o.shape);
    if (polygon.empty()) continue;
    TruthObject t;
    t.id = o.id;
    t.name = o.name;
    t.is_obstacle = o.is_obstacle;
    for (const cv::Point2f& p : polygon) {
      t.centre += Eigen::Vector2d(p.x, p.y);
      t.footprint.emplace_back(p.x, p.y);
    }
    t.centre /= static_cast<double>(polygon.size());
    score.objects.push_back(std::move(t));
    polygons.push_back(std::move(polygon));
  }
  const map::TerrainGrid& grid = terrain.grid();
  int both = 0, either = 0;
  for (int j = 0; j < grid.extent().y(); ++j) {
    for (int i = 0; i < grid.extent().x(); ++i) {
      const map::CellIndex index = grid.min_index() + map::CellIndex(i, j);
      const map::Cell& cell = grid.At(index);
      const Eigen::Vector2d xy = grid.CentreOf(index);
      bool truly = false;
      for (std::size_t k = 0; k < score.objects.size(); ++k) {
        TruthObject& t = score.objects[k];
        const double d = DistanceToFootprint(polygons[k], xy);
        if (t.is_obstacle && d == 0.0) truly = true;
        if (cell.lethal && (t.distance_m < 0 || d < t.distance_m)) {
          t.distance_m = d;
          t.obstacle_id = cell.obstacle_id;
        }
      }
      both += truly && cell.lethal ? 1 : 0;
      either += truly || cell.lethal ? 1 : 0;
    }
  }
  score.iou = either > 0 ? static_cast<double>(both) / either : 0.0;
  for (TruthObject& t : score.objects) {
    t.found = t.distance_m >= 0.0 && t.distance_m <= tolerance_m;
    if (t.is_obstacle) {
      ++score.obstacles;
      score.found += t.found ? 1 : 0;
    } else if (t.found) {
      ++score.marked_non_obstacles;
    }
  }
  for (const map::Obstacle& o : terrain.obstacles()) {
    bool matched = false;
    for (const map::CellIndex& c : o.cells) {
      for (const std::vector<cv::Point2f>& polygon : polygons) {
        if (DistanceToFootprint(polygon, grid.CentreOf(c)) <= tolerance_m) matched = true;
      }
    }
    if (!matched) {
      ++score.false_obstacles;
      score.false_obstacle_ids.push_back(o.id);
    }
  }
  // Elevation against the true terrain, over every cell with ground points.
  double sum2 = 0.0;
  for (int j = 0; j < grid.extent().y(); ++j) {
    for (int i = 0; i < grid.extent().x(); ++i) {
      const map::CellIndex index = grid.min_index() + map::CellIndex(i, j);
      const map::Cell& cell = grid.At(index);
      if (!cell.has_elevation()) continue;
      const double error =
          cell.elevation_mean_m - world->scene.terrain().Height(grid.CentreOf(index));
      sum2 += error * error;
      score.elevation_max_m = std::max(score.elevation_max_m, std::abs(error));
      ++score.elevation_cells;
    }
  }
  if (score.elevation_cells > 0) score.elevation_rms_m = std::sqrt(sum2 / score.elevation_cells);
  return score;
#endif
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
  if (truth != nullptr) {
    for (const TruthObject& t : truth->objects) {
      std::vector<cv::Point> polygon;
      for (const Eigen::Vector2f& p : t.footprint) polygon.push_back(pixel(p.cast<double>()));
      const cv::Scalar colour = t.is_obstacle ? cv::Scalar(0, 150, 0) : cv::Scalar(220, 170, 0);
      cv::polylines(image, polygon, true, colour, 2, cv::LINE_AA);
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
  PoseTruth out;
  out.source = tum_path;
  std::vector<double> tilt_deg;
  double sum2 = 0.0;
  for (const FrameRecord& r : records) {
    Expected<sources::BodyPose> pose = truth->PoseAt(r.stamp_s);
    if (!pose) return Error{"--truth-poses: " + tum_path + ": frame " + std::to_string(r.index) +
                            ": " + pose.error().message};
    const Eigen::Vector3d up_fused = r.T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d up_true =
        pose->T_world_body.linear().transpose() * Eigen::Vector3d::UnitZ();
    tilt_deg.push_back(std::atan2(up_fused.cross(up_true).norm(), up_fused.dot(up_true)) * 180.0 /
                       M_PI);
    const double dz = r.T_world_sensor.translation().z() - pose->T_world_body.translation().z();
    sum2 += dz * dz;
  }
  if (tilt_deg.empty()) return out;
  out.frames = static_cast<int>(tilt_deg.size());
  out.tilt_median_deg = Quantile(tilt_deg, 0.5);
  out.tilt_p95_deg = Quantile(tilt_deg, 0.95);
  out.tilt_max_deg = Quantile(tilt_deg, 1.0);
  out.height_rms_m = std::sqrt(sum2 / out.frames);
  return out;
}

}  // namespace cairn::apps
