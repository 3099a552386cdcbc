#pragma once
// How the simulated robot moves: drivers that turn the current true pose into
// the next motion step of a nonholonomic differential-drive robot (forward
// speed v, turn rate omega; no sideways motion).

#include <functional>
#include <memory>
#include <random>
#include <vector>

#include "odometry/pose2.hpp"
#include "sim/scenario.hpp"

namespace vslam::sim {

// The exact motion over dt of a unicycle driving at (v, omega): an arc.
Pose2 unicycleStep(double v, double omega, double dt);

// Is a disc of `radius` at (x, y) free of walls and furniture?
using FreeSpaceQuery = std::function<bool(double x, double y, double radius)>;

class MotionDriver {
 public:
  virtual ~MotionDriver() = default;
  // The robot's motion over the next dt, in its frame at `current`; false
  // when the motion plan is finished.
  virtual bool advance(const Pose2& current, double dt, Pose2* step) = 0;
  // Fraction of the plan done, for progress output (0..1; random: 0).
  virtual double progress() const { return 0.0; }
};

// Visits the waypoints in order, `laps` times, and returns to the first:
// turns in place towards the next waypoint, then drives to it with a
// proportional heading correction.
class WaypointDriver final : public MotionDriver {
 public:
  explicit WaypointDriver(const MotionParams& params);
  bool advance(const Pose2& current, double dt, Pose2* step) override;
  double progress() const override;
  // Index of the waypoint it drives to in the driven route (the waypoints
  // lap after lap, then the first again); the route's size once done. Tells
  // a scenario generator when the robot has finished a leg.
  size_t target() const { return next_; }

 private:
  MotionParams params_;
  std::vector<Eigen::Vector2d> route_;
  size_t next_ = 0;
  bool turning_ = true;
};

// Wanders: drives straight, turns away (by a random angle) when the space
// ahead is not free, and now and then turns a little on its own.
class RandomExplorer final : public MotionDriver {
 public:
  RandomExplorer(const MotionParams& params, FreeSpaceQuery is_free, uint64_t seed);
  bool advance(const Pose2& current, double dt, Pose2* step) override;

 private:
  void startTurn(double min_rad, double max_rad);
  MotionParams params_;
  FreeSpaceQuery is_free_;
  std::mt19937_64 rng_;
  double turn_remaining_ = 0;  // rad, signed
  double until_wander_m_ = 0;
};

// Discrete actions (paper 003: forward 1 m, 90 degree turns), each executed
// with a multiplicative error N(0, action_error) on its size, then a pause.
class ActionDriver final : public MotionDriver {
 public:
  ActionDriver(const MotionParams& params, uint64_t seed);
  bool advance(const Pose2& current, double dt, Pose2* step) override;
  double progress() const override;
  // Number of actions completed so far.
  size_t actionsDone() const { return index_; }

 private:
  void beginAction();
  MotionParams params_;
  std::vector<char> plan_;
  std::mt19937_64 rng_;
  size_t index_ = 0;
  double remaining_ = 0;  // metres or radians of the current action
  double pause_left_ = 0;
  bool in_action_ = false;
};

// A planar trajectory (t, pose) with linear interpolation, from a TUM file.
class Trajectory {
 public:
  // TUM: "t x y z qx qy qz qw" per line, '#' comments; planar pose = (x, y, yaw).
  static Trajectory loadTum(const std::filesystem::path& file);
  bool empty() const { return stamps_.empty(); }
  double start() const { return stamps_.front(); }
  double end() const { return stamps_.back(); }
  Pose2 at(double t) const;  // clamped to the ends

 private:
  std::vector<double> stamps_;
  std::vector<Pose2> poses_;
};

// Follows a recorded trajectory exactly (as ground truth).
class TrajectoryDriver final : public MotionDriver {
 public:
  explicit TrajectoryDriver(Trajectory trajectory);
  bool advance(const Pose2& current, double dt, Pose2* step) override;
  double progress() const override;
  Pose2 startPose() const { return trajectory_.at(trajectory_.start()); }

 private:
  Trajectory trajectory_;
  double t_ = 0;
};

std::unique_ptr<MotionDriver> makeDriver(const MotionParams& params, FreeSpaceQuery is_free,
                                         uint64_t seed);

}  // namespace vslam::sim
