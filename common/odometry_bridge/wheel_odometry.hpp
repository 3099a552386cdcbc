#pragma once
// Differential-drive odometry from cumulative wheel-encoder counts.
//
// Each wheel's travel between two readings is its tick difference times
// 2 pi r / ticks_per_rev; the counters are finite (a 16-bit counter wraps
// every 65,536 ticks), so the difference is taken modulo 2^counter_bits and
// read as the signed value nearest zero: a wheel may turn less than half the
// counter's range between two readings.
//
// Midpoint integration: the step's translation is applied along the heading
// halfway through the step, which is exact for a straight line and a turn in
// place and errs by O(dtheta^2) of the chord on an arc.

#include <cstdint>
#include <string>

#include "odometry/pose2.hpp"

namespace vslam::odometry_bridge {

struct DiffDriveParams {
  double ticks_per_rev = 0;   // encoder ticks per wheel revolution (no default: the robot's)
  double wheel_radius_m = 0;  // m (no default)
  double track_width_m = 0;   // m, distance between the wheels' contact points (no default)
  int counter_bits = 32;      // width of the encoders' counters; differences wrap at 2^bits
};

inline constexpr int kMinCounterBits = 8;
inline constexpr int kMaxCounterBits = 63;

// Signed difference current - previous of a counter that wraps at
// 2^counter_bits, in [-2^(bits-1), 2^(bits-1)).
int64_t tickDifference(int64_t previous, int64_t current, int counter_bits);

// Whether a reported count can come from a counter of that width: its
// unsigned range [0, 2^bits) or its signed one [-2^(bits-1), 2^(bits-1)).
bool tickInRange(int64_t ticks, int counter_bits);

// The motion of a differential drive whose left and right wheels travel
// left_m and right_m, in the robot frame at the step's start.
Pose2 diffDriveStep(double left_m, double right_m, double track_width_m);

// Wheel travel in metres of a tick difference.
double ticksToMetres(int64_t ticks, const DiffDriveParams& drive);

}  // namespace vslam::odometry_bridge
