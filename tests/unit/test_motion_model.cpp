// Odometry increments and the motion noise model against hand-computed values.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <random>

#include "odometry/motion_model.hpp"

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
