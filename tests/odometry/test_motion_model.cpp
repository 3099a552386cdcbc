// Poses, odometry, motion noise and small statistics against hand-computed values.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <random>
#include <vector>

#include "odometry/motion_model.hpp"
#include "util/angles.hpp"
#include "util/statistics.hpp"

using vslam::OdometryIncrements;
using vslam::Pose2;
using Outcome = OdometryIncrements::Outcome;

TEST(Pose2, ComposeAndBetweenAreInverse) {
  const Pose2 a{1.0, 2.0, 0.5};
  const Pose2 b{-0.3, 0.7, -2.9};
  const Pose2 ab = a.compose(b);
  const Pose2 back = a.between(ab);
  EXPECT_NEAR(back.x, b.x, 1e-12);
  EXPECT_NEAR(back.y, b.y, 1e-12);
  EXPECT_NEAR(back.theta, b.theta, 1e-12);
  // Quarter turn: a step forward in a frame facing +y moves along +y.
  const Pose2 p = Pose2{0, 0, M_PI / 2}.compose({1, 0, 0});
  EXPECT_NEAR(p.x, 0, 1e-12);
  EXPECT_NEAR(p.y, 1, 1e-12);
  // Wrapping across +-pi.
  const Pose2 wrapped = Pose2{0, 0, 3.0}.compose(Pose2{0, 0, 0.5});
  EXPECT_NEAR(wrapped.theta, 3.5 - 2 * M_PI, 1e-12);
}

TEST(Pose2, AnglesWrapToTheHalfOpenIntervalFromMinusPiToPi) {
  // In range (the fast path) and beyond it (std::remainder) alike.
  EXPECT_EQ(vslam::wrapAngle(M_PI), M_PI);
  EXPECT_EQ(vslam::wrapAngle(-M_PI), M_PI);
  EXPECT_EQ(vslam::wrapAngle(3 * M_PI), M_PI);
  EXPECT_EQ(vslam::wrapAngle(0.25), 0.25);
  EXPECT_EQ(vslam::wrapAngle(-0.25), -0.25);
  EXPECT_NEAR(vslam::wrapAngle(0.25 + 2 * M_PI), 0.25, 1e-12);
  EXPECT_NEAR(vslam::wrapAngle(-0.25 - 6 * M_PI), -0.25, 1e-12);
  for (double a = -20.0; a <= 20.0; a += 0.37) {
    const double w = vslam::wrapAngle(a);
    EXPECT_GT(w, -M_PI);
    EXPECT_LE(w, M_PI);
    EXPECT_NEAR(std::cos(w), std::cos(a), 1e-12);
    EXPECT_NEAR(std::sin(w), std::sin(a), 1e-12);
  }
}

TEST(Pose2, InterpolationOfSamplesAndOfMotion) {
  // Samples of a trajectory: each coordinate linearly, the heading the short
  // way round across +-pi.
  const Pose2 a{0, 0, 3.0}, b{2, -4, -3.0};
  const Pose2 half = vslam::interpolate(a, b, 0.5);
  EXPECT_NEAR(half.x, 1, 1e-12);
  EXPECT_NEAR(half.y, -2, 1e-12);
  EXPECT_NEAR(std::abs(half.theta), M_PI, 1e-12);
  EXPECT_NEAR(vslam::interpolate(a, b, 0.0).theta, 3.0, 1e-12);
  EXPECT_NEAR(vslam::interpolate(a, b, 1.0).theta, -3.0, 1e-12);
  // Motion between odometry readings: the fraction of the step in a's frame,
  // so a robot that turned 90 degrees while driving 1 m along its heading
  // from a heading of 90 degrees is half-way at (0, 0.5), 45 degrees turned.
  const Pose2 from{0, 0, M_PI / 2}, to = from.compose({1, 0, M_PI / 2});
  const Pose2 mid = vslam::interpolateMotion(from, to, 0.5);
  EXPECT_NEAR(mid.x, 0, 1e-12);
  EXPECT_NEAR(mid.y, 0.5, 1e-12);
  EXPECT_NEAR(mid.theta, 3 * M_PI / 4, 1e-12);
  const Pose2 end = vslam::interpolateMotion(from, to, 1.0);
  EXPECT_NEAR(end.x, to.x, 1e-12);
  EXPECT_NEAR(end.y, to.y, 1e-12);
}

TEST(Statistics, MedianUpperMedianAndMean) {
  EXPECT_DOUBLE_EQ(vslam::median({3, 1, 2}), 2);
  EXPECT_DOUBLE_EQ(vslam::median({4, 1, 3, 2}), 2.5);
  std::vector<double> v{4, 1, 3, 2};
  EXPECT_DOUBLE_EQ(vslam::upperMedian(&v), 3);  // one of the samples
  std::vector<double> odd{5, 9, 1};
  EXPECT_DOUBLE_EQ(vslam::upperMedian(&odd), 5);
  EXPECT_DOUBLE_EQ(vslam::mean({1, 2, 6}), 3);
  std::vector<double> none;
  EXPECT_TRUE(std::isnan(vslam::upperMedian(&none)));
  EXPECT_TRUE(std::isnan(vslam::median({})));
  EXPECT_TRUE(std::isnan(vslam::mean({})));
}

TEST(OdometryIncrements, LostMessagesLoseNoMotion) {
  OdometryIncrements inc;
  Pose2 step;
  ASSERT_EQ(inc.add({0, 0, {0, 0, 0}}, &step), Outcome::kFirst);
  // seq 1..4 lost: the next reading still carries all the motion.
  ASSERT_EQ(inc.add({0, 5, {0.5, 0, 0}}, &step), Outcome::kStep);
  EXPECT_NEAR(step.x, 0.5, 1e-12);
}

TEST(OdometryIncrements, DuplicatesOutOfOrderAndNaNAreIgnored) {
  OdometryIncrements inc;
  Pose2 step;
  inc.add({0, 10, {0, 0, 0}}, &step);
  ASSERT_EQ(inc.add({0, 12, {0.2, 0, 0}}, &step), Outcome::kStep);
  EXPECT_EQ(inc.add({0, 12, {0.2, 0, 0}}, &step), Outcome::kStale);
  EXPECT_EQ(inc.add({0, 11, {0.1, 0, 0}}, &step), Outcome::kStale);
  EXPECT_EQ(inc.add({0, 13, {NAN, 0, 0}}, &step), Outcome::kInvalid);
  ASSERT_EQ(inc.add({0, 14, {0.3, 0.0, 0}}, &step), Outcome::kStep);
  // The step is measured from the last accepted reading (seq 12), not the NaN one.
  EXPECT_NEAR(step.x, 0.1, 1e-12);
}

TEST(OdometryIncrements, StepIsInThePreviousRobotFrame) {
  OdometryIncrements inc;
  Pose2 step;
  inc.add({0, 1, {1, 1, M_PI / 2}}, &step);
  ASSERT_EQ(inc.add({0, 2, {1, 1.2, M_PI / 2 + 0.1}}, &step), Outcome::kStep);
  EXPECT_NEAR(step.x, 0.2, 1e-12);  // forward in the robot frame
  EXPECT_NEAR(step.y, 0.0, 1e-12);
  EXPECT_NEAR(step.theta, 0.1, 1e-12);
}

TEST(OdometryIncrements, RestartAndJumpsResetWithoutMotion) {
  OdometryIncrements inc(1.0, M_PI / 2);
  Pose2 step;
  inc.add({0, 100, {5, 5, 0}}, &step);
  EXPECT_EQ(inc.add({0, 0, {0, 0, 0}}, &step), Outcome::kReset);
  ASSERT_EQ(inc.add({0, 1, {0.1, 0, 0}}, &step), Outcome::kStep);
  EXPECT_NEAR(step.x, 0.1, 1e-12);
  EXPECT_EQ(inc.add({0, 2, {3.0, 0, 0}}, &step), Outcome::kImplausible);
}

TEST(MotionNoise, VarianceGrowsWithDistanceIndependentOfRate) {
  vslam::MotionNoise noise{0.1, 0.02};
  // 1 m straight in one step or in 100 steps: same accumulated variance.
  vslam::PoseWithCovariance one, many;
  one.apply({1.0, 0, 0}, noise.stepCovariance({1.0, 0, 0}));
  for (int i = 0; i < 100; ++i) many.apply({0.01, 0, 0}, noise.stepCovariance({0.01, 0, 0}));
  EXPECT_NEAR(one.covariance()(0, 0), 0.01, 1e-12);  // sigma_T^2 * 1 m
  EXPECT_NEAR(many.covariance()(0, 0), 0.01, 1e-12);
  EXPECT_NEAR(one.covariance()(2, 2), 0.0004, 1e-12);  // sigma_R^2 * 1 m
  EXPECT_NEAR(many.covariance()(2, 2), 0.0004, 1e-12);
  // Heading noise accumulated along the way becomes lateral error:
  // var(y) = sum over steps of var(theta_i) * (remaining distance)^2 -> sigma_R^2 / 3 for 1 m.
  EXPECT_NEAR(many.covariance()(1, 1), 0.0004 / 3.0, 0.0004 * 0.02);
  EXPECT_NEAR(one.covariance()(1, 1), 0.0, 1e-15);
  EXPECT_NEAR(many.pose().x, 1.0, 1e-12);
}

TEST(MotionNoise, CovarianceMatchesMonteCarloOfTheSameModel) {
  // First-order propagation against sampling the same step noise.
  vslam::MotionNoise noise{0.05, 0.05};
  const Pose2 step{0.05, 0.0, 0.03};
  const int steps = 40, samples = 20000;
  vslam::PoseWithCovariance analytic;
  for (int i = 0; i < steps; ++i) analytic.apply(step, noise.stepCovariance(step));
  std::mt19937 rng(7);
  const Eigen::Matrix3d q = noise.stepCovariance(step);
  const Eigen::Matrix3d l = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(q).operatorSqrt();
  std::normal_distribution<double> n01;
  Eigen::MatrixXd end(3, samples);
  for (int s = 0; s < samples; ++s) {
    Pose2 p;
    for (int i = 0; i < steps; ++i) {
      const Eigen::Vector3d e = l * Eigen::Vector3d(n01(rng), n01(rng), n01(rng));
      p = p.compose({step.x + e.x(), step.y + e.y(), step.theta + e.z()});
    }
    end.col(s) = p.vector();
  }
  const Eigen::Vector3d mean = end.rowwise().mean();
  const Eigen::MatrixXd centered = end.colwise() - mean;
  const Eigen::Matrix3d sampled = centered * centered.transpose() / (samples - 1);
  for (int r = 0; r < 3; ++r) {
    EXPECT_NEAR(sampled(r, r), analytic.covariance()(r, r), 0.08 * analytic.covariance()(r, r))
        << "diagonal " << r;
  }
}
