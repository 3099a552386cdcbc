#pragma once
// The simulated robot in its world: drives the scenario's motion, simulates
// odometry and renders every camera, and writes the messages a real robot's
// drivers would publish, in time order, to an EventSink (an LCM log file, or
// the live bus paced to real time). Deterministic for a given scenario, seed
// and start time.

#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <string>
#include <vector>

#include "bus/log_writer.hpp"
#include "config/robot_config.hpp"
#include "odometry/pose2.hpp"
#include "sim/motion.hpp"
#include "sim/odometry_sim.hpp"
#include "sim/scenario.hpp"
#include "util/time.hpp"
#include "world/renderer.hpp"
#include "world/world.hpp"

namespace vslam::sim {

class EventSink {
 public:
  virtual ~EventSink() = default;
  virtual void write(Utime t, const std::string& channel, const void* data, size_t size) = 0;
};

// Writes an LCM log (as lcm-logger would have recorded the run).
class LogFileSink final : public EventSink {
 public:
  explicit LogFileSink(const std::string& path);
  void write(Utime t, const std::string& channel, const void* data, size_t size) override;

 private:
  bus::LogWriter log_;
};

struct SimulatorStats {
  double sim_seconds = 0;
  int64_t odometry_messages = 0;
  int64_t frames = 0;          // over all cameras
  double render_ms_total = 0;  // wall time spent rendering
  double distance_m = 0;       // true distance driven
  int kidnaps = 0;
};

class Simulator {
 public:
  // The world is loaded from the scenario; cameras come from the robot.
  Simulator(const Scenario& scenario, const config::RobotConfig& robot, Utime start_utime);
  ~Simulator();

  // Advances one odometry period, writing its messages; false when the
  // scenario is over.
  bool step(EventSink& sink);
  const SimulatorStats& stats() const { return stats_; }
  double simTime() const { return toSeconds(t_us_); }
  double progress() const;
  const Pose2& truePose() const { return true_pose_; }
  const world::World& world() const { return *world_; }

 private:
  struct Camera;
  struct Person;
  void emitCalibration(EventSink& sink, Utime t);
  void renderDueCameras(EventSink& sink, const Pose2& previous_pose);
  void movePeople(double dt);
  double exposureAt(double t) const;

  Scenario scenario_;
  config::RobotConfig robot_;
  Utime start_utime_;
  std::unique_ptr<world::World> world_;
  std::unique_ptr<MotionDriver> driver_;
  std::unique_ptr<Trajectory> odometry_trajectory_;
  OdometrySimulator odometry_;
  std::vector<std::unique_ptr<Camera>> cameras_;
  std::vector<Person> people_;
  int person_texture_ = -1;
  std::mt19937_64 rng_;
  Pose2 true_pose_;
  Utime t_us_ = 0;
  Utime dt_us_ = 20000;
  Utime next_calibration_us_ = 0;
  int64_t seq_ = 0;
  size_t next_kidnap_ = 0;
  bool finished_ = false;
  SimulatorStats stats_;
};

}  // namespace vslam::sim
