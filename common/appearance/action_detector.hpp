#pragma once
// Cuts the robot's motion into the paper's actions (section VI: "after each
// action u_i an observation is made") from cumulative odometry. An action
// ends, and a snapshot is due, when since the last state the robot has
//   - travelled `distance_m` or turned `turn_rad` (continuous driving), or
//   - come to rest (no odometry motion for `rest_s`) after travelling at
//     least `min_fraction` of either (discrete actions: the robot stops after
//     each move or turn, so a 0.97 m move ends at its stop, not mid-way
//     through the next move).
// The action is the odometry pose of the new state in the frame of the
// previous one: the "executed action" its link stores.

#include <cstdint>
#include <optional>

#include "odometry/pose2.hpp"

namespace vslam::appearance {

struct ActionParams {
  double distance_m = 1.0;           // one forward action
  double turn_rad = M_PI / 2;        // one turn action
  double rest_s = 0.3;               // no motion for this long: the action ended
  double rest_speed_mps = 0.01;      // slower than this is no motion
  double rest_turn_rate_rps = 0.01;  // rad/s
  double min_fraction = 0.5;         // of distance_m or turn_rad, for an action ended by rest
};

struct CompletedAction {
  int64_t utime = 0;  // odometry time the action ended, microseconds
  Pose2 delta;        // the new state's odometry pose in the frame of the last state
  Pose2 odometry;     // cumulative odometry pose at the end
  double travelled_m = 0;
  double turned_rad = 0;
};

class ActionDetector {
 public:
  explicit ActionDetector(ActionParams params) : params_(params) {}

  // Sets the pose of the last state (after a snapshot): actions are measured from here.
  void setReference(int64_t utime, const Pose2& odometry);
  bool hasReference() const { return has_reference_; }

  // Feeds one cumulative odometry reading (in time order). Returns the
  // completed action, if this reading ends one; the caller takes the snapshot
  // and then calls setReference() with the returned end pose (or with a later
  // one). Readings with non-finite poses must be filtered by the caller.
  std::optional<CompletedAction> add(int64_t utime, const Pose2& odometry);

  // Motion since the reference, for a caller that must give up on a snapshot.
  double travelled() const { return travelled_; }
  double turned() const { return turned_; }

 private:
  ActionParams params_;
  bool has_reference_ = false;
  bool completed_ = false;  // an action was returned; waiting for setReference
  int64_t reference_utime_ = 0;
  Pose2 reference_;
  Pose2 last_;
  int64_t last_utime_ = 0;
  int64_t last_motion_utime_ = 0;
  double travelled_ = 0;
  double turned_ = 0;
};

}  // namespace vslam::appearance
