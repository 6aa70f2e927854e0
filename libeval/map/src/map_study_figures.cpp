#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "cairn/util/format.hpp"
#include "cairn/util/image_file.hpp"
#include "map_study_parts.hpp"

namespace cairn::eval::study {

namespace fs = std::filesystem;
using util::Fixed;

Status WriteCostFigure(const DriftRunResult& r, const fs::path& path) {
  const std::optional<map::CellBox> box = r.map().ObservedBounds();
  if (!box) return Error{path.string() + ": the map observed nothing"};
  constexpr int kPx = 4;
  const Eigen::Vector2i size = box->size();
  cv::Mat image(size.y() * kPx, size.x() * kPx, CV_8UC3, cv::Scalar(0, 0, 0));
  auto rect = [&](int i, int j) {
    const int u = (i - box->min.x()) * kPx, v = (box->max.y() - j) * kPx;
    return cv::Rect(u, v, kPx, kPx);
  };
  for (int j = box->min.y(); j <= box->max.y(); ++j) {
    for (int i = box->min.x(); i <= box->max.x(); ++i) {
      const map::Cell& cell = r.map().grid().At({i, j});
      cv::Scalar colour(0, 0, 0);
      if (cell.lethal) {
        colour = cv::Scalar(0, 0, 255);
      } else if (cell.cost != map::kUnknownCost) {
        const int grey = 230 - cell.cost * 180 / 254;
        colour = cv::Scalar(grey, grey, grey);
      }
      cv::rectangle(image, rect(i, j), colour, cv::FILLED);
    }
  }
  for (const auto& c : r.score.obstacle_cells)
    cv::rectangle(image, rect(c.first, c.second), cv::Scalar(0, 200, 0), 1);
  return util::WriteImageAtomic(path, image);
}

// Each seen obstacle's distance to the nearest lethal cell (dots) at the distance driven when
// it was first seen well, and the horizontal error of the believed sensor position (lines).
Status WriteGrowthFigure(const std::vector<Row>& rows, const std::string& world,
                         const fs::path& path) {
  const int w = 720, h = 420, left = 60, right = 20, top = 30, bottom = 50;
  cv::Mat image(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
  const std::map<std::string, cv::Scalar> colours = {{"true poses", cv::Scalar(0, 0, 0)},
                                                     {"odometry 0%", cv::Scalar(200, 120, 0)},
                                                     {"odometry 1%", cv::Scalar(0, 160, 0)},
                                                     {"odometry 3%", cv::Scalar(0, 0, 220)}};
  double max_x = 1.0, max_y = 0.2;
  for (const Row& row : rows) {
    if (row.world != world || colours.count(row.condition) == 0) continue;
    max_x = std::max(max_x, row.result.distance_m);
    for (const auto& e : row.result.pose_errors) max_y = std::max(max_y, e.position_m);
    for (const auto& o : row.result.obstacles) {
      max_y = std::max(max_y, std::min(o.nearest_lethal_m, 3.0));
    }
  }
  max_y = std::ceil(max_y * 10.0) / 10.0;
  auto P = [&](double x, double y) {
    return cv::Point(left + static_cast<int>(x / max_x * (w - left - right)),
                     h - bottom - static_cast<int>(y / max_y * (h - top - bottom)));
  };
  cv::line(image, P(0, 0), P(max_x, 0), cv::Scalar(0, 0, 0));
  cv::line(image, P(0, 0), P(0, max_y), cv::Scalar(0, 0, 0));
  for (int k = 0; k <= 4; ++k) {
    cv::putText(image, Fixed(max_x * k / 4, 0), P(max_x * k / 4, 0) + cv::Point(-8, 18),
                cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0));
    cv::putText(image, Fixed(max_y * k / 4, 2), P(0, max_y * k / 4) + cv::Point(-50, 4),
                cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0));
  }
  cv::putText(image, "distance driven [m]", cv::Point(w / 2 - 60, h - 12), cv::FONT_HERSHEY_SIMPLEX,
              0.45, cv::Scalar(0, 0, 0));
  cv::putText(image, world + ": error [m]  (lines: sensor position; dots: obstacle to lethal)",
              cv::Point(left, 18), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0));
  int legend = 0;
  for (const auto& [label, colour] : colours) {
    cv::putText(image, label, cv::Point(w - 140, top + 16 * ++legend), cv::FONT_HERSHEY_SIMPLEX,
                0.4, colour);
  }
  for (const Row& row : rows) {
    const auto colour = colours.find(row.condition);
    if (row.world != world || colour == colours.end()) continue;
    const auto& errors = row.result.pose_errors;
    for (std::size_t k = 1; k < errors.size(); ++k) {
      cv::line(image, P(errors[k - 1].distance_m, errors[k - 1].position_m),
               P(errors[k].distance_m, errors[k].position_m), colour->second, 1, cv::LINE_AA);
    }
    for (const auto& o : row.result.obstacles) {
      cv::circle(image, P(o.first_seen_distance_m, std::min(o.nearest_lethal_m, max_y)), 3,
                 colour->second, cv::FILLED, cv::LINE_AA);
    }
  }
  return util::WriteImageAtomic(path, image);
}

// --- The tilt study: prior, the frame-to-map refiner and the gravity estimator ---

}  // namespace cairn::eval::study
