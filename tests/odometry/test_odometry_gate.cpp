// The odometry gate (odometryAgrees): whether a landmark's measurement agrees
// with the odometry since the landmark was made, the bound growing with the
// path driven and the angle turned.
#include <gtest/gtest.h>

#include <cmath>

#include "odometry/odometry_gate.hpp"

using namespace vslam;

namespace {
constexpr double kDeg = M_PI / 180.0;
}  // namespace

// The odometry gate's bound: the measurement's own error near the creation
// pose, growing with the odometry's drift over the path between.
TEST(OdometryGate, BoundsGrowWithThePathAndTheTurn) {
  OdometryGate gate;
  gate.sigmas = 3;
  const Pose2 measured{0.2, 0, 0};
  // No path: the measurement's error alone, 0.10 m + 10 % of 0.2 m, 5 degrees.
  EXPECT_TRUE(odometryAgrees(measured, Pose2{0.2, 0.11, 0}, 0, 0, gate));
  EXPECT_FALSE(odometryAgrees(measured, Pose2{0.2, 0.13, 0}, 0, 0, gate));
  EXPECT_FALSE(odometryAgrees(measured, Pose2{0.2, 0, 6 * kDeg}, 0, 0, gate));
  // 1 m driven: heading 3 * 0.04 rad more, position 3 * (0.05 + 0.04 / 2) m more.
  EXPECT_TRUE(odometryAgrees(measured, Pose2{0.2, 0.32, 0}, 1, 0, gate));
  EXPECT_FALSE(odometryAgrees(measured, Pose2{0.2, 0.34, 0}, 1, 0, gate));
  EXPECT_TRUE(odometryAgrees(measured, Pose2{0.2, 0, 11 * kDeg}, 1, 0, gate));
  // Turning in place adds heading drift.
  EXPECT_FALSE(odometryAgrees(measured, Pose2{0.2, 0, 15 * kDeg}, 0, 1, gate));
  EXPECT_TRUE(odometryAgrees(measured, Pose2{0.2, 0, 15 * kDeg}, 0, 3, gate));
  // A wall pattern one period (0.9 m) along, 2 m of path on: a look-alike.
  EXPECT_FALSE(odometryAgrees(measured, Pose2{1.1, 0, 0}, 2, 0.5, gate));
  gate.sigmas = 0;
  EXPECT_TRUE(odometryAgrees(measured, Pose2{5, 5, 3}, 0, 0, gate)) << "off";
}
