#pragma once
// Recognises a message delivered again: UDP (and the loss injector) may
// deliver one datagram twice, and handling a camera frame or a measurement
// twice would count its evidence twice. A message is known by its source
// (channel or camera), sequence number and time: a restarted sender starts
// its numbers again, but not at the same times. Remembers the last
// `capacity` messages, so memory does not grow with the run.

#include <cstddef>
#include <cstdint>
#include <deque>
#include <mutex>
#include <set>
#include <string>
#include <tuple>

#include "util/time.hpp"

namespace vslam::bus {

class RepeatFilter {
 public:
  explicit RepeatFilter(size_t capacity = 512) : capacity_(capacity) {}

  // True if this message was seen among the last `capacity` (and counts it);
  // otherwise remembers it.
  bool repeated(const std::string& source, int64_t seq, Utime utime) {
    std::lock_guard<std::mutex> lock(mutex_);
    Key key{source, seq, utime};
    if (seen_.count(key)) {
      ++repeats_;
      return true;
    }
    order_.push_back(key);
    seen_.insert(std::move(key));
    if (order_.size() > capacity_) {
      seen_.erase(order_.front());
      order_.pop_front();
    }
    return false;
  }
  int64_t repeats() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return repeats_;
  }

 private:
  using Key = std::tuple<std::string, int64_t, Utime>;
  const size_t capacity_;
  mutable std::mutex mutex_;
  std::set<Key> seen_;
  std::deque<Key> order_;
  int64_t repeats_ = 0;
};

}  // namespace vslam::bus
