#include "cairn/map/tilt_refiner.hpp"

#include <ceres/ceres.h>
#include <ceres/cubic_interpolation.h>

#include <cmath>
#include <sstream>

#include "ground_points.hpp"

namespace cairn::map {
namespace {

using Interpolator = ceres::BiCubicInterpolator<ceres::Grid2D<double>>;

/// The patch as a row-major array the interpolator reads, with unknown cells filled from their
/// known neighbours (so that the bicubic stencil of a point near a hole stays finite), and
/// the mask of cells that were known.
struct FilledPatch {
  int rows = 0, cols = 0;
  std::vector<double> z;
  std::vector<std::uint8_t> known;

  explicit FilledPatch(const Eigen::MatrixXd& patch)
      : rows(static_cast<int>(patch.rows())), cols(static_cast<int>(patch.cols())) {
    z.resize(static_cast<std::size_t>(rows) * cols);
    known.resize(z.size());
    for (int r = 0; r < rows; ++r) {
      for (int c = 0; c < cols; ++c) {
        const double v = patch(r, c);
        z[Index(r, c)] = v;
        known[Index(r, c)] = std::isfinite(v) ? 1 : 0;
      }
    }
    // A few passes of neighbour averaging fill the holes next to known cells; what stays
    // unknown after that is never inside the stencil of a point that is used. Most of a
    // patch is unknown and far from any known cell: a pass visits only the cells with a
    // filled neighbour (the filled mask dilated by 3 x 3, row then column).
    std::vector<std::uint8_t> filled = known;
    std::vector<std::uint8_t> near(z.size()), across(z.size());
    for (int pass = 0; pass < 3; ++pass) {
      for (int r = 0; r < rows; ++r) {
        for (int c = 0; c < cols; ++c) {
          std::uint8_t any = filled[Index(r, c)];
          if (c > 0) any |= filled[Index(r, c - 1)];
          if (c + 1 < cols) any |= filled[Index(r, c + 1)];
          across[Index(r, c)] = any;
        }
      }
      for (int r = 0; r < rows; ++r) {
        for (int c = 0; c < cols; ++c) {
          std::uint8_t any = across[Index(r, c)];
          if (r > 0) any |= across[Index(r - 1, c)];
          if (r + 1 < rows) any |= across[Index(r + 1, c)];
          near[Index(r, c)] = any;
        }
      }
      std::vector<std::uint8_t> next = filled;
      for (int r = 0; r < rows; ++r) {
        for (int c = 0; c < cols; ++c) {
          if (filled[Index(r, c)] || !near[Index(r, c)]) continue;
          double sum = 0.0;
          int n = 0;
          for (int dr = -1; dr <= 1; ++dr) {
            for (int dc = -1; dc <= 1; ++dc) {
              const int rr = r + dr, cc = c + dc;
              if (rr < 0 || cc < 0 || rr >= rows || cc >= cols || !filled[Index(rr, cc)]) continue;
              sum += z[Index(rr, cc)];
              ++n;
            }
          }
          if (n > 0) {
            z[Index(r, c)] = sum / n;
            next[Index(r, c)] = 1;
          }
        }
      }
      filled.swap(next);
    }
    for (std::size_t i = 0; i < z.size(); ++i) {
      if (!filled[i]) z[i] = 0.0;
    }
  }

  std::size_t Index(int r, int c) const { return static_cast<std::size_t>(r) * cols + c; }

  /// True when the whole 4x4 bicubic stencil around (row, col) was known.
  bool StencilKnown(double row, double col) const {
    const int r0 = static_cast<int>(std::floor(row)) - 1;
    const int c0 = static_cast<int>(std::floor(col)) - 1;
    if (r0 < 0 || c0 < 0 || r0 + 3 >= rows || c0 + 3 >= cols) return false;
    for (int r = r0; r < r0 + 4; ++r) {
      for (int c = c0; c < c0 + 4; ++c) {
        if (!known[Index(r, c)]) return false;
      }
    }
    return true;
  }
};

/// Where a world point falls in the patch, in the interpolator's (row, col) coordinates:
/// cell centres at integers.
template <typename T>
void PatchCoordinates(const ElevationPatch& patch, const T& x, const T& y, T* row, T* col) {
  *row = (y - patch.origin_m.y()) / patch.resolution_m - 0.5;
  *col = (x - patch.origin_m.x()) / patch.resolution_m - 0.5;
}

/// Height of one ground point above the terrain after the correction (roll, pitch, dz),
/// in units of the measurement scale.
struct HeightResidual {
  HeightResidual(const Eigen::Vector3d& p_rel, const Eigen::Vector3d& origin,
                 const ElevationPatch& patch, const Interpolator& terrain, double scale_m)
      : p_rel_(p_rel), origin_(origin), patch_(patch), terrain_(terrain), scale_m_(scale_m) {}

  template <typename T>
  bool operator()(const T* correction, T* residual) const {
    using std::cos;
    using std::sin;
    const T cr = cos(correction[0]), sr = sin(correction[0]);
    const T cp = cos(correction[1]), sp = sin(correction[1]);
    // q = Rx(roll) p_rel, then w = Ry(pitch) q.
    const T qx = T(p_rel_.x());
    const T qy = cr * p_rel_.y() - sr * p_rel_.z();
    const T qz = sr * p_rel_.y() + cr * p_rel_.z();
    const T wx = cp * qx + sp * qz;
    const T wy = qy;
    const T wz = -sp * qx + cp * qz;
    const T x = wx + origin_.x();
    const T y = wy + origin_.y();
    const T z = wz + origin_.z() + correction[2];
    T row, col, ground;
    PatchCoordinates(patch_, x, y, &row, &col);
    terrain_.Evaluate(row, col, &ground);
    residual[0] = (z - ground) / scale_m_;
    return true;
  }

  Eigen::Vector3d p_rel_, origin_;
  const ElevationPatch& patch_;
  const Interpolator& terrain_;
  double scale_m_;
};

/// The prior: corrections near zero, each in units of its sigma.
struct PriorResidual {
  double sigma_rad, sigma_z_m;
  template <typename T>
  bool operator()(const T* correction, T* residual) const {
    residual[0] = correction[0] / sigma_rad;
    residual[1] = correction[1] / sigma_rad;
    residual[2] = correction[2] / sigma_z_m;
    return true;
  }
};

Eigen::Matrix3d CorrectionRotation(double roll_rad, double pitch_rad) {
  return (Eigen::AngleAxisd(pitch_rad, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

}  // namespace

Status TiltRefinerConfig::Validate() const {
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(prior_sigma_rad)) return Error{"prior_sigma_rad: expected > 0"};
  if (!positive(prior_sigma_z_m)) return Error{"prior_sigma_z_m: expected > 0"};
  if (!positive(huber_m)) return Error{"huber_m: expected > 0"};
  if (!positive(max_range_m)) return Error{"max_range_m: expected > 0"};
  if (max_points < 1) return Error{"max_points: expected >= 1"};
  if (min_points < 3) return Error{"min_points: expected >= 3 (three unknowns)"};
  if (max_iterations < 1) return Error{"max_iterations: expected >= 1"};
  return {};
}

namespace {

// What both fits start from: the patch filled for the interpolator, and the ground points in
// range, evenly thinned by index, over known terrain (relative to the prior's sensor
// origin, in the world frame). Built in place: the interpolator refers to the grid, the grid
// to the filled patch.
class FitInput {
 public:
  FitInput(const std::vector<Eigen::Vector3f>& ground_points_sensor,
           const Eigen::Isometry3d& T_world_sensor_prior, const ElevationPatch& terrain,
           const TiltRefinerConfig& config)
      : filled(terrain.z),
        grid(filled.z.data(), 0, filled.rows, 0, filled.cols),
        interpolator(grid),
        origin(T_world_sensor_prior.translation()) {
    for (const Eigen::Vector3f& q :
         internal::ThinGroundPoints(ground_points_sensor, config.max_range_m, config.max_points)) {
      const Eigen::Vector3d p = T_world_sensor_prior * q.cast<double>();
      double row = 0.0, col = 0.0;
      PatchCoordinates(terrain, p.x(), p.y(), &row, &col);
      if (filled.StencilKnown(row, col)) used_rel.push_back(p - origin);
    }
  }
  FitInput(const FitInput&) = delete;
  FitInput& operator=(const FitInput&) = delete;

  const FilledPatch filled;
  const ceres::Grid2D<double> grid;
  const Interpolator interpolator;
  const Eigen::Vector3d origin;
  std::vector<Eigen::Vector3d> used_rel;
};

bool PatchUsable(const ElevationPatch& terrain, TiltEstimate& estimate) {
  if (!(terrain.resolution_m > 0.0) || terrain.z.rows() < 4 || terrain.z.cols() < 4) {
    estimate.report = "terrain patch too small (needs 4x4 cells and a positive resolution)";
    return false;
  }
  return true;
}

// Whether the fit has the points it needs; says why not in the estimate's report.
bool EnoughPoints(const FitInput& input, const TiltRefinerConfig& config, TiltEstimate& estimate) {
  estimate.points_used = static_cast<int>(input.used_rel.size());
  if (estimate.points_used >= config.min_points) return true;
  std::ostringstream why;
  why << "prior kept: " << estimate.points_used << " ground points over known terrain, "
      << config.min_points << " needed";
  estimate.report = why.str();
  return false;
}

// The frame of both fits: the config checked, the prior kept unless the patch and the
// points over it allow a fit, then `solve` fills in what it found.
using Solver = void (*)(const FitInput&, const Eigen::Isometry3d&, const ElevationPatch&,
                        const TiltRefinerConfig&, TiltEstimate&);

Expected<TiltEstimate> Fit(const std::vector<Eigen::Vector3f>& ground_points_sensor,
                           const Eigen::Isometry3d& T_world_sensor_prior,
                           const ElevationPatch& terrain, const TiltRefinerConfig& config,
                           Solver solve) {
  if (Status s = config.Validate(); !s) return s.error();
  TiltEstimate estimate;
  estimate.T_world_sensor = T_world_sensor_prior;
  if (!PatchUsable(terrain, estimate)) return estimate;
  const FitInput input(ground_points_sensor, T_world_sensor_prior, terrain, config);
  if (!EnoughPoints(input, config, estimate)) return estimate;
  solve(input, T_world_sensor_prior, terrain, config, estimate);
  return estimate;
}

// RefineTilt's fit: Ceres over roll, pitch and height.
void SolveTilt(const FitInput& input, const Eigen::Isometry3d& T_world_sensor_prior,
               const ElevationPatch& terrain, const TiltRefinerConfig& config,
               TiltEstimate& estimate) {
  const Eigen::Vector3d& origin = input.origin;
  const Interpolator& interpolator = input.interpolator;
  const std::vector<Eigen::Vector3d>& used_rel = input.used_rel;

  double correction[3] = {0.0, 0.0, 0.0};
  // The residuals, their cost functions and one Huber loss live here, in two arrays,
  // not as three allocations per point (the Problem, made after them, goes first).
  using HeightCost = ceres::AutoDiffCostFunction<HeightResidual, 1, 3>;
  std::vector<HeightResidual> residuals;
  std::vector<HeightCost> costs;
  residuals.reserve(used_rel.size());
  costs.reserve(used_rel.size());
  ceres::HuberLoss huber(1.0);
  PriorResidual prior{config.prior_sigma_rad, config.prior_sigma_z_m};
  ceres::AutoDiffCostFunction<PriorResidual, 3, 3> prior_cost(&prior, ceres::DO_NOT_TAKE_OWNERSHIP);
  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  for (const Eigen::Vector3d& p_rel : used_rel) {
    residuals.emplace_back(p_rel, origin, terrain, interpolator, config.huber_m);
    costs.emplace_back(&residuals.back(), ceres::DO_NOT_TAKE_OWNERSHIP);
    problem.AddResidualBlock(&costs.back(), &huber, correction);
  }
  problem.AddResidualBlock(&prior_cost, nullptr, correction);

  auto rms = [&](const double* c) {
    double sum = 0.0;
    for (const HeightResidual& r : residuals) {
      double value = 0.0;
      r(c, &value);
      sum += value * value;
    }
    return std::sqrt(sum / static_cast<double>(residuals.size())) * config.huber_m;
  };
  estimate.rms_before_m = rms(correction);

  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = config.max_iterations;
  options.num_threads = 1;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  estimate.report = summary.BriefReport();
  if (!summary.IsSolutionUsable()) return;

  estimate.usable = true;
  estimate.roll_rad = correction[0];
  estimate.pitch_rad = correction[1];
  estimate.dz_m = correction[2];
  estimate.rms_after_m = rms(correction);
  estimate.T_world_sensor =
      ApplyTiltCorrection(T_world_sensor_prior, correction[0], correction[1], correction[2]);
}

// RefineHeight's fit: the height alone, the tilt held.
void SolveHeight(const FitInput& input, const Eigen::Isometry3d& T_world_sensor_prior,
                 const ElevationPatch& terrain, const TiltRefinerConfig& config,
                 TiltEstimate& estimate) {
  const std::vector<Eigen::Vector3d>& used_rel = input.used_rel;
  // With the tilt held, a point's height over the terrain is a_i + dz: the Huber cost
  // sum rho(((a_i + dz) / h)^2) + (dz / sigma_z)^2 has one unknown. Iteratively
  // reweighted least squares (weight 1 within the Huber scale, h / |a_i + dz| beyond)
  // descends it to its minimum.
  std::vector<double> a(used_rel.size());
  for (std::size_t i = 0; i < used_rel.size(); ++i) {
    const Eigen::Vector3d p = used_rel[i] + input.origin;
    double row = 0.0, col = 0.0, ground = 0.0;
    PatchCoordinates(terrain, p.x(), p.y(), &row, &col);
    input.interpolator.Evaluate(row, col, &ground);
    a[i] = p.z() - ground;
  }
  const double h = config.huber_m;
  auto rms = [&](double dz) {
    double sum = 0.0;
    for (const double ai : a) sum += (ai + dz) * (ai + dz);
    return std::sqrt(sum / static_cast<double>(a.size()));
  };
  estimate.rms_before_m = rms(0.0);
  // Its stationary point: dz = -sum w_i a_i / (sum w_i + h^2 / sigma_z^2).
  const double prior = h * h / (config.prior_sigma_z_m * config.prior_sigma_z_m);
  double dz = 0.0;
  int iterations = 0;
  while (iterations < config.max_iterations) {
    ++iterations;
    double num = 0.0, den = prior;
    for (const double ai : a) {
      const double e = std::abs(ai + dz);
      const double w = e <= h ? 1.0 : h / e;
      num += w * ai;
      den += w;
    }
    const double next = -num / den;
    const bool done = std::abs(next - dz) < 1e-9;
    dz = next;
    if (done) break;
  }
  estimate.usable = true;
  estimate.dz_m = dz;
  estimate.rms_after_m = rms(dz);
  estimate.T_world_sensor = ApplyTiltCorrection(T_world_sensor_prior, 0.0, 0.0, dz);
  std::ostringstream report;
  report << "height alone (tilt held): " << iterations << " reweightings, dz " << dz << " m over "
         << a.size() << " points";
  estimate.report = report.str();
}

}  // namespace

Expected<TiltEstimate> RefineTilt(const std::vector<Eigen::Vector3f>& ground_points_sensor,
                                  const Eigen::Isometry3d& T_world_sensor_prior,
                                  const ElevationPatch& terrain, const TiltRefinerConfig& config) {
  return Fit(ground_points_sensor, T_world_sensor_prior, terrain, config, SolveTilt);
}

Expected<TiltEstimate> RefineHeight(const std::vector<Eigen::Vector3f>& ground_points_sensor,
                                    const Eigen::Isometry3d& T_world_sensor_prior,
                                    const ElevationPatch& terrain,
                                    const TiltRefinerConfig& config) {
  return Fit(ground_points_sensor, T_world_sensor_prior, terrain, config, SolveHeight);
}

ElevationPatch ElevationPatchAround(const TerrainMap& terrain, const Eigen::Vector2d& centre,
                                    double half_size_m) {
  const GridPatch grid = terrain.PatchAround(centre, half_size_m);
  ElevationPatch patch;
  patch.z = grid.elevation_m.transpose().cast<double>();  // rows along y, columns along x
  patch.origin_m = grid.origin;
  patch.resolution_m = grid.cell_size_m;
  return patch;
}

Eigen::Isometry3d ApplyTiltCorrection(const Eigen::Isometry3d& T_world_sensor, double roll_rad,
                                      double pitch_rad, double dz_m) {
  Eigen::Isometry3d corrected = T_world_sensor;
  corrected.linear() = CorrectionRotation(roll_rad, pitch_rad) * T_world_sensor.linear();
  corrected.translation() = T_world_sensor.translation() + Eigen::Vector3d(0.0, 0.0, dz_m);
  return corrected;
}

}  // namespace cairn::map
