#include "cairn/map/gravity_estimator.hpp"

#include <ceres/ceres.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <deque>
#include <exception>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "cairn/od/units.hpp"
#include "gravity_terms.hpp"
#include "json_numbers.hpp"

namespace cairn::map {
namespace {

double Wrap(double a) { return std::remainder(a, 2.0 * kPi); }

// A ground rise's figures are finite and its sigma positive (as given, or as restored).
bool Usable(const GroundRise& r) {
  return std::isfinite(r.rise_m) && r.R_world_sensor.allFinite() &&
         r.R_world_sensor_earlier.allFinite() && r.R_world_body.allFinite() &&
         r.R_world_body_earlier.allFinite() && r.sensor_on_body_m.allFinite() &&
         r.offset_m.allFinite() && r.offset_earlier_m.allFinite() &&
         r.odometry_step_m.allFinite() && r.gradient.allFinite() && std::isfinite(r.sigma_m) &&
         r.sigma_m > 0.0;
}

Error GravityError(const std::string& field, const std::string& what) {
  return Error{"gravity." + field + ": " + what};
}

// The half span of the accelerometer term centred on frame `id` (frames counted from the
// first), or 0 when no term is centred there. Spans run end to end from frame 0: first
// accel_warmup_spans of half span 1 (centres 1, 3, ..), then half span m.
int AccelHalfSpanAt(const GravityEstimatorConfig& c, std::int64_t id) {
  const std::int64_t warmup_end = 2 * static_cast<std::int64_t>(c.accel_warmup_spans);
  if (id < warmup_end) return id % 2 == 1 ? 1 : 0;
  const int m = c.accel_half_span_frames;
  return (id - warmup_end) % (2 * m) == m ? m : 0;
}

// The raw samples as integration pieces: sample j covers [stamp - dt/2, stamp + dt/2].
struct Sample {
  GravityImuSample raw;
  double dt_s = 0.0;
};

// One frame of the window and its states.
struct WindowFrame {
  GravityFrame input;
  int id = 0;
  double rpy[3] = {0.0, 0.0, 0.0};
  double h[1] = {0.0};
  std::vector<Sample> samples;  // those that arrived with it
  // Its velocity (odometry frame, z 0) from the neighbours' odometry: the mean over the
  // chord [chord_from_s, chord_to_s]; a central difference once the next frame is in
  // (one-sided at the start), until then (provisional) the backward one, so that the
  // accelerometer term ending at the newest frame is there a frame sooner; a known velocity
  // as given, at its stamp (both ends).
  std::optional<Eigen::Vector3d> velocity;
  double chord_from_s = 0.0, chord_to_s = 0.0;
  bool provisional = false;
};

// The fraction of a velocity's chord [from, to] that lies before t (a step at the stamp
// for an instantaneous velocity).
double ChordFractionBefore(const WindowFrame& f, double t) {
  if (!(f.chord_to_s > f.chord_from_s)) return t > f.chord_from_s ? 1.0 : 0.0;
  return std::clamp((t - f.chord_from_s) / (f.chord_to_s - f.chord_from_s), 0.0, 1.0);
}

// A Gaussian prior on parameter blocks (the slow states' start, or what the frames that
// left the window said about the ones that remain).
struct Prior {
  Eigen::MatrixXd L;
  Eigen::VectorXd x0, e0;
  std::vector<double*> blocks;
  std::vector<int> sizes;
};

enum class Kind {
  kAccel,
  kGyro,
  kAttitude,
  kYaw,
  kVertical,
  kHeightStep,
  kGround,
  kGroundRise,
  kAnchor,
  kPrior
};

struct Residual {
  ceres::ResidualBlockId id = nullptr;
  std::vector<double*> blocks;
  Kind kind = Kind::kPrior;
  int frame = -1;  // window index of the frame it belongs to (centre, or first of a pair)
};

}  // namespace

// A smoother's solve may start far from the answer (the gyro chained from the first frame),
// and fails when it does not converge within max(max_iterations, this).
constexpr int kSmootherIterations = 100;

struct GravityEstimator::State {
  GravityEstimatorConfig config;
  Eigen::Matrix3d R_body_imu = Eigen::Matrix3d::Identity();
  Eigen::Matrix3d R_body_sensor = Eigen::Matrix3d::Identity();
  std::deque<std::unique_ptr<WindowFrame>> window;
  double ba[3] = {0.0, 0.0, 0.0};
  double bg[3] = {0.0, 0.0, 0.0};
  double mount[2] = {0.0, 0.0};
  double prior_bias[2] = {0.0, 0.0};
  double scale[1] = {0.0};
  std::vector<Prior> priors;
  int added = 0;
  double last_sample_stamp_s = NAN;
  // Heading: unwrapped odometry yaw, its range so far; verticals seen so far.
  double heading_unwrapped = 0.0, heading_min = 0.0, heading_max = 0.0;
  double last_heading = NAN;
  int verticals_seen = 0;
  int rises_seen = 0;  // ground rises given so far

  // The window's problem; with `oldest_only`, only the residuals that may involve the
  // oldest frame (those Marginalise needs: built the same way, the rest left out).
  void Build(ceres::Problem& problem, std::vector<Residual>& residuals,
             bool oldest_only = false) const;
  void Marginalise();
  // Builds the window's problem into `problem` and solves it (a sparse solver for a batch).
  ceres::Solver::Summary Solve(ceres::Problem& problem, std::vector<Residual>& residuals,
                               bool sparse, int max_iterations);
  // A frame's estimate at the states as they stand: attitude, height, slow states, up vectors.
  GravityEstimate EstimateOf(const WindowFrame& frame) const;
};

namespace {

using gravity::ImuSegment;

// The window's samples in time order. A sample's piece reaches from halfway to the sample
// before it (those starts ascend with the stamps) to as far past it, so at most max_half_dt.
struct SampleIndex {
  std::vector<const Sample*> samples;
  double max_half_dt = 0.0;
  explicit SampleIndex(const std::deque<std::unique_ptr<WindowFrame>>& w) {
    for (const auto& frame : w) {
      for (const Sample& s : frame->samples) {
        samples.push_back(&s);
        max_half_dt = std::max(max_half_dt, 0.5 * s.dt_s);
      }
    }
  }
};

// Pieces of the window's samples within [a, b], in time order (forward) or reverse; each
// force's weight is weight(stamp), or 1. Only the samples whose pieces may reach [a, b] are
// looked at (a window of a whole run holds many).
template <typename Weight = std::nullptr_t>
std::vector<gravity::ImuSegment> SegmentsOf(const SampleIndex& index, double a, double b,
                                            bool forward, Weight weight = nullptr) {
  std::vector<ImuSegment> out;
  const double from = a - index.max_half_dt - 1e-9;  // earlier pieces end before a
  auto it = std::lower_bound(index.samples.begin(), index.samples.end(), from,
                             [](const Sample* s, double t) { return s->raw.stamp_s < t; });
  for (; it != index.samples.end(); ++it) {
    const Sample& s = **it;
    if (s.raw.stamp_s - 0.5 * s.dt_s > b) break;  // this piece and all after start past b
    const double lo = std::max(s.raw.stamp_s - 0.5 * s.dt_s, a);
    const double hi = std::min(s.raw.stamp_s + 0.5 * s.dt_s, b);
    if (!(hi > lo)) continue;
    ImuSegment seg;
    seg.omega_imu = s.raw.angular_rate_radps;
    seg.force_imu = s.raw.specific_force_mps2;
    const double mid = std::clamp(s.raw.stamp_s, lo, hi);
    seg.before_s = mid - lo;
    seg.after_s = hi - mid;
    seg.use_force = s.raw.stamp_s > a && s.raw.stamp_s <= b;
    if constexpr (!std::is_same_v<Weight, std::nullptr_t>) seg.weight = weight(s.raw.stamp_s);
    out.push_back(seg);
  }
  if (!forward) std::reverse(out.begin(), out.end());
  return out;
}

}  // namespace

void GravityEstimator::State::Build(ceres::Problem& problem, std::vector<Residual>& residuals,
                                    bool oldest_only) const {
  const GravityEstimatorConfig& c = config;
  auto add = [&](ceres::CostFunction* cost, ceres::LossFunction* loss,
                 std::vector<double*> blocks, Kind kind, int frame) {
    Residual r;
    r.id = problem.AddResidualBlock(cost, loss, blocks);
    r.blocks = std::move(blocks);
    r.kind = kind;
    r.frame = frame;
    residuals.push_back(std::move(r));
  };
  double* ba_ = const_cast<double*>(ba);
  double* bg_ = const_cast<double*>(bg);
  double* mount_ = const_cast<double*>(mount);
  double* prior_bias_ = const_cast<double*>(prior_bias);
  double* scale_ = const_cast<double*>(scale);
  problem.AddParameterBlock(prior_bias_, 2);
  problem.AddParameterBlock(scale_, 1);
  problem.AddParameterBlock(ba_, 3);
  problem.AddParameterBlock(bg_, 3);
  problem.AddParameterBlock(mount_, 2);
  // The IMU terms are pre-integrated at the gyro bias as it stands (GyroTerm).
  const Eigen::Vector3d bg_now(bg[0], bg[1], bg[2]);
  const SampleIndex imu_samples(window);
  const int n = static_cast<int>(window.size());
  for (int i = 0; i < n; ++i) {
    WindowFrame& f = *window[i];
    problem.AddParameterBlock(f.rpy, 3);
    problem.AddParameterBlock(f.h, 1);
  }
  for (int i = 0; i < n; ++i) {
    WindowFrame& f = *window[i];
    const GravityFrame& in = f.input;
    // The terms of frame i and of the step from i to i + 1 involve frame i; an accelerometer
    // term frames i - m to i + m.
    const int m = AccelHalfSpanAt(c, f.id);
    const bool accel_wanted = !oldest_only || i - m == 0;
    if (!oldest_only || i == 0) {
      if (in.attitude_prior_rad) {
        auto* t = new gravity::AttitudePriorTerm{
            (*in.attitude_prior_rad)[0], (*in.attitude_prior_rad)[1], c.attitude_prior_sigma_rad};
        add(new ceres::AutoDiffCostFunction<gravity::AttitudePriorTerm, 2, 3, 2>(t), nullptr,
            {f.rpy, prior_bias_}, Kind::kAttitude, i);
      }
      auto* yaw = new gravity::YawPriorTerm{in.odometry_xy_yaw.z(), c.yaw_sigma_rad};
      add(new ceres::AutoDiffCostFunction<gravity::YawPriorTerm, 1, 3>(yaw), nullptr, {f.rpy},
          Kind::kYaw, i);
      for (const VerticalCue& v : in.verticals) {
        auto* t = new gravity::VerticalTerm;
        t->direction_sensor = v.direction_sensor.normalized();
        t->R_body_sensor = R_body_sensor;
        t->wall_normal = v.wall_normal;
        t->sigma_rad = v.wall_normal ? c.wall_sigma_rad : c.vertical_sigma_rad;
        ceres::CostFunction* cost =
            v.wall_normal ? static_cast<ceres::CostFunction*>(
                                new ceres::AutoDiffCostFunction<gravity::VerticalTerm, 1, 3, 2>(t))
                          : new ceres::AutoDiffCostFunction<gravity::VerticalTerm, 2, 3, 2>(t);
        add(cost, new ceres::CauchyLoss(c.vertical_cauchy), {f.rpy, mount_}, Kind::kVertical, i);
      }
      if (in.ground_height_m) {
        auto* t = new gravity::HeightTerm{*in.ground_height_m, in.ground_height_sigma_m};
        add(new ceres::AutoDiffCostFunction<gravity::HeightTerm, 1, 1>(t),
            new ceres::HuberLoss(c.ground_height_huber), {f.h}, Kind::kGround, i);
      }
    }
    // Ground rises: frame i against an earlier frame j of the window (they involve the
    // oldest frame when j is it).
    for (const GroundRise& rise : in.ground_rises) {
      int j = i - 1;
      while (j >= 0 && window[j]->input.stamp_s != rise.earlier_stamp_s) --j;
      if (j < 0 || (oldest_only && j != 0)) continue;
      WindowFrame& e = *window[j];
      auto* t = new gravity::GroundRiseTerm;
      t->R_body_sensor = R_body_sensor;
      t->R0_k = rise.R_world_sensor;
      t->R0_j = rise.R_world_sensor_earlier;
      t->Rb0_k = rise.R_world_body;
      t->Rb0_j = rise.R_world_body_earlier;
      t->sensor_on_body = rise.sensor_on_body_m;
      t->offset_k = rise.offset_m;
      t->offset_j = rise.offset_earlier_m;
      t->rise_m = rise.rise_m;
      t->sigma_m = rise.sigma_m;
      t->gradient = rise.gradient;
      t->climb_m = rise.gradient.dot(rise.odometry_step_m);
      add(new ceres::AutoDiffCostFunction<gravity::GroundRiseTerm, 1, 1, 1, 3, 3, 2, 1>(t),
          new ceres::HuberLoss(c.ground_height_huber), {e.h, f.h, e.rpy, f.rpy, mount_, scale_},
          Kind::kGroundRise, j);
    }
    if (!oldest_only || i == 0) {
      if (f.id == 0) {
        // The start's anchor: heights are relative to it.
        auto* t = new gravity::HeightTerm{in.ground_height_m.value_or(0.0), 0.01};
        add(new ceres::AutoDiffCostFunction<gravity::HeightTerm, 1, 1>(t), nullptr, {f.h},
            Kind::kAnchor, i);
      }
      if (i + 1 < n) {
        WindowFrame& g = *window[i + 1];
        const double t0 = in.stamp_s, t1 = g.input.stamp_s;
        auto* gyro = new gravity::GyroTerm;
        gyro->segments = SegmentsOf(imu_samples, t0, t1, true);
        gyro->R_body_imu = R_body_imu;
        double sum_sq = 0.0;
        for (const ImuSegment& s : gyro->segments) {
          sum_sq += (s.before_s + s.after_s) * (s.before_s + s.after_s);
        }
        gyro->sigma_rad = std::sqrt(c.gyro_sigma_radps * c.gyro_sigma_radps * sum_sq +
                                    c.rotation_floor_rad * c.rotation_floor_rad);
        if (!gyro->segments.empty()) {
          gyro->Preintegrate(bg_now);
          add(new ceres::AutoDiffCostFunction<gravity::GyroTerm, 3, 3, 3, 3>(gyro), nullptr,
              {f.rpy, g.rpy, bg_}, Kind::kGyro, i);
        } else {
          delete gyro;
        }
        auto* step = new gravity::HeightStepTerm;
        if (in.velocity_world_mps && g.input.velocity_world_mps) {
          step->from_pitch = false;
          step->known_dh_m =
              0.5 * (in.velocity_world_mps->z() + g.input.velocity_world_mps->z()) * (t1 - t0);
          step->sigma_m = c.height_step_sigma_m;
        } else {
          // The step in the mean heading of the two frames (a chord along an arc is
          // straight ahead in it).
          const Eigen::Vector2d d =
              g.input.odometry_xy_yaw.head<2>() - in.odometry_xy_yaw.head<2>();
          const double heading = in.odometry_xy_yaw.z() +
                                 0.5 * Wrap(g.input.odometry_xy_yaw.z() - in.odometry_xy_yaw.z());
          step->distance_m = std::cos(heading) * d.x() + std::sin(heading) * d.y();
          step->lateral_m = -std::sin(heading) * d.x() + std::cos(heading) * d.y();
          step->sigma_m = c.height_step_sigma_m + c.height_step_sigma_per_m * d.norm();
        }
        add(new ceres::AutoDiffCostFunction<gravity::HeightStepTerm, 1, 1, 1, 3, 3, 1>(step),
            nullptr, {f.h, g.h, f.rpy, g.rpy, scale_}, Kind::kHeightStep, i);
      }
    }
    if (accel_wanted && m > 0 && i - m >= 0 && i + m < n && window[i - m]->velocity &&
        window[i + m]->velocity) {
      WindowFrame& fa = *window[i - m];
      WindowFrame& fb = *window[i + m];
      const double ta = fa.input.stamp_s, tb = fb.input.stamp_s;
      // The forces averaged with the kernel of v_b - v_a (AccelTerm).
      const auto kernel = [&fa, &fb](double t) {
        return ChordFractionBefore(fa, t) - ChordFractionBefore(fb, t);
      };
      auto* acc = new gravity::AccelTerm;
      acc->forward = SegmentsOf(imu_samples, in.stamp_s, std::max(tb, fb.chord_to_s), true, kernel);
      acc->backward =
          SegmentsOf(imu_samples, std::min(ta, fa.chord_from_s), in.stamp_s, false, kernel);
      acc->R_body_imu = R_body_imu;
      acc->Preintegrate(bg_now);
      acc->span_s = 0.5 * (fb.chord_from_s + fb.chord_to_s - fa.chord_from_s - fa.chord_to_s);
      acc->gravity_mps2 = c.gravity_mps2;
      const Eigen::Matrix3d R_level_world =
          Eigen::AngleAxisd(-in.odometry_xy_yaw.z(), Eigen::Vector3d::UnitZ()).toRotationMatrix();
      double odometry_part = 0.0;
      acc->v_minus = R_level_world * *fa.velocity;
      acc->v_plus = R_level_world * *fb.velocity;
      acc->yaw_minus_rad = Wrap(fa.input.odometry_xy_yaw.z() - in.odometry_xy_yaw.z());
      acc->yaw_plus_rad = Wrap(fb.input.odometry_xy_yaw.z() - in.odometry_xy_yaw.z());
      if (fa.input.velocity_world_mps && fb.input.velocity_world_mps) {
        acc->vertical_from_pitch = false;
      } else {
        // v_b - v_a, each velocity a chord's displacement over its time T: every frame's
        // position is off by odometry_sigma_m (white) and weighs -+1/T at a chord's ends (a
        // frame that ends chord a and starts chord b once, with both weights); each chord's
        // length L adds the random walk, walk^2 L / T^2. A provisional (backward) chord is
        // half a central one's time and twice as noisy.
        const double walk2 = c.odometry_walk_sigma * c.odometry_walk_sigma;
        double variance = 0.0;
        std::array<std::pair<double, double>, 4> ends{};  // (stamp, weight)
        int n_ends = 0;
        for (const auto& [e, sign] : {std::pair{&fa, -1.0}, std::pair{&fb, 1.0}}) {
          const double T = e->chord_to_s - e->chord_from_s;
          if (!(T > 0.0)) continue;  // a known velocity
          for (const auto& [t, w] :
               {std::pair{e->chord_from_s, -sign / T}, std::pair{e->chord_to_s, sign / T}}) {
            int k = 0;
            while (k < n_ends && ends[k].first != t) ++k;
            if (k == n_ends) ends[n_ends++] = {t, 0.0};
            ends[k].second += w;
          }
          variance += walk2 * e->velocity->head<2>().norm() / T;
        }
        for (int k = 0; k < n_ends; ++k) {
          variance += c.odometry_sigma_m * c.odometry_sigma_m * ends[k].second * ends[k].second;
        }
        odometry_part = std::sqrt(variance) / acc->span_s;
      }
      const double samples = acc->effective_samples();
      if (samples > 0.0 && acc->span_s > 0.0) {
        acc->sigma_mps2 =
            std::sqrt(c.accel_sigma_mps2 * c.accel_sigma_mps2 / samples +
                      c.motion_sigma_mps2 * c.motion_sigma_mps2 + odometry_part * odometry_part);
        add(new ceres::AutoDiffCostFunction<gravity::AccelTerm, 3, 3, 3, 3, 3, 3, 1>(acc),
            new ceres::HuberLoss(c.accel_huber), {fa.rpy, f.rpy, fb.rpy, ba_, bg_, scale_},
            Kind::kAccel, i);
      } else {
        delete acc;
      }
    }
  }
  for (const Prior& prior : priors) {
    add(new gravity::LinearPrior(prior.L, prior.x0, prior.e0, prior.sizes), nullptr,
        prior.blocks, Kind::kPrior, -1);
  }
}

// Marginalises the oldest frame: the residuals that involve it become a Gaussian prior on
// the other blocks they involve (Schur complement of its states), at the current values.
void GravityEstimator::State::Marginalise() {
  WindowFrame& old = *window.front();
  ceres::Problem problem;
  std::vector<Residual> residuals;
  Build(problem, residuals, /*oldest_only=*/true);
  std::vector<ceres::ResidualBlockId> leaving;
  std::vector<double*> order = {old.rpy, old.h};
  std::map<double*, int> size_of = {{old.rpy, 3}, {old.h, 1}};
  std::set<double*> seen = {old.rpy, old.h};
  for (const Residual& r : residuals) {
    const bool involves = std::find(r.blocks.begin(), r.blocks.end(), old.rpy) != r.blocks.end() ||
                          std::find(r.blocks.begin(), r.blocks.end(), old.h) != r.blocks.end();
    if (!involves) continue;
    leaving.push_back(r.id);
    for (double* b : r.blocks) {
      if (seen.insert(b).second) {
        order.push_back(b);
        size_of[b] = problem.ParameterBlockSize(b);
      }
    }
  }
  ceres::Problem::EvaluateOptions options;
  options.residual_blocks = leaving;
  options.parameter_blocks = order;
  std::vector<double> residual_values;
  ceres::CRSMatrix crs;
  double cost = 0.0;
  problem.Evaluate(options, &cost, &residual_values, nullptr, &crs);
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(crs.num_rows, crs.num_cols);
  for (int row = 0; row < crs.num_rows; ++row) {
    for (int k = crs.rows[row]; k < crs.rows[row + 1]; ++k) J(row, crs.cols[k]) = crs.values[k];
  }
  const Eigen::VectorXd r = Eigen::Map<Eigen::VectorXd>(residual_values.data(),
                                                        static_cast<Eigen::Index>(residual_values.size()));
  const Eigen::MatrixXd H = J.transpose() * J;
  const Eigen::VectorXd g = J.transpose() * r;
  const int m = 4;
  // Slow states not estimated are held at their values (conditioned on), not kept.
  std::vector<int> offsets;
  int offset = 0;
  for (std::size_t b = 0; b < order.size(); ++b) {
    offsets.push_back(offset);
    offset += size_of[order[b]];
  }
  Prior prior;
  std::vector<int> keep_index;
  for (std::size_t b = 2; b < order.size(); ++b) {
    double* block = order[b];
    const bool fixed = (block == ba && !config.estimate_accel_bias) ||
                       (block == bg && !config.estimate_gyro_bias) ||
                       (block == mount && !config.estimate_mount) ||
                       (block == scale && !config.estimate_odometry_scale);
    if (fixed) continue;
    prior.blocks.push_back(block);
    prior.sizes.push_back(size_of[block]);
    for (int i = 0; i < size_of[block]; ++i) keep_index.push_back(offsets[b] + i);
  }
  const int k = static_cast<int>(keep_index.size());
  if (k > 0) {
    Eigen::MatrixXd Hmm = H.topLeftCorner(m, m);
    Hmm.diagonal().array() += 1e-12;
    Eigen::MatrixXd Hrm(k, m), Hrr(k, k);
    Eigen::VectorXd gr(k);
    for (int i = 0; i < k; ++i) {
      Hrm.row(i) = H.block(keep_index[i], 0, 1, m);
      gr[i] = g[keep_index[i]];
      for (int j = 0; j < k; ++j) Hrr(i, j) = H(keep_index[i], keep_index[j]);
    }
    const Eigen::LDLT<Eigen::MatrixXd> solve(Hmm);
    const Eigen::MatrixXd Hm = Hrr - Hrm * solve.solve(Hrm.transpose());
    const Eigen::VectorXd gm = gr - Hrm * solve.solve(g.head(m));
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(0.5 * (Hm + Hm.transpose()));
    const double floor = 1e-10 * std::max(1.0, eig.eigenvalues().maxCoeff());
    const Eigen::VectorXd s = eig.eigenvalues().array().max(floor);
    prior.L = s.array().sqrt().matrix().asDiagonal() * eig.eigenvectors().transpose();
    prior.e0 = (s.array().rsqrt().matrix().asDiagonal() * eig.eigenvectors().transpose()) * gm;
    prior.x0.resize(k);
    int at = 0;
    for (std::size_t b = 0; b < prior.blocks.size(); ++b) {
      for (int i = 0; i < prior.sizes[b]; ++i) prior.x0[at++] = prior.blocks[b][i];
    }
  }
  // The priors that involved the old frame are in the new one now.
  std::vector<Prior> remaining;
  for (Prior& p : priors) {
    const bool involves = std::find(p.blocks.begin(), p.blocks.end(), old.rpy) != p.blocks.end() ||
                          std::find(p.blocks.begin(), p.blocks.end(), old.h) != p.blocks.end();
    if (!involves) remaining.push_back(std::move(p));
  }
  if (k > 0) remaining.push_back(std::move(prior));
  priors = std::move(remaining);
  window.pop_front();
}

Status GravityEstimatorConfig::Validate() const {
  if (accel_warmup_spans < 0) {
    return GravityError("accel_warmup_spans",
                        "must be >= 0, got " + std::to_string(accel_warmup_spans));
  }
  if (accel_half_span_frames < 1) {
    return GravityError("accel_half_span_frames",
                        "must be >= 1, got " + std::to_string(accel_half_span_frames));
  }
  if (window_frames < 2 * accel_half_span_frames + 2) {
    return GravityError("window_frames", "must be >= 2 accel_half_span_frames + 2 = " +
                                             std::to_string(2 * accel_half_span_frames + 2) +
                                             ", got " + std::to_string(window_frames));
  }
  if (!(std::isfinite(odometry_sigma_m) && odometry_sigma_m >= 0.0)) {
    return GravityError("odometry_sigma_m", "must be a finite number >= 0");
  }
  if (!(std::isfinite(odometry_walk_sigma) && odometry_walk_sigma >= 0.0)) {
    return GravityError("odometry_walk_sigma", "must be a finite number >= 0");
  }
  const struct {
    const char* name;
    double value;
  } positive[] = {{"gravity_mps2", gravity_mps2},
                  {"accel_sigma_mps2", accel_sigma_mps2},
                  {"motion_sigma_mps2", motion_sigma_mps2},
                  {"accel_huber", accel_huber},
                  {"gyro_sigma_radps", gyro_sigma_radps},
                  {"rotation_floor_rad", rotation_floor_rad},
                  {"attitude_prior_sigma_rad", attitude_prior_sigma_rad},
                  {"attitude_bias_sigma_rad", attitude_bias_sigma_rad},
                  {"yaw_sigma_rad", yaw_sigma_rad},
                  {"vertical_sigma_rad", vertical_sigma_rad},
                  {"vertical_cauchy", vertical_cauchy},
                  {"wall_sigma_rad", wall_sigma_rad},
                  {"height_step_sigma_m", height_step_sigma_m},
                  {"ground_height_huber", ground_height_huber},
                  {"accel_bias_sigma_mps2", accel_bias_sigma_mps2},
                  {"gyro_bias_sigma_radps", gyro_bias_sigma_radps},
                  {"mount_sigma_rad", mount_sigma_rad},
                  {"odometry_scale_sigma", odometry_scale_sigma},
                  {"observable_ratio", observable_ratio}};
  for (const auto& p : positive) {
    if (!(std::isfinite(p.value) && p.value > 0.0)) {
      return GravityError(p.name, "must be a finite number > 0, got " + std::to_string(p.value));
    }
  }
  if (!(std::isfinite(height_step_sigma_per_m) && height_step_sigma_per_m >= 0.0)) {
    return GravityError("height_step_sigma_per_m", "must be a finite number >= 0");
  }
  if (max_iterations < 1) return GravityError("max_iterations", "must be >= 1");
  return {};
}

const char* StateName(GravityDegeneracy::State state) {
  switch (state) {
    case GravityDegeneracy::State::kAccelBias:
      return "accelerometer bias";
    case GravityDegeneracy::State::kGyroBias:
      return "gyro bias";
    case GravityDegeneracy::State::kMount:
      return "sensor mount tilt";
    case GravityDegeneracy::State::kCovariance:
      return "covariance";
  }
  return "?";
}

bool GravityEstimate::Degenerate(GravityDegeneracy::State state) const {
  return std::any_of(degeneracies.begin(), degeneracies.end(),
                     [&](const GravityDegeneracy& d) { return d.state == state; });
}

std::string GravityEstimate::BriefReport() const {
  char line[512];
  std::snprintf(line, sizeof(line),
                "roll %.3f pitch %.3f deg (sigma %.3f %.3f), ba (%.3f %.3f %.3f) m/s^2, "
                "mount (%.3f %.3f) deg, odometry scale %+.2f%%; cues: %d accel (%d out), %d gyro, "
                "%d verticals (%d out), %d ground rises, %d priors; %d iterations, cost %.3g "
                "-> %.3g",
                roll_rad / kDegToRad, pitch_rad / kDegToRad,
                std::sqrt(attitude_covariance(0, 0)) / kDegToRad,
                std::sqrt(attitude_covariance(1, 1)) / kDegToRad, accel_bias_mps2.x(),
                accel_bias_mps2.y(), accel_bias_mps2.z(), mount_rad.x() / kDegToRad,
                mount_rad.y() / kDegToRad, 100.0 * odometry_scale, cues.accel_terms,
                cues.accel_outliers, cues.gyro_terms, cues.verticals, cues.vertical_outliers,
                cues.ground_rises, cues.attitude_priors, iterations, initial_cost, final_cost);
  std::string out = line;
  for (const GravityDegeneracy& d : degeneracies) out += "; not observable: " + d.reason;
  return out;
}

GravityEstimator::GravityEstimator(std::unique_ptr<State> state) : state_(std::move(state)) {}
GravityEstimator::GravityEstimator(GravityEstimator&&) noexcept = default;
GravityEstimator& GravityEstimator::operator=(GravityEstimator&&) noexcept = default;
GravityEstimator::~GravityEstimator() = default;

int GravityEstimator::frames_added() const { return state_->added; }

Expected<GravityEstimator> GravityEstimator::Create(const GravityEstimatorConfig& config,
                                                    const Eigen::Matrix3d& R_body_imu,
                                                    const Eigen::Matrix3d& R_body_sensor_nominal) {
  if (Status s = config.Validate(); !s) return s.error();
  auto state = std::make_unique<State>();
  state->config = config;
  state->R_body_imu = R_body_imu;
  state->R_body_sensor = R_body_sensor_nominal;
  // The slow states' prior (a fixed state gets none: it stays at zero).
  Prior prior;
  std::vector<double> info;
  prior.blocks.push_back(state->prior_bias);
  prior.sizes.push_back(2);
  info.insert(info.end(), 2, 1.0 / config.attitude_bias_sigma_rad);
  if (config.estimate_accel_bias) {
    prior.blocks.push_back(state->ba);
    prior.sizes.push_back(3);
    info.insert(info.end(), 3, 1.0 / config.accel_bias_sigma_mps2);
  }
  if (config.estimate_gyro_bias) {
    prior.blocks.push_back(state->bg);
    prior.sizes.push_back(3);
    info.insert(info.end(), 3, 1.0 / config.gyro_bias_sigma_radps);
  }
  if (config.estimate_mount) {
    prior.blocks.push_back(state->mount);
    prior.sizes.push_back(2);
    info.insert(info.end(), 2, 1.0 / config.mount_sigma_rad);
  }
  if (config.estimate_odometry_scale) {
    prior.blocks.push_back(state->scale);
    prior.sizes.push_back(1);
    info.push_back(1.0 / config.odometry_scale_sigma);
  }
  if (!info.empty()) {
    const int n = static_cast<int>(info.size());
    prior.L = Eigen::Map<Eigen::VectorXd>(info.data(), n).asDiagonal();
    prior.x0 = Eigen::VectorXd::Zero(n);
    prior.e0 = Eigen::VectorXd::Zero(n);
    state->priors.push_back(std::move(prior));
  }
  return GravityEstimator(std::move(state));
}

Status GravityEstimator::Push(const GravityFrame& frame) {
  State& st = *state_;
  const GravityEstimatorConfig& c = st.config;
  if (!std::isfinite(frame.stamp_s)) return GravityError("frame.stamp_s", "must be finite");
  if (!st.window.empty() && !(frame.stamp_s > st.window.back()->input.stamp_s)) {
    return GravityError("frame.stamp_s", "must be after the previous frame's (" +
                                             std::to_string(st.window.back()->input.stamp_s) +
                                             " s), got " + std::to_string(frame.stamp_s));
  }
  if (!frame.odometry_xy_yaw.allFinite()) {
    return GravityError("frame.odometry_xy_yaw", "must be finite");
  }
  if (frame.velocity_world_mps && !frame.velocity_world_mps->allFinite()) {
    return GravityError("frame.velocity_world_mps", "must be finite");
  }
  if (frame.attitude_prior_rad && !frame.attitude_prior_rad->allFinite()) {
    return GravityError("frame.attitude_prior_rad", "must be finite");
  }
  for (std::size_t i = 0; i < frame.verticals.size(); ++i) {
    if (!(frame.verticals[i].direction_sensor.allFinite() &&
          frame.verticals[i].direction_sensor.norm() > 0.0)) {
      return GravityError("frame.verticals[" + std::to_string(i) + "]",
                          "must be a finite, non-zero direction");
    }
  }
  if (frame.ground_height_m &&
      !(std::isfinite(*frame.ground_height_m) && frame.ground_height_sigma_m > 0.0)) {
    return GravityError("frame.ground_height_m", "must be finite, with a sigma > 0");
  }
  for (std::size_t i = 0; i < frame.ground_rises.size(); ++i) {
    const GroundRise& r = frame.ground_rises[i];
    const std::string field = "frame.ground_rises[" + std::to_string(i) + "]";
    if (!Usable(r)) {
      return GravityError(field, "must be finite, with a sigma > 0");
    }
    if (!(r.earlier_stamp_s < frame.stamp_s)) {
      return GravityError(field + ".earlier_stamp_s", "must be before the frame's stamp");
    }
    // The window keeps its last window_frames - 1 frames beside this one.
    const std::size_t kept = static_cast<std::size_t>(c.window_frames - 1);
    const std::size_t first = st.window.size() > kept ? st.window.size() - kept : 0;
    bool found = false;  // looked for from the newest back: it is usually a frame or two
    for (std::size_t w = st.window.size(); w > first && !found; --w) {
      found = st.window[w - 1]->input.stamp_s == r.earlier_stamp_s;
    }
    if (!found) {
      return GravityError(
          field + ".earlier_stamp_s",
          "names no frame that stays in the window (" + std::to_string(r.earlier_stamp_s) + " s)");
    }
  }

  // Every sample checked before anything changes: a frame that fails leaves the state as it was.
  double last_stamp_s = st.last_sample_stamp_s;
  for (std::size_t j = 0; j < frame.imu.size(); ++j) {
    const GravityImuSample& s = frame.imu[j];
    if (!(std::isfinite(s.stamp_s) && s.specific_force_mps2.allFinite() &&
          s.angular_rate_radps.allFinite())) {
      return GravityError("frame.imu[" + std::to_string(j) + "]", "must be finite");
    }
    if (std::isfinite(last_stamp_s) && !(s.stamp_s > last_stamp_s)) {
      return GravityError("frame.imu[" + std::to_string(j) + "].stamp_s",
                          "must increase, got " + std::to_string(s.stamp_s) + " after " +
                              std::to_string(last_stamp_s));
    }
    last_stamp_s = s.stamp_s;
  }

  auto wf = std::make_unique<WindowFrame>();
  wf->input = frame;
  wf->input.imu.clear();  // kept as `samples`
  wf->id = st.added;
  for (std::size_t j = 0; j < frame.imu.size(); ++j) {
    const GravityImuSample& s = frame.imu[j];
    Sample sample;
    sample.raw = s;
    if (std::isfinite(st.last_sample_stamp_s)) {
      sample.dt_s = s.stamp_s - st.last_sample_stamp_s;
    } else if (j + 1 < frame.imu.size()) {
      sample.dt_s = frame.imu[j + 1].stamp_s - s.stamp_s;
    } else {
      sample.dt_s = 0.0;
    }
    st.last_sample_stamp_s = s.stamp_s;
    wf->samples.push_back(sample);
  }

  // Initial values: the previous frame turned by the gyro; the first from its prior or the
  // accelerometer.
  if (st.window.empty()) {
    if (frame.attitude_prior_rad) {
      wf->rpy[0] = (*frame.attitude_prior_rad)[0];
      wf->rpy[1] = (*frame.attitude_prior_rad)[1];
    } else if (!frame.imu.empty()) {
      Eigen::Vector3d f = Eigen::Vector3d::Zero();
      for (const GravityImuSample& s : frame.imu) f += st.R_body_imu * s.specific_force_mps2;
      wf->rpy[0] = std::atan2(f.y(), f.z());
      wf->rpy[1] = std::atan2(-f.x(), std::hypot(f.y(), f.z()));
    }
    wf->rpy[2] = frame.odometry_xy_yaw.z();
    wf->h[0] = frame.ground_height_m.value_or(0.0);
  } else {
    const WindowFrame& prev = *st.window.back();
    Eigen::Matrix3d R = gravity::WorldFromBody(prev.rpy);
    const Eigen::Vector3d bias(st.bg[0], st.bg[1], st.bg[2]);
    for (const Sample& s : wf->samples) {
      const Eigen::Vector3d w = st.R_body_imu * (s.raw.angular_rate_radps - bias) * s.dt_s;
      if (w.norm() > 0.0) R = R * Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
    }
    const Eigen::Matrix3d& Rm = R;
    wf->rpy[1] = std::atan2(-Rm(2, 0), std::hypot(Rm(0, 0), Rm(1, 0)));
    wf->rpy[0] = std::atan2(Rm(2, 1), Rm(2, 2));
    wf->rpy[2] = prev.rpy[2] + Wrap(frame.odometry_xy_yaw.z() - prev.input.odometry_xy_yaw.z());
    const double d = (frame.odometry_xy_yaw.head<2>() - prev.input.odometry_xy_yaw.head<2>()).norm();
    wf->h[0] = prev.h[0] - d * std::tan(wf->rpy[1]);
  }
  // Heading range and structure seen so far, for the reasons given with a flag.
  if (std::isfinite(st.last_heading)) {
    st.heading_unwrapped += Wrap(frame.odometry_xy_yaw.z() - st.last_heading);
  }
  st.last_heading = frame.odometry_xy_yaw.z();
  st.heading_min = std::min(st.heading_min, st.heading_unwrapped);
  st.heading_max = std::max(st.heading_max, st.heading_unwrapped);
  st.verticals_seen += static_cast<int>(frame.verticals.size());
  st.rises_seen += static_cast<int>(frame.ground_rises.size());

  if (frame.velocity_world_mps) {
    wf->velocity = *frame.velocity_world_mps;
    wf->chord_from_s = wf->chord_to_s = frame.stamp_s;
  }
  st.window.push_back(std::move(wf));
  ++st.added;
  // The mean velocity over the odometry's chord from frame a to frame b of the window.
  const auto chord = [&st](std::size_t a, std::size_t b, WindowFrame& to) {
    const GravityFrame& before = st.window[a]->input;
    const GravityFrame& after = st.window[b]->input;
    Eigen::Vector3d v = Eigen::Vector3d::Zero();
    v.head<2>() = (after.odometry_xy_yaw.head<2>() - before.odometry_xy_yaw.head<2>()) /
                  (after.stamp_s - before.stamp_s);
    to.velocity = v;
    to.chord_from_s = before.stamp_s;
    to.chord_to_s = after.stamp_s;
  };
  if (st.window.size() >= 2) {
    const std::size_t j = st.window.size() - 2;
    WindowFrame& middle = *st.window[j];
    if (!middle.velocity || middle.provisional) {
      chord(j > 0 ? j - 1 : j, j + 1, middle);
      middle.provisional = false;
    }
    WindowFrame& newest = *st.window.back();
    if (!newest.velocity) {
      chord(j, j + 1, newest);
      newest.provisional = true;
    }
  }
  while (static_cast<int>(st.window.size()) > c.window_frames) st.Marginalise();
  return {};
}

ceres::Solver::Summary GravityEstimator::State::Solve(ceres::Problem& problem,
                                                      std::vector<Residual>& residuals, bool sparse,
                                                      int max_iterations) {
  const GravityEstimatorConfig& c = config;
  Build(problem, residuals);
  if (!c.estimate_accel_bias) problem.SetParameterBlockConstant(ba);
  if (!c.estimate_gyro_bias) problem.SetParameterBlockConstant(bg);
  if (!c.estimate_mount) problem.SetParameterBlockConstant(mount);
  if (c.estimate_odometry_scale) {
    problem.SetParameterLowerBound(scale, 0, -0.5);  // the terms divide by 1 + s
    problem.SetParameterUpperBound(scale, 0, 0.5);
  } else {
    problem.SetParameterBlockConstant(scale);
  }
  ceres::Solver::Options options;
  options.linear_solver_type = sparse ? ceres::SPARSE_NORMAL_CHOLESKY : ceres::DENSE_QR;
  options.max_num_iterations = max_iterations;
  options.num_threads = 1;
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  return summary;
}

namespace {

// Gravity's up in the sensor frame, for a body at roll and pitch rpy[0..1] and a mount tilted
// by (mount[0], mount[1]) from R_body_sensor.
Eigen::Vector3d UpInSensor(const double* rpy, const double* mount,
                           const Eigen::Matrix3d& R_body_sensor) {
  const Eigen::Vector3d up_body =
      gravity::LevelFromBody(rpy).transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Matrix3d R_mount = gravity::RotY(mount[1]) * gravity::RotX(mount[0]);
  return (R_mount * R_body_sensor).transpose() * up_body;
}

}  // namespace

GravityEstimate GravityEstimator::State::EstimateOf(const WindowFrame& frame) const {
  GravityEstimate est;
  est.stamp_s = frame.input.stamp_s;
  est.roll_rad = Wrap(frame.rpy[0]);
  est.pitch_rad = frame.rpy[1];
  est.yaw_rad = Wrap(frame.rpy[2]);
  est.height_m = frame.h[0];
  est.accel_bias_mps2 = Eigen::Vector3d(ba[0], ba[1], ba[2]);
  est.gyro_bias_radps = Eigen::Vector3d(bg[0], bg[1], bg[2]);
  est.mount_rad = Eigen::Vector2d(mount[0], mount[1]);
  est.attitude_bias_rad = Eigen::Vector2d(prior_bias[0], prior_bias[1]);
  est.odometry_scale = scale[0];
  const Eigen::Matrix3d R_level_body = gravity::LevelFromBody(frame.rpy);
  est.up_body = R_level_body.transpose() * Eigen::Vector3d::UnitZ();
  est.up_sensor = UpInSensor(frame.rpy, mount, R_body_sensor);
  return est;
}

namespace {

void SetSolverFigures(const ceres::Solver::Summary& summary, GravityEstimate& est) {
  est.iterations = static_cast<int>(summary.iterations.size());
  est.initial_cost = summary.initial_cost;
  est.final_cost = summary.final_cost;
  est.converged = summary.IsSolutionUsable();
  est.solver_report = summary.BriefReport();
}

}  // namespace

Expected<GravityEstimate> GravityEstimator::AddFrame(const GravityFrame& frame) {
  if (Status s = Push(frame); !s) return s.error();
  State& st = *state_;
  const GravityEstimatorConfig& c = st.config;
  ceres::Problem problem;
  std::vector<Residual> residuals;
  const ceres::Solver::Summary summary =
      st.Solve(problem, residuals, /*sparse=*/false, c.max_iterations);
  WindowFrame& newest = *st.window.back();
  GravityEstimate est = st.EstimateOf(newest);
  SetSolverFigures(summary, est);

  // Cues.
  GravityCues& cues = est.cues;
  for (const Residual& r : residuals) {
    switch (r.kind) {
      case Kind::kAccel:
      case Kind::kVertical: {
        const ceres::CostFunction* cost = problem.GetCostFunctionForResidualBlock(r.id);
        std::vector<double> values(cost->num_residuals());
        std::vector<const double*> params(r.blocks.begin(), r.blocks.end());
        cost->Evaluate(params.data(), values.data(), nullptr);
        double sq = 0.0;
        for (double v : values) sq += v * v;
        const bool outlier = std::sqrt(sq) > (r.kind == Kind::kAccel ? c.accel_huber : 3.0);
        if (r.kind == Kind::kAccel) {
          ++cues.accel_terms;
          cues.accel_outliers += outlier ? 1 : 0;
        } else {
          ++cues.verticals;
          cues.vertical_outliers += outlier ? 1 : 0;
        }
        break;
      }
      case Kind::kGyro: ++cues.gyro_terms; break;
      case Kind::kAttitude: ++cues.attitude_priors; break;
      case Kind::kGround: ++cues.ground_heights; break;
      case Kind::kGroundRise:
        ++cues.ground_rises;
        break;
      default: break;
    }
  }
  cues.frame_imu_samples = static_cast<int>(frame.imu.size());
  cues.frame_verticals = static_cast<int>(frame.verticals.size());
  cues.heading_change_rad = st.heading_max - st.heading_min;

  // Covariance and what it says about observability.
  if (c.covariance) {
    ceres::Covariance::Options cov_options;
    cov_options.algorithm_type = ceres::DENSE_SVD;
    cov_options.null_space_rank = -1;
    ceres::Covariance covariance(cov_options);
    std::vector<std::pair<const double*, const double*>> blocks = {{newest.rpy, newest.rpy},
                                                                   {newest.h, newest.h}};
    if (c.estimate_accel_bias) blocks.emplace_back(st.ba, st.ba);
    if (c.estimate_gyro_bias) blocks.emplace_back(st.bg, st.bg);
    if (c.estimate_mount) {
      blocks.emplace_back(st.mount, st.mount);
      blocks.emplace_back(newest.rpy, st.mount);
    }
    if (covariance.Compute(blocks, &problem)) {
      Eigen::Matrix<double, 3, 3, Eigen::RowMajor> m3;
      covariance.GetCovarianceBlock(newest.rpy, newest.rpy, m3.data());
      est.attitude_covariance = m3;
      covariance.GetCovarianceBlock(newest.h, newest.h, &est.height_variance);
      if (c.estimate_accel_bias) {
        covariance.GetCovarianceBlock(st.ba, st.ba, m3.data());
        est.accel_bias_covariance = m3;
      }
      if (c.estimate_gyro_bias) {
        covariance.GetCovarianceBlock(st.bg, st.bg, m3.data());
        est.gyro_bias_covariance = m3;
      }
      // The sensor's up: (roll, pitch, yaw, mount roll, mount pitch) -> up_sensor, to first
      // order (central differences).
      Eigen::Matrix<double, 5, 5> S = Eigen::Matrix<double, 5, 5>::Zero();
      S.topLeftCorner<3, 3>() = est.attitude_covariance;
      if (c.estimate_mount) {
        Eigen::Matrix<double, 2, 2, Eigen::RowMajor> m2;
        covariance.GetCovarianceBlock(st.mount, st.mount, m2.data());
        est.mount_covariance = m2;
        Eigen::Matrix<double, 3, 2, Eigen::RowMajor> cross;
        covariance.GetCovarianceBlock(newest.rpy, st.mount, cross.data());
        S.bottomRightCorner<2, 2>() = m2;
        S.topRightCorner<3, 2>() = cross;
        S.bottomLeftCorner<2, 3>() = cross.transpose();
      }
      const auto up_of = [&](const Eigen::Matrix<double, 5, 1>& x) {
        return UpInSensor(x.data(), x.data() + 3, st.R_body_sensor);
      };
      Eigen::Matrix<double, 5, 1> x0;
      x0 << newest.rpy[0], newest.rpy[1], newest.rpy[2], st.mount[0], st.mount[1];
      Eigen::Matrix<double, 3, 5> J;
      constexpr double kStep = 1e-6;
      for (int j = 0; j < 5; ++j) {
        Eigen::Matrix<double, 5, 1> plus = x0, minus = x0;
        plus[j] += kStep;
        minus[j] -= kStep;
        J.col(j) = (up_of(plus) - up_of(minus)) / (2.0 * kStep);
      }
      est.up_sensor_covariance = J * S * J.transpose();
      char why[256];
      const double limit = c.observable_ratio;
      if (c.estimate_accel_bias) {
        // Along the body's horizontal axes (the IMU's may point anywhere).
        const Eigen::Matrix3d P =
            st.R_body_imu * est.accel_bias_covariance * st.R_body_imu.transpose();
        const double sx = std::sqrt(P(0, 0)), sy = std::sqrt(P(1, 1));
        if (std::max(sx, sy) > limit * c.accel_bias_sigma_mps2) {
          std::snprintf(why, sizeof(why),
                        "accelerometer bias (sigma %.3f %.3f m/s^2 of %.3f a priori): the heading "
                        "changed %.0f deg so far; on a straight drive a bias and a tilt look "
                        "alike, a turn or a change of attitude tells them apart (tilt uncertain by "
                        "up to %.2f deg)",
                        sx, sy, c.accel_bias_sigma_mps2, cues.heading_change_rad / kDegToRad,
                        std::max(sx, sy) / c.gravity_mps2 / kDegToRad);
          est.degeneracies.push_back({GravityDegeneracy::State::kAccelBias, why});
        }
      }
      if (c.estimate_gyro_bias) {
        const double s = std::sqrt(est.gyro_bias_covariance.diagonal().maxCoeff());
        if (s > limit * c.gyro_bias_sigma_radps) {
          std::snprintf(why, sizeof(why), "gyro bias (sigma %.4f rad/s of %.4f a priori)", s,
                        c.gyro_bias_sigma_radps);
          est.degeneracies.push_back({GravityDegeneracy::State::kGyroBias, why});
        }
      }
      if (c.estimate_mount) {
        const double s = std::sqrt(est.mount_covariance.diagonal().maxCoeff());
        if (s > limit * c.mount_sigma_rad) {
          std::snprintf(
              why, sizeof(why),
              "sensor mount tilt (sigma %.2f deg of %.2f a priori): %d vertical cues and %d "
              "ground rises so far; the mount needs trunks, poles or walls in view, or ground "
              "seen by two frames",
              s / kDegToRad, c.mount_sigma_rad / kDegToRad, st.verticals_seen, st.rises_seen);
          est.degeneracies.push_back({GravityDegeneracy::State::kMount, why});
        }
      }
    } else {
      est.degeneracies.push_back(
          {GravityDegeneracy::State::kCovariance, "covariance: the window's problem is rank deficient"});
    }
  }
  return est;
}

Expected<GravitySmoother> GravitySmoother::Create(const GravityEstimatorConfig& config,
                                                  const Eigen::Matrix3d& R_body_imu,
                                                  const Eigen::Matrix3d& R_body_sensor_nominal) {
  GravityEstimatorConfig c = config;
  c.window_frames = std::numeric_limits<int>::max();  // nothing leaves
  Expected<GravityEstimator> estimator =
      GravityEstimator::Create(c, R_body_imu, R_body_sensor_nominal);
  if (!estimator) return estimator.error();
  return GravitySmoother(std::move(*estimator));
}

Status GravitySmoother::Add(const GravityFrame& frame, const GravityEstimate* start) {
  if (start != nullptr && !(std::isfinite(start->roll_rad) && std::isfinite(start->pitch_rad) &&
                            std::isfinite(start->height_m))) {
    return GravityError("start", "must be a finite roll, pitch and height");
  }
  if (Status s = estimator_.Push(frame); !s) return s;
  if (start != nullptr) {
    WindowFrame& f = *estimator_.state_->window.back();
    f.rpy[0] = start->roll_rad;
    f.rpy[1] = start->pitch_rad;
    f.h[0] = start->height_m;
  }
  return {};
}

int GravitySmoother::frames() const { return estimator_.frames_added(); }

std::string GravitySmoother::SaveState() const { return estimator_.SaveState(); }

Status GravitySmoother::RestoreState(const std::string& state) {
  const GravityEstimator::State& own = *estimator_.state_;
  Expected<GravityEstimator> restored =
      GravityEstimator::Create(own.config, own.R_body_imu, own.R_body_sensor);
  if (!restored) return restored.error();
  if (Status s = restored->RestoreState(state); !s) return s;
  const GravityEstimator::State& st = *restored->state_;
  if (st.added != static_cast<int>(st.window.size())) {
    return GravityError("smoother state",
                        "is a sliding window's (frames left it): a smoother "
                        "keeps every frame");
  }
  estimator_ = std::move(*restored);
  return {};
}

const GravityFrame& GravitySmoother::frame(int index) const {
  return estimator_.state_->window.at(static_cast<std::size_t>(index))->input;
}

Expected<std::vector<GravityEstimate>> GravitySmoother::Solve() {
  GravityEstimator::State& st = *estimator_.state_;
  if (st.window.empty()) return GravityError("smoother", "has no frames to solve");
  // The states as they stand, put back once solved: solving again, or saving the smoother,
  // starts from them as this solve did.
  std::vector<std::array<double, 4>> frames;
  for (const auto& f : st.window) frames.push_back({f->rpy[0], f->rpy[1], f->rpy[2], f->h[0]});
  std::array<double, 11> slow = {st.ba[0],         st.ba[1],         st.ba[2],    st.bg[0],
                                 st.bg[1],         st.bg[2],         st.mount[0], st.mount[1],
                                 st.prior_bias[0], st.prior_bias[1], st.scale[0]};
  // Twice: the IMU terms are pre-integrated at the gyro bias as it stands, which the first
  // solve learns.
  ceres::Solver::Summary summary;
  for (int round = 0; round < 2; ++round) {
    ceres::Problem problem;
    std::vector<Residual> residuals;
    summary = st.Solve(problem, residuals, /*sparse=*/true,
                       std::max(st.config.max_iterations, kSmootherIterations));
  }
  std::vector<GravityEstimate> out;
  out.reserve(st.window.size());
  for (const auto& frame : st.window) {
    out.push_back(st.EstimateOf(*frame));
    SetSolverFigures(summary, out.back());
  }
  for (std::size_t k = 0; k < frames.size(); ++k) {
    WindowFrame& f = *st.window[k];
    f.rpy[0] = frames[k][0];
    f.rpy[1] = frames[k][1];
    f.rpy[2] = frames[k][2];
    f.h[0] = frames[k][3];
  }
  double* const slow_states[11] = {&st.ba[0],         &st.ba[1],         &st.ba[2],    &st.bg[0],
                                   &st.bg[1],         &st.bg[2],         &st.mount[0], &st.mount[1],
                                   &st.prior_bias[0], &st.prior_bias[1], &st.scale[0]};
  for (int k = 0; k < 11; ++k) *slow_states[k] = slow[static_cast<std::size_t>(k)];
  if (summary.termination_type != ceres::CONVERGENCE) {
    return GravityError("smoother", "the solve did not converge: " + summary.BriefReport());
  }
  return out;
}

namespace {

using nlohmann::json;

using internal::Array;
using internal::ArrayFrom;
using internal::Number;
using internal::NumberFrom;

Eigen::Vector3d Vector3From(const json& j, const char* what) {
  Eigen::Vector3d v;
  ArrayFrom(j, v.data(), 3, what);
  return v;
}

json FrameJson(const WindowFrame& f) {
  const GravityFrame& in = f.input;
  json samples = json::array();
  for (const Sample& s : f.samples) {
    const Eigen::Vector3d& a = s.raw.specific_force_mps2;
    const Eigen::Vector3d& w = s.raw.angular_rate_radps;
    samples.push_back({s.raw.stamp_s, s.dt_s, a.x(), a.y(), a.z(), w.x(), w.y(), w.z()});
  }
  json verticals = json::array();
  for (const VerticalCue& v : in.verticals) {
    verticals.push_back({Array(v.direction_sensor.data(), 3), v.wall_normal});
  }
  json j = {{"id", f.id},
            {"rpy", Array(f.rpy, 3)},
            {"h", f.h[0]},
            {"stamp", in.stamp_s},
            {"odom", Array(in.odometry_xy_yaw.data(), 3)},
            {"verticals", verticals},
            {"ground_sigma", in.ground_height_sigma_m},
            {"samples", samples}};
  if (f.velocity) {
    j["velocity"] = Array(f.velocity->data(), 3);
    j["chord"] = {f.chord_from_s, f.chord_to_s};
    if (f.provisional) j["provisional"] = true;
  }
  if (in.velocity_world_mps) j["velocity_world"] = Array(in.velocity_world_mps->data(), 3);
  if (in.attitude_prior_rad) j["attitude"] = Array(in.attitude_prior_rad->data(), 2);
  if (in.ground_height_m) j["ground"] = *in.ground_height_m;
  if (!in.ground_rises.empty()) {
    json rises = json::array();
    for (const GroundRise& r : in.ground_rises) {
      rises.push_back({{"earlier", r.earlier_stamp_s},
                       {"rise", r.rise_m},
                       {"R", Array(r.R_world_sensor.data(), 9)},
                       {"R_earlier", Array(r.R_world_sensor_earlier.data(), 9)},
                       {"Rb", Array(r.R_world_body.data(), 9)},
                       {"Rb_earlier", Array(r.R_world_body_earlier.data(), 9)},
                       {"sensor_on_body", Array(r.sensor_on_body_m.data(), 3)},
                       {"offset", Array(r.offset_m.data(), 3)},
                       {"offset_earlier", Array(r.offset_earlier_m.data(), 3)},
                       {"step", Array(r.odometry_step_m.data(), 2)},
                       {"gradient", Array(r.gradient.data(), 2)},
                       {"sigma", r.sigma_m}});
    }
    j["rises"] = rises;
  }
  return j;
}

std::unique_ptr<WindowFrame> FrameFrom(const json& j) {
  auto f = std::make_unique<WindowFrame>();
  GravityFrame& in = f->input;
  f->id = j.at("id").get<int>();
  ArrayFrom(j.at("rpy"), f->rpy, 3, "rpy");
  f->h[0] = j.at("h").get<double>();
  in.stamp_s = j.at("stamp").get<double>();
  in.odometry_xy_yaw = Vector3From(j.at("odom"), "odom");
  for (const json& v : j.at("verticals")) {
    in.verticals.push_back({Vector3From(v.at(0), "verticals"), v.at(1).get<bool>()});
  }
  in.ground_height_sigma_m = j.at("ground_sigma").get<double>();
  for (const json& s : j.at("samples")) {
    double v[8];
    ArrayFrom(s, v, 8, "samples");
    Sample sample;
    sample.raw.stamp_s = v[0];
    sample.dt_s = v[1];
    sample.raw.specific_force_mps2 = Eigen::Vector3d(v[2], v[3], v[4]);
    sample.raw.angular_rate_radps = Eigen::Vector3d(v[5], v[6], v[7]);
    f->samples.push_back(sample);
  }
  if (j.contains("velocity")) {
    f->velocity = Vector3From(j.at("velocity"), "velocity");
    double chord[2];
    ArrayFrom(j.at("chord"), chord, 2, "chord");
    if (!(chord[0] <= chord[1])) throw std::runtime_error("chord: its ends are not in order");
    f->chord_from_s = chord[0];
    f->chord_to_s = chord[1];
    f->provisional = j.value("provisional", false);
  }
  if (j.contains("velocity_world")) {
    in.velocity_world_mps = Vector3From(j.at("velocity_world"), "velocity_world");
  }
  if (j.contains("attitude")) {
    Eigen::Vector2d a;
    ArrayFrom(j.at("attitude"), a.data(), 2, "attitude");
    in.attitude_prior_rad = a;
  }
  if (j.contains("ground")) in.ground_height_m = j.at("ground").get<double>();
  if (j.contains("rises")) {
    for (const json& rj : j.at("rises")) {
      GroundRise r;
      r.earlier_stamp_s = rj.at("earlier").get<double>();
      r.rise_m = rj.at("rise").get<double>();
      ArrayFrom(rj.at("R"), r.R_world_sensor.data(), 9, "R");
      ArrayFrom(rj.at("R_earlier"), r.R_world_sensor_earlier.data(), 9, "R_earlier");
      ArrayFrom(rj.at("Rb"), r.R_world_body.data(), 9, "Rb");
      ArrayFrom(rj.at("Rb_earlier"), r.R_world_body_earlier.data(), 9, "Rb_earlier");
      r.sensor_on_body_m = Vector3From(rj.at("sensor_on_body"), "sensor_on_body");
      r.offset_m = Vector3From(rj.at("offset"), "offset");
      r.offset_earlier_m = Vector3From(rj.at("offset_earlier"), "offset_earlier");
      ArrayFrom(rj.at("step"), r.odometry_step_m.data(), 2, "step");
      ArrayFrom(rj.at("gradient"), r.gradient.data(), 2, "gradient");
      r.sigma_m = rj.at("sigma").get<double>();
      if (!(Usable(r) && r.earlier_stamp_s < in.stamp_s)) {
        throw std::runtime_error(
            "rises: a rise is not finite, its sigma not > 0 or its earlier "
            "frame not before its own");
      }
      in.ground_rises.push_back(r);
    }
  }
  return f;
}

}  // namespace

namespace {

// The settings that shape the window's problem: a state is only restored under the same.
json ConfigJson(const GravityEstimatorConfig& c) {
  return {{"window_frames", c.window_frames},
          {"accel_half_span_frames", c.accel_half_span_frames},
          {"accel_warmup_spans", c.accel_warmup_spans},
          {"estimate_accel_bias", c.estimate_accel_bias},
          {"estimate_gyro_bias", c.estimate_gyro_bias},
          {"estimate_mount", c.estimate_mount},
          {"estimate_odometry_scale", c.estimate_odometry_scale}};
}

// The frame id after "rpy:" / "h:", the whole rest of the name a non-negative integer.
int FrameIdOf(const std::string& digits, const std::string& name) {
  if (digits.empty() || digits.size() > 9 ||
      digits.find_first_not_of("0123456789") != std::string::npos) {
    throw std::runtime_error("a prior's block '" + name + "' names no frame id");
  }
  return std::stoi(digits);
}

}  // namespace

// A prior's blocks are named: the slow states by name, a frame's states by its id.
std::string GravityEstimator::SaveState() const {
  const State& st = *state_;
  const auto name = [&](const double* block) -> std::string {
    if (block == st.ba) return "ba";
    if (block == st.bg) return "bg";
    if (block == st.mount) return "mount";
    if (block == st.prior_bias) return "attitude_bias";
    if (block == st.scale) return "odometry_scale";
    for (const auto& f : st.window) {
      if (block == f->rpy) return "rpy:" + std::to_string(f->id);
      if (block == f->h) return "h:" + std::to_string(f->id);
    }
    return "?";  // not reached: every prior's block is one of these
  };
  json window = json::array();
  for (const auto& f : st.window) window.push_back(FrameJson(*f));
  json priors = json::array();
  for (const Prior& p : st.priors) {
    json blocks = json::array();
    for (const double* b : p.blocks) blocks.push_back(name(b));
    priors.push_back({{"blocks", blocks},
                      {"L", Array(p.L.data(), static_cast<int>(p.L.size()))},
                      {"x0", Array(p.x0.data(), static_cast<int>(p.x0.size()))},
                      {"e0", Array(p.e0.data(), static_cast<int>(p.e0.size()))}});
  }
  const GravityEstimatorConfig& c = st.config;
  const json j = {{"config", ConfigJson(c)},
                  {"window", window},
                  {"priors", priors},
                  {"ba", Array(st.ba, 3)},
                  {"bg", Array(st.bg, 3)},
                  {"mount", Array(st.mount, 2)},
                  {"attitude_bias", Array(st.prior_bias, 2)},
                  {"odometry_scale", st.scale[0]},
                  {"added", st.added},
                  {"last_sample_stamp", Number(st.last_sample_stamp_s)},
                  {"heading", {st.heading_unwrapped, st.heading_min, st.heading_max}},
                  {"last_heading", Number(st.last_heading)},
                  {"verticals_seen", st.verticals_seen},
                  {"rises_seen", st.rises_seen}};
  return j.dump();
}

Status GravityEstimator::RestoreState(const std::string& text) {
  auto next = std::make_unique<State>();
  State& st = *next;
  st.config = state_->config;
  st.R_body_imu = state_->R_body_imu;
  st.R_body_sensor = state_->R_body_sensor;
  try {
    const json j = json::parse(text);
    if (j.at("config") != ConfigJson(st.config)) {
      return GravityError("state", "was saved with other settings (" + j.at("config").dump() +
                                       ", here " + ConfigJson(st.config).dump() + ")");
    }
    for (const json& f : j.at("window")) st.window.push_back(FrameFrom(f));
    if (static_cast<int>(st.window.size()) > st.config.window_frames) {
      return GravityError("state", "holds " + std::to_string(st.window.size()) +
                                       " frames, more than the window (" +
                                       std::to_string(st.config.window_frames) + ")");
    }
    st.added = j.at("added").get<int>();
    if (st.added < static_cast<int>(st.window.size())) {
      return GravityError(
          "state", "'added' (" + std::to_string(st.added) + ") is less than the window's frames");
    }
    // The window's frames: consecutive ids ending at the last frame added, stamps rising.
    for (std::size_t k = 0; k < st.window.size(); ++k) {
      const WindowFrame& f = *st.window[k];
      const int want = st.added - static_cast<int>(st.window.size() - k);
      if (f.id != want) {
        return GravityError("state", "window frame " + std::to_string(k) + " has id " +
                                         std::to_string(f.id) + ", expected " +
                                         std::to_string(want) + " (ids run to added - 1)");
      }
      if (k > 0 && !(f.input.stamp_s > st.window[k - 1]->input.stamp_s)) {
        return GravityError("state",
                            "window frame " + std::to_string(k) + ": stamps must increase");
      }
    }
    // The IMU samples in time order with their intervals, as Push keeps them (SegmentsOf
    // looks them up by stamp).
    double last_sample = -std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < st.window.size(); ++k) {
      for (const Sample& sample : st.window[k]->samples) {
        if (!(sample.raw.stamp_s > last_sample && sample.dt_s >= 0.0)) {
          return GravityError("state", "window frame " + std::to_string(k) +
                                           ": IMU sample stamps must increase, their "
                                           "intervals be >= 0");
        }
        last_sample = sample.raw.stamp_s;
      }
    }
    ArrayFrom(j.at("ba"), st.ba, 3, "ba");
    ArrayFrom(j.at("bg"), st.bg, 3, "bg");
    ArrayFrom(j.at("mount"), st.mount, 2, "mount");
    ArrayFrom(j.at("attitude_bias"), st.prior_bias, 2, "attitude_bias");
    st.scale[0] = j.at("odometry_scale").get<double>();
    if (!(std::abs(st.scale[0]) < 0.5)) {
      return GravityError(
          "state", "odometry_scale " + std::to_string(st.scale[0]) + " is outside (-0.5, 0.5)");
    }
    const auto block = [&](const std::string& name, int& size) -> double* {
      if (name == "ba") return size = 3, st.ba;
      if (name == "bg") return size = 3, st.bg;
      if (name == "mount") return size = 2, st.mount;
      if (name == "attitude_bias") return size = 2, st.prior_bias;
      if (name == "odometry_scale") return size = 1, st.scale;
      const std::size_t colon = name.find(':');
      if (colon != std::string::npos) {
        const std::string part = name.substr(0, colon);
        const int id = FrameIdOf(name.substr(colon + 1), name);
        for (const auto& f : st.window) {
          if (f->id != id) continue;
          if (part == "rpy") return size = 3, f->rpy;
          if (part == "h") return size = 1, f->h;
        }
      }
      throw std::runtime_error("a prior's block '" + name + "' is no state of the window");
    };
    for (const json& pj : j.at("priors")) {
      Prior p;
      int n = 0;
      std::set<double*> seen;
      for (const json& b : pj.at("blocks")) {
        int size = 0;
        const std::string name = b.get<std::string>();
        p.blocks.push_back(block(name, size));
        if (!seen.insert(p.blocks.back()).second) {
          throw std::runtime_error("a prior names block '" + name + "' twice");
        }
        p.sizes.push_back(size);
        n += size;
      }
      if (n == 0) throw std::runtime_error("a prior without blocks");
      p.L.resize(n, n);
      p.x0.resize(n);
      p.e0.resize(n);
      ArrayFrom(pj.at("L"), p.L.data(), n * n, "L");
      ArrayFrom(pj.at("x0"), p.x0.data(), n, "x0");
      ArrayFrom(pj.at("e0"), p.e0.data(), n, "e0");
      st.priors.push_back(std::move(p));
    }
    st.last_sample_stamp_s = NumberFrom(j.at("last_sample_stamp"));
    double heading[3];
    ArrayFrom(j.at("heading"), heading, 3, "heading");
    st.heading_unwrapped = heading[0];
    st.heading_min = heading[1];
    st.heading_max = heading[2];
    st.last_heading = NumberFrom(j.at("last_heading"));
    st.verticals_seen = j.at("verticals_seen").get<int>();
    st.rises_seen = j.value("rises_seen", 0);  // absent before the ground rises
  } catch (const std::exception& e) {
    return GravityError("state", std::string("unreadable: ") + e.what());
  }
  state_ = std::move(next);
  return Status::Ok();
}

}  // namespace cairn::map
