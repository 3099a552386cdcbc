#pragma once
// A synthetic robot for back-end tests: a true path (a rectangle driven
// counter-clockwise, repeatedly), odometry with the motion model's noise,
// landmarks created along the first lap at known true poses, and relative
// pose measurements y = h(s, phi) + v with v ~ N(0, Sigma) taken when the
// robot is within range of a landmark's creation pose and facing the same
// way. Test data only.

#include <cmath>
#include <cstdint>
#include <vector>

#include "backend/measurement_model.hpp"
#include "backend/rng.hpp"
#include "odometry/motion_model.hpp"

namespace vslam::backend::test {

struct SyntheticParams {
  double width_m = 4.0;
  double height_m = 3.0;
  double speed_mps = 0.3;
  double rate_hz = 50;        // odometry
  double measurement_hz = 5;  // visual measurements (per visible landmark, at most one per tick)
  double landmark_spacing_m = 0.8;
  double range_m = 1.0;         // measured within this distance of the creation pose...
  double max_heading_deg = 40;  // ...and this heading difference
  MotionNoise odometry_noise{0.03, 0.03};
  double sigma_xy_m = 0.03;  // measurement noise
  double sigma_theta_rad = 0.01;
  uint64_t seed = 7;
};

struct TrueLandmark {
  int64_t id;
  Pose2 pose;   // map frame = start frame
  size_t tick;  // when it was created (its pose is the true pose then)
};

// Precomputed run: per odometry tick the true pose and the cumulative
// odometry reading; measurements attached to ticks.
struct SyntheticMeasurement {
  size_t tick;
  int64_t landmark_id;
  Pose2 y;
};

class SyntheticWorld {
 public:
  explicit SyntheticWorld(SyntheticParams p) : p_(p) {}

  // Builds `laps` laps. A kidnapping at tick `kidnap_tick` (if > 0) carries
  // the robot kidnap_jump_m further along its path without the odometry
  // seeing it (the wheels turn as before, the robot is elsewhere).
  void build(double laps, size_t kidnap_tick = 0, double kidnap_jump_m = 0) {
    const double perimeter = 2 * (p_.width_m + p_.height_m);
    const double step = p_.speed_mps / p_.rate_hz;
    const auto ticks = static_cast<size_t>(laps * perimeter / step);
    const auto jump = static_cast<size_t>(kidnap_jump_m / step);
    // The noise-free path by arc length: straight sides, a 90 degree turn
    // over the last 0.2 m before each corner.
    std::vector<Pose2> path{Pose2{}};
    for (size_t k = 1; k <= ticks + jump; ++k) {
      const double s = std::fmod((k - 1) * step, perimeter);
      const double sides[4] = {p_.width_m, p_.height_m, p_.width_m, p_.height_m};
      double acc = 0, turn = 0;
      for (double side : sides) {
        acc += side;
        if (s < acc) {
          if (s + step > acc - 0.2) turn = (M_PI / 2) * step / 0.2;
          break;
        }
      }
      path.push_back(path.back().compose({step, 0, turn}));
    }
    auto index = [&](size_t t) { return t + (kidnap_tick > 0 && t >= kidnap_tick ? jump : 0); };
    RandomStream rng(p_.seed, 0, 0, 0);
    Pose2 odom;
    truth_.push_back(path[0]);
    odometry_.push_back(odom);
    double next_landmark = 0.1;
    const auto measure_every = static_cast<size_t>(p_.rate_hz / p_.measurement_hz);
    for (size_t t = 1; t <= ticks; ++t) {
      const size_t i = index(t);
      const Pose2 truth = path[i];
      // What the wheels did: the step of the path before a kidnapping, the
      // robot's own step after it.
      const Pose2 motion =
          t == kidnap_tick ? path[t - 1].between(path[t]) : path[i - 1].between(path[i]);
      odom = odom.compose(p_.odometry_noise.perturb(motion, rng.normal(), rng.normal()));
      truth_.push_back(truth);
      odometry_.push_back(odom);
      const double arc = static_cast<double>(i) * step;
      if (arc <= perimeter && arc >= next_landmark) {
        landmarks_.push_back({static_cast<int64_t>(1000000000 + landmarks_.size()), truth, t});
        next_landmark += p_.landmark_spacing_m;
      }
      if (t % measure_every == 0) {
        // The closest visible landmark created so far.
        const TrueLandmark* best = nullptr;
        double best_d = p_.range_m;
        for (const TrueLandmark& l : landmarks_) {
          const Pose2 rel = l.pose.between(truth);
          const double d = std::hypot(rel.x, rel.y);
          if (d < best_d && std::abs(rel.theta) < p_.max_heading_deg * M_PI / 180) {
            best_d = d;
            best = &l;
          }
        }
        if (best) {
          Pose2 y = predictMeasurement(truth, best->pose);
          y.x += p_.sigma_xy_m * rng.normal();
          y.y += p_.sigma_xy_m * rng.normal();
          y.theta = wrapAngle(y.theta + p_.sigma_theta_rad * rng.normal());
          measurements_.push_back({t, best->id, y});
        }
      }
    }
  }

  const std::vector<Pose2>& truth() const { return truth_; }
  const std::vector<Pose2>& odometry() const { return odometry_; }
  const std::vector<TrueLandmark>& landmarks() const { return landmarks_; }
  const std::vector<SyntheticMeasurement>& measurements() const { return measurements_; }
  int64_t utime(size_t tick) const {
    return 1700000000000000LL + static_cast<int64_t>(tick * 1e6 / p_.rate_hz);
  }
  const SyntheticParams& params() const { return p_; }

 private:
  SyntheticParams p_;
  std::vector<Pose2> truth_, odometry_;
  std::vector<TrueLandmark> landmarks_;
  std::vector<SyntheticMeasurement> measurements_;
};

}  // namespace vslam::backend::test
