#pragma once
// Start barrier for a data source: waits until every named process instance
// has published a health message, so that a source started together with its
// consumers (vslam-sim under scripts/launch) loses none of its first messages.
// A stage publishes health only after it has subscribed, so one health message
// from an instance means it receives from then on.

#include <lcm/lcm-cpp.hpp>
#include <set>
#include <string>
#include <vector>

#include "util/time.hpp"

namespace vslam::bus {

class HealthBarrier {
 public:
  HealthBarrier(lcm::LCM& lcm, const std::string& health_channel,
                const std::vector<std::string>& instances);
  ~HealthBarrier();
  HealthBarrier(const HealthBarrier&) = delete;
  HealthBarrier& operator=(const HealthBarrier&) = delete;

  // Handles health messages until every instance has been heard from, or
  // `timeout_s` of wall time has passed, or stop_requested() (signal) turns
  // true. Returns true when every instance was heard.
  template <class StopFn>
  bool wait(double timeout_s, StopFn stop_requested) {
    const Utime deadline = monotonicUtime() + fromSeconds(timeout_s);
    while (!pending_.empty() && !stop_requested()) {
      const Utime now = monotonicUtime();
      if (now >= deadline) break;
      lcm_.handleTimeout(static_cast<int>(std::min<Utime>(100000, deadline - now) / 1000 + 1));
    }
    return pending_.empty();
  }

  // Instances not heard from yet.
  const std::set<std::string>& pending() const { return pending_; }
  // Health messages that failed to decode (counted, otherwise ignored).
  int malformed() const { return malformed_; }

 private:
  void onMessage(const lcm::ReceiveBuffer* rbuf, const std::string& channel);

  lcm::LCM& lcm_;
  lcm::Subscription* subscription_ = nullptr;
  std::set<std::string> pending_;
  int malformed_ = 0;
};

}  // namespace vslam::bus
