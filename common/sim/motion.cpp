#include "sim/motion.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace vslam::sim {

Pose2 unicycleStep(double v, double omega, double dt) {
  const double dtheta = omega * dt;
  if (std::abs(dtheta) < 1e-9) return {v * dt, 0.0, dtheta};
  const double r = v / omega;
  return {r * std::sin(dtheta), r * (1.0 - std::cos(dtheta)), dtheta};
}

// ---- WaypointDriver ----

WaypointDriver::WaypointDriver(const MotionParams& params) : params_(params) {
  for (int lap = 0; lap < params_.laps; ++lap) {
    route_.insert(route_.end(), params_.waypoints.begin(), params_.waypoints.end());
  }
  route_.push_back(params_.waypoints.front());  // close the last lap
}

bool WaypointDriver::advance(const Pose2& current, double dt, Pose2* step) {
  constexpr double kArrived = 0.01;       // m
  constexpr double kStartDriving = 0.03;  // rad: aligned enough to drive
  constexpr double kStopDriving = 0.35;   // rad: so far off that it turns in place again
  while (next_ < route_.size() &&
         (route_[next_] - Eigen::Vector2d(current.x, current.y)).norm() < kArrived) {
    ++next_;
    turning_ = true;
  }
  if (next_ >= route_.size()) return false;
  const Eigen::Vector2d d = route_[next_] - Eigen::Vector2d(current.x, current.y);
  const double bearing = wrapAngle(std::atan2(d.y(), d.x()) - current.theta);
  const double max_turn = params_.turn_rate_rps;
  if (turning_ && std::abs(bearing) < kStartDriving) turning_ = false;
  if (!turning_ && std::abs(bearing) > kStopDriving) turning_ = true;
  double v = 0, omega = 0;
  if (turning_) {
    omega = std::clamp(bearing / dt, -max_turn, max_turn);
  } else {
    v = std::min(params_.speed_mps, d.norm() / dt);
    omega = std::clamp(2.0 * bearing, -max_turn, max_turn);
  }
  *step = unicycleStep(v, omega, dt);
  return true;
}

double WaypointDriver::progress() const {
  return static_cast<double>(next_) / static_cast<double>(route_.size());
}

// ---- RandomExplorer ----

RandomExplorer::RandomExplorer(const MotionParams& params, FreeSpaceQuery is_free, uint64_t seed)
    : params_(params), is_free_(std::move(is_free)), rng_(seed) {
  until_wander_m_ = std::exponential_distribution<double>(1.0 / 3.0)(rng_);
}

void RandomExplorer::startTurn(double min_rad, double max_rad) {
  const double magnitude = std::uniform_real_distribution<double>(min_rad, max_rad)(rng_);
  turn_remaining_ = std::bernoulli_distribution(0.5)(rng_) ? magnitude : -magnitude;
}

bool RandomExplorer::advance(const Pose2& current, double dt, Pose2* step) {
  const double max_turn = params_.turn_rate_rps;
  if (std::abs(turn_remaining_) > 1e-9) {
    const double omega = std::clamp(turn_remaining_ / dt, -max_turn, max_turn);
    turn_remaining_ -= omega * dt;
    *step = unicycleStep(0.0, omega, dt);
    return true;
  }
  const Pose2 ahead = current.compose({params_.lookahead_m, 0, 0});
  if (!is_free_(ahead.x, ahead.y, params_.robot_radius_m)) {
    startTurn(M_PI / 3, M_PI);
    *step = {0, 0, 0};
    return true;
  }
  if (until_wander_m_ <= 0) {
    startTurn(M_PI / 12, M_PI / 2);
    until_wander_m_ = std::exponential_distribution<double>(1.0 / 3.0)(rng_);
    *step = {0, 0, 0};
    return true;
  }
  *step = unicycleStep(params_.speed_mps, 0.0, dt);
  until_wander_m_ -= step->x;
  return true;
}

// ---- ActionDriver ----

ActionDriver::ActionDriver(const MotionParams& params, uint64_t seed)
    : params_(params), rng_(seed) {
  const auto one_lap = parseActions(params_.actions);
  for (int lap = 0; lap < params_.laps; ++lap)
    plan_.insert(plan_.end(), one_lap.begin(), one_lap.end());
}

void ActionDriver::beginAction() {
  const double nominal = plan_[index_] == 'F' ? params_.action_length_m : params_.action_turn_rad;
  const double factor = 1.0 + std::normal_distribution<double>(0.0, params_.action_error)(rng_);
  remaining_ = nominal * std::max(0.0, factor);
  in_action_ = true;
}

bool ActionDriver::advance(const Pose2&, double dt, Pose2* step) {
  if (pause_left_ > 0) {
    pause_left_ -= dt;
    *step = {0, 0, 0};
    return true;
  }
  if (!in_action_) {
    if (index_ >= plan_.size()) return false;
    beginAction();
  }
  const char kind = plan_[index_];
  if (kind == 'F') {
    const double d = std::min(remaining_, params_.speed_mps * dt);
    remaining_ -= d;
    *step = {d, 0, 0};
  } else {
    const double a = std::min(remaining_, params_.turn_rate_rps * dt);
    remaining_ -= a;
    *step = {0, 0, kind == 'L' ? a : -a};
  }
  if (remaining_ <= 1e-12) {
    in_action_ = false;
    ++index_;
    pause_left_ = params_.action_pause_s;
  }
  return true;
}

double ActionDriver::progress() const {
  return plan_.empty() ? 1.0 : static_cast<double>(index_) / static_cast<double>(plan_.size());
}

// ---- Trajectory ----

Trajectory Trajectory::loadTum(const std::filesystem::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot open trajectory file");
  Trajectory tr;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream ls(line);
    double t, x, y, z, qx, qy, qz, qw;
    if (!(ls >> t >> x >> y >> z >> qx >> qy >> qz >> qw)) {
      throw std::runtime_error(file.string() + ":" + std::to_string(line_no) +
                               ": expected 't x y z qx qy qz qw'");
    }
    if (!tr.stamps_.empty() && t <= tr.stamps_.back()) {
      throw std::runtime_error(file.string() + ":" + std::to_string(line_no) +
                               ": timestamps must increase");
    }
    const Eigen::Quaterniond q(qw, qx, qy, qz);
    if (std::abs(q.norm() - 1.0) > 1e-3) {
      throw std::runtime_error(file.string() + ":" + std::to_string(line_no) +
                               ": quaternion is not of unit length");
    }
    const Eigen::Vector3d forward = q.normalized() * Eigen::Vector3d::UnitX();
    tr.stamps_.push_back(t);
    tr.poses_.push_back({x, y, std::atan2(forward.y(), forward.x())});
  }
  if (tr.stamps_.size() < 2) {
    throw std::runtime_error(file.string() + ": a trajectory needs at least two poses");
  }
  return tr;
}

Pose2 Trajectory::at(double t) const {
  if (t <= stamps_.front()) return poses_.front();
  if (t >= stamps_.back()) return poses_.back();
  const size_t i =
      static_cast<size_t>(std::upper_bound(stamps_.begin(), stamps_.end(), t) - stamps_.begin());
  const double a = (t - stamps_[i - 1]) / (stamps_[i] - stamps_[i - 1]);
  return interpolate(poses_[i - 1], poses_[i], a);
}

TrajectoryDriver::TrajectoryDriver(Trajectory trajectory)
    : trajectory_(std::move(trajectory)), t_(trajectory_.start()) {}

bool TrajectoryDriver::advance(const Pose2& current, double dt, Pose2* step) {
  if (t_ >= trajectory_.end()) return false;
  t_ += dt;
  // From where the robot is (a kidnap may have moved it) to the next
  // recorded pose's motion: the recorded increment.
  (void)current;
  *step = trajectory_.at(t_ - dt).between(trajectory_.at(t_));
  return true;
}

double TrajectoryDriver::progress() const {
  return (t_ - trajectory_.start()) / (trajectory_.end() - trajectory_.start());
}

std::unique_ptr<MotionDriver> makeDriver(const MotionParams& params, FreeSpaceQuery is_free,
                                         uint64_t seed) {
  switch (params.mode) {
    case MotionMode::kWaypoints:
      return std::make_unique<WaypointDriver>(params);
    case MotionMode::kRandom:
      return std::make_unique<RandomExplorer>(params, std::move(is_free), seed);
    case MotionMode::kActions:
      return std::make_unique<ActionDriver>(params, seed);
    case MotionMode::kTrajectory:
      return std::make_unique<TrajectoryDriver>(Trajectory::loadTum(params.trajectory_file));
  }
  return nullptr;
}

}  // namespace vslam::sim
