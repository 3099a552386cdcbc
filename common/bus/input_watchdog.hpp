#pragma once
// Watches one input a stage needs (odometry, a camera's images): while it
// has been quiet for longer than a timeout (the stage's clock: wall time
// live, log time in replay) the stage's health is WARN and says so, and the
// silence is logged once, with a line when the input is back. Times that go
// back (a restarted driver or simulator, two sources on one channel) or jump
// forward by more than the timeout beyond the time that passed are counted,
// logged once per episode and reported until a health period passes
// without one.

#include <mutex>
#include <string>

#include "bus/stage.hpp"
#include "util/time.hpp"

namespace vslam::bus {

class InputWatchdog {
 public:
  // `input` names it ("odometry on ODOMETRY"), `age_key` is its health value
  // ("odometry_age_s"), `consequence` says what its silence means (", the
  // pose does not move with the robot"; may be empty).
  InputWatchdog(std::string input, std::string age_key, double timeout_s,
                std::string consequence = "");

  // Silence counts from `now` (the stage's start; 0, a replay before its
  // first event: from the first report or arrival).
  void begin(Utime now);
  // A message arrived at stage-clock time `now`, stamped `stamp` (its utime).
  void arrived(Utime now, Utime stamp);
  // The input's age, and WARN while it is quiet or its time jumped lately.
  void report(Utime now, HealthReport& report);

  int64_t timeJumps() const;

 private:
  const std::string input_, age_key_, consequence_;
  const Utime timeout_;
  mutable std::mutex mutex_;
  Utime started_ = 0;       // first report or arrival: silence counts from here
  Utime last_arrival_ = 0;  // stage clock
  Utime last_stamp_ = 0;
  bool quiet_logged_ = false;
  int64_t jumps_ = 0;
  int64_t jumps_reported_ = 0;  // up to the last report
  bool jump_logged_ = false;    // in the current episode
  std::string last_jump_;
};

}  // namespace vslam::bus
