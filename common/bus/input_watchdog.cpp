#include "bus/input_watchdog.hpp"

#include <cstdio>

#include "util/log.hpp"

namespace vslam::bus {
namespace {

std::string seconds(Utime us) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.1f", toSeconds(us));
  return text;
}

}  // namespace

InputWatchdog::InputWatchdog(std::string input, std::string age_key, double timeout_s,
                             std::string consequence)
    : input_(std::move(input)),
      age_key_(std::move(age_key)),
      consequence_(std::move(consequence)),
      timeout_(fromSeconds(timeout_s)) {}

void InputWatchdog::begin(Utime now) {
  std::lock_guard<std::mutex> lock(mutex_);
  started_ = now;
}

void InputWatchdog::arrived(Utime now, Utime stamp) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (started_ == 0) started_ = now;
  if (quiet_logged_) {
    const Utime since = last_arrival_ > 0 ? last_arrival_ : started_;
    log::info(input_, last_arrival_ > 0 ? " back after " : " first after ", seconds(now - since),
              " s without");
    quiet_logged_ = false;
  }
  if (last_arrival_ > 0 && last_stamp_ > 0) {
    const Utime stamp_step = stamp - last_stamp_;
    const Utime clock_step = now - last_arrival_;
    std::string jump;
    if (stamp_step < 0) {
      jump = "time went back " + seconds(-stamp_step) + " s";
    } else if (stamp_step > clock_step + timeout_) {
      jump = "time jumped " + seconds(stamp_step) + " s ahead in " + seconds(clock_step) + " s";
    }
    if (!jump.empty()) {
      ++jumps_;
      last_jump_ = jump + " on " + input_;
      if (!jump_logged_) log::warn(last_jump_, " (a restarted source, or two on one channel?)");
      jump_logged_ = true;
    }
  }
  last_arrival_ = now;
  last_stamp_ = stamp;
}

void InputWatchdog::report(Utime now, HealthReport& report) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (started_ == 0) started_ = now;
  const Utime since = last_arrival_ > 0 ? last_arrival_ : started_;
  const Utime quiet = now - since;
  report.add(age_key_, toSeconds(quiet), "s");
  if (quiet > timeout_) {
    const std::string why = "no " + input_ + (last_arrival_ > 0 ? " for " : " yet, for ") +
                            seconds(quiet) + " s" + consequence_;
    report.warn(why);
    if (!quiet_logged_) log::warn(why);
    quiet_logged_ = true;
  }
  if (jumps_ > jumps_reported_) {
    report.warn(last_jump_);
  } else {
    jump_logged_ = false;  // a quiet period ends the episode
  }
  jumps_reported_ = jumps_;
}

int64_t InputWatchdog::timeJumps() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return jumps_;
}

}  // namespace vslam::bus
