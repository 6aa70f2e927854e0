#include "cairn/eval/figures.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <sstream>

#include "cairn/eval/report.hpp"
#include "cairn/util/format.hpp"
#include "cairn/util/image_file.hpp"
#include "opencv_image.hpp"

namespace cairn::eval {
namespace {

using od::io::RgbImage;
using Rgb = std::array<std::uint8_t, 3>;

const cv::Scalar kBlack(0, 0, 0);
const cv::Scalar kWhite(255, 255, 255);
const cv::Scalar kGridGrey(225, 225, 225);
using detail::FromMat;
using detail::kFont;
constexpr double kTextScale = 0.42;
constexpr int kLine = 17;  // text line height [px]
constexpr int kGap = 6;    // between and around cells [px]

cv::Mat ToMat(const RgbImage& image) {
  cv::Mat out(image.height, image.width, CV_8UC3);
  for (int r = 0; r < image.height; ++r) {
    auto* row = out.ptr<cv::Vec3b>(r);
    for (int c = 0; c < image.width; ++c) {
      const Rgb& p = image.at(r, c);
      row[c] = cv::Vec3b(p[2], p[1], p[0]);
    }
  }
  return out;
}

/// Scaled down (area averaging keeps thin obstacles visible) to at most `width` columns.
cv::Mat Fit(const cv::Mat& image, int width) {
  if (image.cols <= width) return image;
  const double s = static_cast<double>(width) / image.cols;
  cv::Mat out;
  cv::resize(image, out,
             cv::Size(width, std::max(1, static_cast<int>(std::lround(image.rows * s)))), 0, 0,
             cv::INTER_AREA);
  return out;
}

/// `text`, cut with ".." so that it fits `width` pixels.
std::string FitText(std::string text, int width) {
  int baseline = 0;
  while (text.size() > 3 && cv::getTextSize(text, kFont, kTextScale, 1, &baseline).width > width) {
    text = text.substr(0, text.size() - 3) + "..";
  }
  return text;
}

void Text(cv::Mat& image, const std::string& text, int x, int baseline_y, int width,
          const cv::Scalar& colour = kBlack) {
  cv::putText(image, FitText(text, width), cv::Point(x, baseline_y), kFont, kTextScale, colour, 1,
              cv::LINE_AA);
}

/// Mostly `colour`, a quarter of the grey underneath (as the detection overlays do).
Rgb Blend(const Rgb& under, const Rgb& colour, int parts_colour = 3, int parts_under = 1) {
  Rgb out;
  const int total = parts_colour + parts_under;
  for (int k = 0; k < 3; ++k) {
    out[k] = static_cast<std::uint8_t>(
        (parts_colour * colour[k] + parts_under * under[k] + total / 2) / total);
  }
  return out;
}

RgbImage Grey(const od::Grid<float>& depth) {
  const od::Grid<std::uint8_t> grey = od::io::RenderDepthGrey(depth);
  RgbImage out{grey.width, grey.height, {}};
  out.data.reserve(grey.data.size());
  for (const std::uint8_t g : grey.data) out.data.push_back({g, g, g});
  return out;
}

/// Truth in the overlay's colours: obstacles blue, their foot band cyan, other objects yellow.
RgbImage TruthOverlay(const EvalFrame& frame, const std::vector<std::int32_t>& band) {
  RgbImage image = Grey(frame.depth_m);
  const std::vector<std::uint8_t> obstacle = frame.truth.ObstacleMask();
  for (std::size_t i = 0; i < image.data.size(); ++i) {
    const int id = frame.truth.object_id[i];
    if (obstacle[i]) {
      image.data[i] = Blend(image.data[i], {0, 40, 255});
    } else if (id > 0) {
      image.data[i] = Blend(image.data[i], {255, 210, 0});
    } else if (!band.empty() && band[i] != 0) {
      image.data[i] = Blend(image.data[i], {0, 220, 230}, 1, 1);
    }
  }
  return image;
}

/// Truth as segments: a colour per object, its foot band in a lighter shade of it.
RgbImage TruthSegments(const EvalFrame& frame, const std::vector<std::int32_t>& band) {
  RgbImage image = Grey(frame.depth_m);
  for (std::size_t i = 0; i < image.data.size(); ++i) {
    const int id = frame.truth.object_id[i];
    if (id > 0) {
      image.data[i] = Blend(image.data[i], od::io::SegmentColor(id));
    } else if (!band.empty() && band[i] != 0) {
      image.data[i] = Blend(image.data[i], od::io::SegmentColor(band[i]), 1, 1);
    }
  }
  return image;
}

struct Column {
  std::string title;
  std::string line2;
  std::string lower;
  cv::Mat upper;
  cv::Mat bottom;
};

std::string Num(double v, int decimals = 2) {
  if (!std::isfinite(v)) return "-";
  return util::Fixed(v, decimals);
}

/// BGR colours of the curves, by method position.
cv::Scalar CurveColour(std::size_t k) {
  static const cv::Scalar palette[] = {{180, 80, 10},  {235, 175, 90}, {40, 150, 40},
                                       {30, 30, 200},  {50, 140, 245}, {150, 60, 150},
                                       {100, 100, 100}};
  return palette[k % (sizeof(palette) / sizeof(palette[0]))];
}

/// Marker `shape` (by method position): disc, square, triangle, diamond, cross.
void Marker(cv::Mat& image, const cv::Point& p, std::size_t shape, int size,
            const cv::Scalar& colour) {
  const int s = size;
  switch (shape % 5) {
    case 0:
      cv::circle(image, p, s, colour, cv::FILLED, cv::LINE_AA);
      break;
    case 1:
      cv::rectangle(image, p - cv::Point(s, s), p + cv::Point(s, s), colour, cv::FILLED);
      break;
    case 2: {
      const std::vector<cv::Point> tri = {p + cv::Point(0, -s), p + cv::Point(s, s),
                                          p + cv::Point(-s, s)};
      cv::fillConvexPoly(image, tri, colour, cv::LINE_AA);
      break;
    }
    case 3: {
      const std::vector<cv::Point> diamond = {p + cv::Point(0, -s), p + cv::Point(s, 0),
                                              p + cv::Point(0, s), p + cv::Point(-s, 0)};
      cv::fillConvexPoly(image, diamond, colour, cv::LINE_AA);
      break;
    }
    default:
      cv::line(image, p - cv::Point(s, s), p + cv::Point(s, s), colour, 2, cv::LINE_AA);
      cv::line(image, p + cv::Point(-s, s), p + cv::Point(s, -s), colour, 2, cv::LINE_AA);
      break;
  }
}

}  // namespace

Expected<RgbImage> ComparisonStrip(const EvalFrame& frame, const FrameEvaluation& evaluation,
                                   const std::vector<Method>& methods,
                                   const FigureOptions& options) {
  if (evaluation.runs.size() != methods.size() || evaluation.scores.size() != methods.size()) {
    return Error{frame.name + ": figure: " + std::to_string(evaluation.runs.size()) + " runs for " +
                 std::to_string(methods.size()) + " methods"};
  }
  const int cell = std::max(64, options.cell_width);
  std::vector<Column> columns;
  {
    Column truth;
    truth.title = "truth";
    int obstacles = 0, others = 0;
    for (const TruthObject& o : frame.truth.objects) (o.is_obstacle ? obstacles : others)++;
    truth.line2 =
        std::to_string(obstacles) + " obstacles, " + std::to_string(others) + " other objects seen";
    truth.lower = "objects (foot band lighter)";
    truth.upper = Fit(ToMat(TruthOverlay(frame, evaluation.foot_band)), cell);
    truth.bottom = Fit(ToMat(TruthSegments(frame, evaluation.foot_band)), cell);
    columns.push_back(std::move(truth));
  }
  for (std::size_t k = 0; k < methods.size(); ++k) {
    const MethodRun& run = evaluation.runs[k];
    const Score& s = evaluation.scores[k].score;
    Expected<RgbImage> overlay =
        od::io::RenderOverlay(frame.depth_m, run.detection, run.classification);
    if (!overlay)
      return Error{frame.name + ": " + methods[k].label + ": " + overlay.error().message};
    Expected<RgbImage> segments = od::io::RenderSegmentsColor(frame.depth_m, run.detection);
    if (!segments) {
      return Error{frame.name + ": " + methods[k].label + ": " + segments.error().message};
    }
    Column c;
    c.title = methods[k].label;
    c.line2 = "P " + Num(s.strict.Precision()) + " (" + Num(s.band_excluded.Precision()) + ") R " +
              Num(s.strict.Recall()) + "  found " + std::to_string(s.objects_found) + "/" +
              std::to_string(s.objects_counted) + "  false " + std::to_string(s.false_obstacles);
    c.lower =
        std::to_string(s.segments) + " segments, " + std::to_string(s.kept_segments) + " kept";
    c.upper = Fit(ToMat(*overlay), cell);
    c.bottom = Fit(ToMat(*segments), cell);
    columns.push_back(std::move(c));
  }

  const int cell_w = columns.front().upper.cols;
  const int cell_h = columns.front().upper.rows;
  const int title_h = kLine + 6;
  const int caption_h = 2 * kLine + 4;
  const int lower_h = kLine + 4;
  const int width = kGap + static_cast<int>(columns.size()) * (cell_w + kGap);
  const int height = title_h + caption_h + cell_h + lower_h + cell_h + kGap;
  cv::Mat strip(height, width, CV_8UC3, kWhite);
  Text(strip, frame.name, kGap, kLine, width - 2 * kGap);
  for (std::size_t k = 0; k < columns.size(); ++k) {
    const Column& c = columns[k];
    const int x = kGap + static_cast<int>(k) * (cell_w + kGap);
    int y = title_h;
    Text(strip, c.title, x, y + kLine - 3, cell_w);
    Text(strip, c.line2, x, y + 2 * kLine - 3, cell_w, cv::Scalar(60, 60, 60));
    y += caption_h;
    c.upper.copyTo(strip(cv::Rect(x, y, c.upper.cols, c.upper.rows)));
    y += cell_h;
    Text(strip, c.lower, x, y + kLine - 1, cell_w, cv::Scalar(60, 60, 60));
    y += lower_h;
    c.bottom.copyTo(strip(cv::Rect(x, y, c.bottom.cols, c.bottom.rows)));
  }
  return FromMat(strip);
}

RgbImage ComparisonFigure(const std::string& title, const std::vector<RgbImage>& strips) {
  int width = 640;
  int height = 0;
  for (const RgbImage& s : strips) {
    width = std::max(width, s.width);
    height += s.height;
  }
  const std::vector<std::string> legend = {
      "upper rows: grey depth (near bright), kept obstacle points blue, rejected by the rules red;"
      " truth: obstacles blue, their foot band cyan, other objects yellow",
      "lower rows: a colour per segment (truth: per object).  Captions: P strict (P without the "
      "foot band), per-point recall, obstacles found / counted, false obstacles"};
  const int title_h = kLine + 10;
  const int legend_h = static_cast<int>(legend.size()) * kLine + 10;
  cv::Mat figure(title_h + height + legend_h, width, CV_8UC3, kWhite);
  cv::putText(figure, FitText(title, width - 2 * kGap), cv::Point(kGap, kLine + 2), kFont, 0.55,
              kBlack, 1, cv::LINE_AA);
  int y = title_h;
  for (const RgbImage& s : strips) {
    ToMat(s).copyTo(figure(cv::Rect(0, y, s.width, s.height)));
    y += s.height;
  }
  for (const std::string& line : legend) {
    y += kLine;
    Text(figure, line, kGap, y, width - 2 * kGap, cv::Scalar(60, 60, 60));
  }
  return FromMat(figure);
}

RgbImage PrecisionRecallPlot(const SweepSpec& sweep, const std::vector<Method>& methods,
                             const SweepScores& scores, const std::string& title) {
  const int left = 70, top = 76, side = 440, legend_x = left + side + 30;
  const int width = legend_x + 250, height = top + side + 60;
  cv::Mat plot(height, width, CV_8UC3, kWhite);
  // Each axis spans [lo, 1], lo in {0, 0.5, 0.8, 0.9} (round ticks): zoomed when every point
  // lies high (precision is often close to 1 everywhere), so that the curves can be told
  // apart.
  double min_recall = 1.0, min_precision = 1.0;
  for (const std::vector<Score>& row : scores) {
    for (const Score& s : row) {
      const double p = s.band_excluded.Precision(), r = s.strict.Recall();
      if (!std::isfinite(p) || !std::isfinite(r)) continue;
      min_recall = std::min(min_recall, r);
      min_precision = std::min(min_precision, p);
    }
  }
  const auto lower = [](double min) {
    for (const double lo : {0.9, 0.8, 0.5}) {
      if (min - 0.02 >= lo) return lo;
    }
    return 0.0;
  };
  const double r0 = lower(min_recall), p0 = lower(min_precision);
  const auto at = [&](double recall, double precision) {
    return cv::Point(left + static_cast<int>(std::lround((recall - r0) / (1.0 - r0) * side)),
                     top + static_cast<int>(std::lround((1.0 - precision) / (1.0 - p0) * side)));
  };
  cv::putText(plot, FitText(title, width - 20), cv::Point(10, 22), kFont, 0.5, kBlack, 1,
              cv::LINE_AA);
  for (int t = 0; t <= 10; ++t) {
    const double vr = r0 + (1.0 - r0) * t / 10.0, vp = p0 + (1.0 - p0) * t / 10.0;
    cv::line(plot, at(vr, p0), at(vr, 1.0), kGridGrey, 1);
    cv::line(plot, at(r0, vp), at(1.0, vp), kGridGrey, 1);
    if (t % 2 == 0) {
      const int decimals_r = r0 > 0.0 ? 2 : 1, decimals_p = p0 > 0.0 ? 2 : 1;
      cv::putText(plot, Num(vr, decimals_r), at(vr, p0) + cv::Point(-12, 18), kFont, kTextScale,
                  kBlack, 1, cv::LINE_AA);
      cv::putText(plot, Num(vp, decimals_p), at(r0, vp) + cv::Point(-38, 5), kFont, kTextScale,
                  kBlack, 1, cv::LINE_AA);
    }
  }
  cv::rectangle(plot, at(r0, 1.0), at(1.0, p0), kBlack, 1);
  cv::putText(plot, "recall (per point)", at(0.5 * (1.0 + r0), p0) + cv::Point(-60, 40), kFont,
              0.48, kBlack, 1, cv::LINE_AA);
  cv::putText(plot, "precision (per point, foot band excluded)", cv::Point(left - 40, top - 24),
              kFont, 0.45, kBlack, 1, cv::LINE_AA);

  const std::vector<double> values = sweep.Values();
  const std::string unit = SettingUnit(sweep.key);
  for (std::size_t m = 0; m < methods.size(); ++m) {
    const cv::Scalar colour = CurveColour(m);
    std::vector<cv::Point> points;
    std::vector<std::size_t> which;
    for (std::size_t v = 0; v < scores.size() && v < values.size(); ++v) {
      if (m >= scores[v].size()) continue;
      const double p = scores[v][m].band_excluded.Precision();
      const double r = scores[v][m].strict.Recall();
      if (!std::isfinite(p) || !std::isfinite(r)) continue;
      points.push_back(at(r, p));
      which.push_back(v);
    }
    // Methods often coincide: later ones are drawn thinner and with smaller markers of
    // another shape, on top, so that every curve stays visible.
    const int thickness = m < 2 ? 3 - static_cast<int>(m) : 1;
    const int size = std::max(3, 7 - static_cast<int>(m));
    if (points.size() > 1) cv::polylines(plot, points, false, colour, thickness, cv::LINE_AA);
    for (const cv::Point& p : points) Marker(plot, p, m, size, colour);
    if (!points.empty()) {
      std::ostringstream first, last;
      first << values[which.front()];
      last << values[which.back()];
      cv::putText(plot, first.str(), points.front() + cv::Point(6, -6), kFont, 0.38, colour, 1,
                  cv::LINE_AA);
      if (points.size() > 1) {
        cv::putText(plot, last.str(), points.back() + cv::Point(6, -6), kFont, 0.38, colour, 1,
                    cv::LINE_AA);
      }
    }
    const int y = top + 10 + static_cast<int>(m) * 24;
    cv::line(plot, cv::Point(legend_x, y), cv::Point(legend_x + 26, y), colour, thickness,
             cv::LINE_AA);
    Marker(plot, cv::Point(legend_x + 13, y), m, size, colour);
    Text(plot, methods[m].label, legend_x + 34, y + 5, width - legend_x - 40);
  }
  std::ostringstream range;
  range << sweep.key << " " << sweep.lo << " .. " << sweep.hi << (unit.empty() ? "" : " " + unit)
        << ", " << values.size() << " values";
  Text(plot, range.str(), legend_x, top + 10 + static_cast<int>(methods.size()) * 24 + 16,
       width - legend_x - 10, cv::Scalar(60, 60, 60));
  Text(plot, "labels: first and last value", legend_x,
       top + 10 + static_cast<int>(methods.size()) * 24 + 16 + kLine, width - legend_x - 10,
       cv::Scalar(60, 60, 60));
  return FromMat(plot);
}

Status WritePng(const std::filesystem::path& path, const RgbImage& image) {
  if (image.width <= 0 || image.height <= 0 ||
      image.data.size() != static_cast<std::size_t>(image.width) * image.height) {
    return Error{path.string() + ": empty or inconsistent image"};
  }
  return util::WriteImageAtomic(path, ToMat(image), ".png", {cv::IMWRITE_PNG_COMPRESSION, 9});
}

}  // namespace cairn::eval
