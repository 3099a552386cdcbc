#include "odometry_bridge/wheel_odometry.hpp"

#include <cmath>

namespace vslam::odometry_bridge {

int64_t tickDifference(int64_t previous, int64_t current, int counter_bits) {
  // Unsigned arithmetic wraps by definition; the mask keeps counter_bits.
  const uint64_t modulus_mask = (uint64_t{1} << counter_bits) - 1;
  const uint64_t diff =
      (static_cast<uint64_t>(current) - static_cast<uint64_t>(previous)) & modulus_mask;
  const uint64_t half = uint64_t{1} << (counter_bits - 1);
  return diff >= half ? static_cast<int64_t>(diff) - static_cast<int64_t>(half) * 2
                      : static_cast<int64_t>(diff);
}

bool tickInRange(int64_t ticks, int counter_bits) {
  const int64_t half = int64_t{1} << (counter_bits - 1);
  return ticks >= -half && ticks < 2 * half;
}

Pose2 diffDriveStep(double left_m, double right_m, double track_width_m) {
  const double distance = 0.5 * (left_m + right_m);
  const double dtheta = (right_m - left_m) / track_width_m;
  const double mid = 0.5 * dtheta;
  return {distance * std::cos(mid), distance * std::sin(mid), dtheta};
}

double ticksToMetres(int64_t ticks, const DiffDriveParams& drive) {
  return static_cast<double>(ticks) * 2.0 * M_PI * drive.wheel_radius_m / drive.ticks_per_rev;
}

}  // namespace vslam::odometry_bridge
