#pragma once
// Time in the stack is int64 microseconds since the Unix epoch ("utime"), as
// in every message. A Clock is injected into stages so that live processes use
// the wall clock and lock-step replay uses the log's time, which makes replay
// output independent of how fast the machine is.

#include <atomic>
#include <cstdint>

namespace vslam {

using Utime = int64_t;

constexpr Utime kMicrosPerSecond = 1000000;
inline double toSeconds(Utime us) { return static_cast<double>(us) * 1e-6; }
inline Utime fromSeconds(double s) { return static_cast<Utime>(s * 1e6); }

// Wall clock, microseconds since the Unix epoch.
Utime wallUtime();
// Monotonic clock for measuring durations, microseconds.
Utime monotonicUtime();

class Clock {
 public:
  virtual ~Clock() = default;
  virtual Utime now() const = 0;
};

class WallClock final : public Clock {
 public:
  Utime now() const override { return wallUtime(); }
};

// Set by the replay driver to the time of the log event being processed.
class ManualClock final : public Clock {
 public:
  Utime now() const override { return now_.load(); }
  void set(Utime t) { now_.store(t); }

 private:
  std::atomic<Utime> now_{0};
};

}  // namespace vslam
