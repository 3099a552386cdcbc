#pragma once
// Alternating image acquisition (vSLAM paper, section 8: "some alternating
// image acquisition scheme can be employed"): `slots` cameras take turns, so
// together they cost the front-ends what one camera at the full rate does.
// Time is cut into periods of slots / rate_hz seconds counted from the
// clock's epoch (robot time: the Unix epoch), each period into `slots` equal
// slots; a camera takes the first frame whose capture time falls in its slot,
// one per period. The turn is a pure function of the capture time, so cameras
// in separate processes agree on it through the shared robot clock alone.

#include <cstdint>

#include "util/time.hpp"

namespace vslam {

struct Alternation {
  int slot = 0;   // this camera's turn, 0 .. slots - 1
  int slots = 1;  // cameras taking turns; 1: no alternation
  bool active() const { return slots > 1; }
};

// Where a capture time falls: the period (floor of t / period, so times
// before the epoch work too) and the slot within it, floor(phase * slots /
// period) for the phase (t - period start) in microseconds: slot k starts at
// the first microsecond at or after k * period / slots, so a time on a
// boundary belongs to the later slot.
struct AlternationTurn {
  int64_t period = 0;
  int slot = 0;
};

// The period of `slots` cameras sharing `rate_hz`, microseconds (rounded).
// std::invalid_argument naming the parameter if rate_hz is not a finite
// number > 0, slots is not in 1..1000, or a slot would be shorter than a
// microsecond (or the period longer than 1e9 s).
Utime alternationPeriodUs(double rate_hz, int slots);
// std::invalid_argument if slots is not in 1..1000 or period_us < slots.
AlternationTurn alternationTurn(Utime t, Utime period_us, int slots);
// std::invalid_argument naming `slot` or `slots` (and rate_hz, as above).
void checkAlternation(const Alternation& alternation, double rate_hz);

// One camera kept to its turns.
class AlternationGate {
 public:
  AlternationGate(Alternation alternation, double rate_hz);  // checkAlternation's errors
  // True for the first time of each period that falls in this camera's slot
  // (times must not go backwards; an earlier period is never taken again).
  bool take(Utime t);
  Utime periodUs() const { return period_us_; }

 private:
  Alternation alternation_;
  Utime period_us_;
  bool taken_any_ = false;
  int64_t last_period_ = 0;
};

}  // namespace vslam
