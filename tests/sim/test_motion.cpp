// Motion drivers, the odometry noise model and scenario files, against known
// values and statistics.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include "sim/motion.hpp"
#include "sim/odometry_sim.hpp"
#include "sim/scenario.hpp"

namespace fs = std::filesystem;
using namespace vslam;
using namespace vslam::sim;

TEST(Unicycle, ArcMatchesCircleGeometry) {
  // Quarter circle of radius 1 m: v = 1, omega = 1 rad/s for pi/2 s.
  const Pose2 s = unicycleStep(1.0, 1.0, M_PI / 2);
  EXPECT_NEAR(s.x, 1.0, 1e-12);
  EXPECT_NEAR(s.y, 1.0, 1e-12);
  EXPECT_NEAR(s.theta, M_PI / 2, 1e-12);
  // Many small steps compose to the same arc.
  Pose2 p;
  for (int i = 0; i < 1000; ++i) p = p.compose(unicycleStep(1.0, 1.0, M_PI / 2000));
  EXPECT_NEAR(p.x, 1.0, 1e-9);
  EXPECT_NEAR(p.y, 1.0, 1e-9);
}

TEST(OdometrySimulator, NoiseStatisticsMatchSigmaTAndSigmaR) {
  // 1 m straight in 50 steps, many times: the end-point errors must have the
  // variances the model states: var(x) = sigma_T^2 * 1 m, var(theta) = sigma_R^2 * 1 m.
  OdometryParams params;
  params.sigma_translation = 0.05;
  params.sigma_rotation = 0.03;
  const int runs = 4000;
  double sx = 0, sxx = 0, st = 0, stt = 0;
  for (int r = 0; r < runs; ++r) {
    OdometrySimulator odo(params, 1000 + static_cast<uint64_t>(r));
    for (int i = 0; i < 50; ++i) odo.addStep({0.02, 0, 0}, 0.02 * i);
    const double ex = odo.pose().x - 1.0, et = odo.pose().theta;
    sx += ex;
    sxx += ex * ex;
    st += et;
    stt += et * et;
  }
  const double var_x = sxx / runs - (sx / runs) * (sx / runs);
  const double var_t = stt / runs - (st / runs) * (st / runs);
  // Sampling error of a variance from 4000 samples is ~2.2%; allow 8%.
  EXPECT_NEAR(var_x, 0.05 * 0.05 * 1.0, 0.08 * 0.05 * 0.05);
  EXPECT_NEAR(var_t, 0.03 * 0.03 * 1.0, 0.08 * 0.03 * 0.03);
  EXPECT_NEAR(sx / runs, 0.0, 4 * 0.05 / std::sqrt(runs));  // unbiased
}

TEST(OdometrySimulator, DiagonalAndCurvedStepsStayFinite) {
  // Steps in every direction (a rank-deficient step covariance) must never
  // produce a non-finite pose.
  OdometryParams params;
  params.sigma_translation = 0.03;
  params.sigma_rotation = 0.03;
  OdometrySimulator odo(params, 11);
  for (int i = 0; i < 20000; ++i) {
    const double a = 0.001 * i;
    odo.addStep({0.006 * std::cos(a), 0.006 * std::sin(a), 0.002 * std::sin(0.37 * i)}, 0.02 * i);
    ASSERT_TRUE(odo.pose().isFinite()) << "step " << i;
  }
}

TEST(MotionNoise, PerturbationHasTheStepCovariance) {
  // Sampled perturbations of a diagonal step against stepCovariance().
  const MotionNoise noise{0.05, 0.02};
  const Pose2 step{0.3, 0.4, 0.1};
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01;
  Eigen::Matrix3d sum = Eigen::Matrix3d::Zero();
  const int n = 50000;
  for (int i = 0; i < n; ++i) {
    const double nt = n01(rng), nr = n01(rng);
    const Pose2 p = noise.perturb(step, nt, nr);
    const Eigen::Vector3d e(p.x - step.x, p.y - step.y, p.theta - step.theta);
    sum += e * e.transpose();
  }
  const Eigen::Matrix3d sampled = sum / n;
  const Eigen::Matrix3d expected = noise.stepCovariance(step);
  EXPECT_TRUE(sampled.isApprox(expected, 0.03)) << sampled << "\nvs\n" << expected;
}

TEST(OdometrySimulator, TurningOnTheSpotAddsRotationNoiseOnly) {
  OdometryParams params;
  params.sigma_translation = 0.05;
  params.sigma_rotation = 0.03;
  const int runs = 4000;
  double stt = 0, sxx = 0;
  for (int r = 0; r < runs; ++r) {
    OdometrySimulator odo(params, 7 + static_cast<uint64_t>(r));
    for (int i = 0; i < 50; ++i) odo.addStep({0, 0, M_PI / 100}, 0.02 * i);  // 90 degrees
    stt += std::pow(odo.pose().theta - M_PI / 2, 2);
    sxx += odo.pose().x * odo.pose().x;
  }
  EXPECT_NEAR(stt / runs, 0.03 * 0.03 * (M_PI / 2), 0.08 * 0.03 * 0.03 * (M_PI / 2));
  EXPECT_LT(sxx / runs, 1e-20);
}

TEST(OdometrySimulator, SlipEventsScaleWhatTheWheelsReport) {
  OdometryParams params;
  params.sigma_translation = 0;
  params.sigma_rotation = 0;
  params.slips.push_back({1.0, 0.5, 0.0, 1.0});  // wheels report no translation for 0.5 s
  OdometrySimulator odo(params, 1);
  for (int i = 0; i < 100; ++i) odo.addStep({0.01, 0, 0}, 0.02 * i);  // 2 s at 0.5 m/s
  // Steps at t in [1.0, 1.5) (25 of them) were lost to the slip.
  EXPECT_NEAR(odo.pose().x, 0.75, 1e-12);
  EXPECT_NEAR(odo.distance(), 0.75, 1e-12);
}

TEST(OdometrySimulator, ScaleAndHeadingBiasesOfUnequalWheels) {
  OdometryParams params;
  params.sigma_translation = 0;
  params.sigma_rotation = 0;
  params.scale_bias = 0.02;
  OdometrySimulator scaled(params, 1);
  for (int i = 0; i < 1000; ++i) scaled.addStep({0.01, 0, 0}, 0.02 * i);  // 10 m straight
  EXPECT_NEAR(scaled.pose().x, 10.2, 1e-9);
  EXPECT_NEAR(scaled.distance(), 10.2, 1e-9);
  EXPECT_NEAR(scaled.pose().theta, 0.0, 1e-12);

  params.scale_bias = 0;
  params.heading_bias = 0.01;  // rad per metre
  OdometrySimulator curving(params, 1);
  for (int i = 0; i < 1000; ++i) curving.addStep({0.01, 0, 0}, 0.02 * i);
  EXPECT_NEAR(curving.pose().theta, 0.1, 1e-9);
  EXPECT_NEAR(curving.distance(), 10.0, 1e-9);
  EXPECT_GT(curving.pose().y, 0.4);  // the reported path bends left: ~0.5 m off after 10 m
  // Turning on the spot rolls no distance, so no heading bias.
  OdometrySimulator turning(params, 1);
  for (int i = 0; i < 50; ++i) turning.addStep({0, 0, M_PI / 100}, 0.02 * i);
  EXPECT_NEAR(turning.pose().theta, M_PI / 2, 1e-12);
}

TEST(Scenario, OdometryBiasesAreReadAndValidated) {
  const fs::path dir = fs::temp_directory_path() / "vslam_test_scenario_bias";
  fs::create_directories(dir);
  std::ofstream(dir / "world.yaml") << "x: 1\n";
  const std::string base =
      "name: t\nworld: world.yaml\nmotion:\n  mode: actions\n  start: [0, 0, 0]\n"
      "  actions: F2 L\nodometry:\n  sigma_translation: 0.01\n  sigma_rotation: 0.01\n";
  std::ofstream(dir / "s.yaml") << base;
  const Scenario plain = Scenario::loadByName((dir / "s.yaml").string(), dir);
  EXPECT_EQ(plain.odometry.scale_bias, 0.0);
  EXPECT_EQ(plain.odometry.heading_bias, 0.0);
  std::ofstream(dir / "s.yaml") << base + "  scale_bias: -0.015\n  heading_bias: 0.004\n";
  const Scenario biased = Scenario::loadByName((dir / "s.yaml").string(), dir);
  EXPECT_DOUBLE_EQ(biased.odometry.scale_bias, -0.015);
  EXPECT_DOUBLE_EQ(biased.odometry.heading_bias, 0.004);
  std::ofstream(dir / "s.yaml") << base + "  scale_bias: 0.9\n";
  try {
    Scenario::loadByName((dir / "s.yaml").string(), dir);
    ADD_FAILURE() << "scale_bias 0.9 accepted";
  } catch (const config::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("odometry.scale_bias"), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

TEST(WaypointDriver, DrivesTheLapsAndClosesTheLoop) {
  MotionParams p;
  p.mode = MotionMode::kWaypoints;
  p.start = {0, 0, 0};
  p.waypoints = {{0, 0}, {2, 0}, {2, 1}, {0, 1}};
  p.laps = 3;
  p.speed_mps = 0.3;
  WaypointDriver driver(p);
  Pose2 pose = p.start, step;
  double distance = 0, max_off_route = 0;
  int steps = 0;
  size_t target = driver.target();
  while (driver.advance(pose, 0.02, &step) && steps < 100000) {
    // The target moves on one waypoint at a time, once the robot is there.
    if (driver.target() != target) {
      EXPECT_EQ(driver.target(), target + 1);
      const Eigen::Vector2d reached = p.waypoints[target % p.waypoints.size()];
      EXPECT_LT((reached - Eigen::Vector2d(pose.x, pose.y)).norm(), 0.01);
      target = driver.target();
    }
    pose = pose.compose(step);
    distance += std::hypot(step.x, step.y);
    // Never far from the rectangle's edges.
    const double dx = std::min(std::abs(pose.x), std::abs(pose.x - 2));
    const double dy = std::min(std::abs(pose.y), std::abs(pose.y - 1));
    max_off_route = std::max(max_off_route, std::min(dx, dy));
    ++steps;
  }
  EXPECT_NEAR(distance, 3 * 6.0, 0.15);         // 3 laps of 6 m, each corner cut by < 1 cm
  EXPECT_LT(std::hypot(pose.x, pose.y), 0.05);  // back at the start
  EXPECT_LT(max_off_route, 0.05);
  EXPECT_DOUBLE_EQ(driver.progress(), 1.0);
  EXPECT_EQ(driver.target(), 3u * 4u + 1u);
}

TEST(ActionDriver, ExecutesActionsWithTheStatedError) {
  MotionParams p;
  p.mode = MotionMode::kActions;
  p.actions = "F L F R";
  p.laps = 1;
  p.action_error = 0.0;
  p.action_pause_s = 0.1;
  ActionDriver exact(p, 1);
  Pose2 pose, step;
  while (exact.advance(pose, 0.02, &step)) pose = pose.compose(step);
  EXPECT_NEAR(pose.x, 1.0, 1e-9);
  EXPECT_NEAR(pose.y, 1.0, 1e-9);
  EXPECT_NEAR(pose.theta, 0.0, 1e-9);
  EXPECT_EQ(exact.actionsDone(), 4u);

  // 3% error: the executed forward lengths have a 3% standard deviation.
  p.actions = "F1000";
  p.action_error = 0.03;
  p.action_pause_s = 0.0;
  ActionDriver noisy(p, 5);
  std::vector<double> lengths;
  double current = 0;
  size_t done = 0;
  Pose2 origin;
  while (noisy.advance(origin, 0.02, &step)) {
    current += step.x;
    if (noisy.actionsDone() > done) {
      lengths.push_back(current);
      current = 0;
      done = noisy.actionsDone();
    }
  }
  ASSERT_EQ(lengths.size(), 1000u);
  double mean = 0, var = 0;
  for (double l : lengths) mean += l / 1000;
  for (double l : lengths) var += (l - mean) * (l - mean) / 999;
  EXPECT_NEAR(mean, 1.0, 0.005);
  EXPECT_NEAR(std::sqrt(var), 0.03, 0.003);
}

TEST(ParseActions, CountsAndErrors) {
  EXPECT_EQ(parseActions("F3 L r"), (std::vector<char>{'F', 'F', 'F', 'L', 'R'}));
  EXPECT_THROW(parseActions("F2 X"), std::invalid_argument);
  EXPECT_THROW(parseActions("F0"), std::invalid_argument);
  EXPECT_THROW(parseActions("Fx"), std::invalid_argument);
}

TEST(RandomExplorer, StaysInFreeSpace) {
  MotionParams p;
  p.mode = MotionMode::kRandom;
  p.start = {0, 0, 0.3};
  p.speed_mps = 0.15;
  p.robot_radius_m = 0.2;
  p.lookahead_m = 0.4;
  // A 4 x 3 m room centred on the origin.
  const auto is_free = [](double x, double y, double r) {
    return std::abs(x) + r <= 2.0 && std::abs(y) + r <= 1.5;
  };
  RandomExplorer driver(p, is_free, 3);
  Pose2 pose = p.start, step;
  double distance = 0;
  for (int i = 0; i < 50 * 600; ++i) {  // 10 minutes
    ASSERT_TRUE(driver.advance(pose, 0.02, &step));
    pose = pose.compose(step);
    distance += std::hypot(step.x, step.y);
    ASSERT_TRUE(is_free(pose.x, pose.y, 0.15)) << "left free space at step " << i;
  }
  EXPECT_GT(distance, 40.0);  // it keeps moving (0.15 m/s minus turning time)
}

TEST(Trajectory, LoadsTumAndInterpolates) {
  const fs::path file = fs::temp_directory_path() / "vslam_test_traj.tum";
  std::ofstream(file) << "# t x y z qx qy qz qw\n"
                         "10.0 0 0 0 0 0 0 1\n"
                         "12.0 2 0 0 0 0 0.7071067811865476 0.7071067811865476\n";
  const Trajectory tr = Trajectory::loadTum(file);
  const Pose2 mid = tr.at(11.0);
  EXPECT_NEAR(mid.x, 1.0, 1e-12);
  EXPECT_NEAR(mid.theta, M_PI / 4, 1e-9);
  EXPECT_NEAR(tr.at(99).theta, M_PI / 2, 1e-9);
  std::ofstream(file) << "10.0 0 0 0 0 0 0 1\n11.0 1 0 0 0 0\n";
  try {
    Trajectory::loadTum(file);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("vslam_test_traj.tum:2:"), std::string::npos) << e.what();
  }
  fs::remove(file);
}

TEST(Scenario, BadFilesNameFileLineAndKey) {
  const fs::path dir = fs::temp_directory_path() / "vslam_test_scenario";
  fs::create_directories(dir);
  std::ofstream(dir / "world.yaml") << "x: 1\n";
  const std::string base =
      "name: t\nworld: world.yaml\nmotion:\n  mode: actions\n  start: [0, 0, 0]\n"
      "  actions: F2 L\nodometry:\n  sigma_translation: 0.01\n  sigma_rotation: 0.01\n";
  auto expectError = [&](const std::string& text, const std::string& part) {
    std::ofstream(dir / "s.yaml") << text;
    try {
      Scenario::loadByName((dir / "s.yaml").string(), dir);
      ADD_FAILURE() << "no error for: " << part;
    } catch (const config::ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
    }
  };
  std::ofstream(dir / "s.yaml") << base;
  const Scenario ok = Scenario::loadByName((dir / "s.yaml").string(), dir);
  EXPECT_EQ(ok.motion.mode, MotionMode::kActions);
  EXPECT_EQ(ok.world_file, (dir / "world.yaml").lexically_normal());
  expectError(base + "speed: 3\n", "s.yaml:10: speed: unknown key");
  expectError(base + "disturbances:\n  kidnap:\n    - {at_s: 5, to: [1, 2]}\n",
              "s.yaml:12: disturbances.kidnap[0].to: expected a list of 3 numbers");
  std::string bad_action = base;
  bad_action.replace(bad_action.find("F2 L"), 4, "F2 Q");
  expectError(bad_action, "s.yaml:6: motion.actions: action 'Q'");
  std::string bad_world = base;
  bad_world.replace(bad_world.find("world.yaml"), 10, "nowhere.yaml");
  expectError(bad_world, "s.yaml:2: world: file 'nowhere.yaml' not found");
  fs::remove_all(dir);
}
