// The visual measurement (paper 4.2) on synthetic scenes with known motion,
// and the pre-filter (paper 5). Tolerances are stated at each assertion;
// every random scene uses a fixed seed.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <set>
#include <stdexcept>
#include <vector>

#include "config/robot_config.hpp"
#include "frontend/measurement_cost.hpp"
#include "frontend/pose_measurement.hpp"
#include "util/angles.hpp"
#include "vslam/visual_measurement_t.hpp"

namespace vslam::frontend {
namespace {

constexpr double kF = 277.13;  // config/calib/sim_320x240.yml
constexpr double kHalfW = 160.0 / kF, kHalfH = 120.0 / kF;

MeasurementCamera forwardCamera() {
  MeasurementCamera c;
  c.fx = c.fy = kF;
  c.robot_T_camera.linear() = config::robotRotationCamera(0, 0, 0);
  c.robot_T_camera.translation() = Eigen::Vector3d(0.10, 0, 0.30);
  return c;
}

MeasurementCamera backwardCamera() {
  MeasurementCamera c = forwardCamera();
  c.robot_T_camera.linear() = config::robotRotationCamera(M_PI, 0, 0);
  c.robot_T_camera.translation() = Eigen::Vector3d(-0.10, 0, 0.30);
  return c;
}

Eigen::Isometry3d planarMotion(double x, double y, double theta) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, 0);
  return T;
}

struct SceneSpec {
  int num_points = 60;                      // correspondences handed to measurePose
  double outlier_fraction = 0.2;            // of num_points
  double noise_px = 0.5;                    // standard deviation per image axis
  double min_depth = 1.0, max_depth = 5.0;  // along the creating camera's axis
  // Points are drawn in this window of the creating camera's normalized
  // image (default: the whole 320x240 image).
  double u_half = kHalfW, v_half = kHalfH, u_center = 0, v_center = 0;
  MeasurementCamera creating = forwardCamera();
  MeasurementCamera current = forwardCamera();
  Eigen::Isometry3d creation_T_current = planarMotion(0.3, -0.2, degToRad(15));
};

struct Scene {
  std::vector<Eigen::Vector3d> points;  // creation robot frame
  std::vector<Eigen::Vector2d> obs;     // current camera, normalized
  std::set<int> outliers;
};

// Landmark points in front of the creating camera that the current camera
// sees inside its image; observations with Gaussian noise; a fraction
// replaced by random image positions at least 10 px from the true one.
Scene makeScene(const SceneSpec& s, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uni(-1, 1), depth(s.min_depth, s.max_depth);
  std::normal_distribution<double> noise(0, s.noise_px / kF);
  const Eigen::Isometry3d camera_T_creation =
      s.current.robot_T_camera.inverse() * s.creation_T_current.inverse();
  Scene scene;
  for (int tries = 0; static_cast<int>(scene.points.size()) < s.num_points; ++tries) {
    if (tries > 100000) throw std::runtime_error("scene: too few visible points");
    const double d = depth(rng);
    const Eigen::Vector3d x_cam(d * (s.u_center + s.u_half * uni(rng)),
                                d * (s.v_center + s.v_half * uni(rng)), d);
    const Eigen::Vector3d x_robot = s.creating.robot_T_camera * x_cam;
    const Eigen::Vector3d p = camera_T_creation * x_robot;
    if (p.z() < 0.2) continue;
    const Eigen::Vector2d uv(p.x() / p.z(), p.y() / p.z());
    if (std::abs(uv.x()) > kHalfW || std::abs(uv.y()) > kHalfH) continue;
    scene.points.push_back(x_robot);
    scene.obs.push_back(uv + Eigen::Vector2d(noise(rng), noise(rng)));
  }
  const int num_outliers = static_cast<int>(std::lround(s.outlier_fraction * s.num_points));
  std::vector<int> idx(s.num_points);
  for (int i = 0; i < s.num_points; ++i) idx[i] = i;
  std::shuffle(idx.begin(), idx.end(), rng);
  for (int k = 0; k < num_outliers; ++k) {
    const int i = idx[k];
    Eigen::Vector2d o;
    do {
      o = Eigen::Vector2d(kHalfW * uni(rng), kHalfH * uni(rng));
    } while ((o - scene.obs[i]).norm() * kF < 10.0);
    scene.obs[i] = o;
    scene.outliers.insert(i);
  }
  return scene;
}

void expectPoseNear(const PoseMeasurement& m, const Eigen::Isometry3d& truth) {
  const Pose2 t = planarPose(truth);
  EXPECT_NEAR(m.relative.x, t.x, 0.01);  // 1 cm
  EXPECT_NEAR(m.relative.y, t.y, 0.01);
  EXPECT_NEAR(radToDeg(wrapAngle(m.relative.theta - t.theta)), 0.0, 0.3);  // 0.3 deg
  EXPECT_NEAR(m.z_m, truth.translation().z(), 0.02);                       // 2 cm
  EXPECT_LT(m.slope, 0.01);  // level truth: tilt below 0.6 deg
}

void expectOutliersExcluded(const PoseMeasurement& m, const Scene& scene) {
  const std::set<int> in(m.inliers.begin(), m.inliers.end());
  for (int o : scene.outliers) EXPECT_EQ(in.count(o), 0u) << "outlier " << o << " kept";
  // With 0.5 px noise a true inlier beyond the 3 px threshold has
  // probability ~e^-18: every one must be kept.
  EXPECT_EQ(in.size() + scene.outliers.size(), scene.points.size());
  EXPECT_EQ(m.num_points, static_cast<int>(m.inliers.size()));
}

TEST(PoseMeasurement, ForwardCameraRecoversPlanarMotion) {
  SceneSpec spec;
  for (unsigned seed = 1; seed <= 10; ++seed) {
    SCOPED_TRACE(seed);
    const Scene scene = makeScene(spec, seed);
    const PoseMeasurementResult r = measurePose(scene.points, scene.obs, spec.current, {});
    ASSERT_TRUE(r.ok()) << r.reason;
    expectPoseNear(r.measurement, spec.creation_T_current);
    expectOutliersExcluded(r.measurement, scene);
  }
}

TEST(PoseMeasurement, EverySolverRecoversPlanarMotion) {
  SceneSpec spec;
  for (PnpSolver solver :
       {PnpSolver::kAp3p, PnpSolver::kP3p, PnpSolver::kEpnp, PnpSolver::kSqpnp}) {
    SCOPED_TRACE(static_cast<int>(solver));
    PoseMeasurementParams params;
    params.solver = solver;
    const Scene scene = makeScene(spec, 7);
    const PoseMeasurementResult r = measurePose(scene.points, scene.obs, spec.current, params);
    ASSERT_TRUE(r.ok()) << r.reason;
    expectPoseNear(r.measurement, spec.creation_T_current);
    expectOutliersExcluded(r.measurement, scene);
  }
}

// A landmark built by the forward camera (points in front of it, stored in
// the robot frame) measured by the backward camera after the robot turned
// around: only the current camera's extrinsics connect the two.
TEST(PoseMeasurement, BackwardCameraMeasuresForwardLandmark) {
  SceneSpec spec;
  spec.creating = forwardCamera();
  spec.current = backwardCamera();
  spec.creation_T_current = planarMotion(0.3, -0.2, degToRad(165));
  for (unsigned seed = 1; seed <= 10; ++seed) {
    SCOPED_TRACE(seed);
    const Scene scene = makeScene(spec, seed);
    const PoseMeasurementResult r = measurePose(scene.points, scene.obs, spec.current, {});
    ASSERT_TRUE(r.ok()) << r.reason;
    expectPoseNear(r.measurement, spec.creation_T_current);
    expectOutliersExcluded(r.measurement, scene);
    // The same data read with the forward camera's extrinsics is a
    // different robot pose: the extrinsics are what makes this right.
    const PoseMeasurementResult wrong = measurePose(scene.points, scene.obs, forwardCamera(), {});
    ASSERT_TRUE(wrong.ok());
    EXPECT_GT(std::abs(wrapAngle(wrong.measurement.relative.theta - degToRad(165))), 3.0);
  }
}

// ProjErrRMS is the RMS over inliers of the per-point reprojection distance
// |r_i| in pixels. With per-axis noise sigma and n inliers of a 6-parameter
// fit, E[ProjErrRMS^2] = 2 sigma^2 (2n - 6) / (2n).
TEST(PoseMeasurement, ProjErrRmsMatchesInjectedNoise) {
  for (double sigma : {0.25, 0.5, 1.0}) {
    SCOPED_TRACE(sigma);
    SceneSpec spec;
    spec.noise_px = sigma;
    spec.num_points = 100;
    const Scene scene = makeScene(spec, 3);
    const PoseMeasurementResult r = measurePose(scene.points, scene.obs, spec.current, {});
    ASSERT_TRUE(r.ok()) << r.reason;
    const int n = r.measurement.num_points;
    const double expected = sigma * std::sqrt(2.0 * (2 * n - 6) / (2 * n));
    // Sampling spread of the RMS over ~80 points is ~6%; allow 15%.
    EXPECT_NEAR(r.measurement.proj_err_rms_px, expected, 0.15 * expected);
  }
  SceneSpec exact;
  exact.noise_px = 0;
  const Scene scene = makeScene(exact, 4);
  const PoseMeasurementResult r = measurePose(scene.points, scene.obs, exact.current, {});
  ASSERT_TRUE(r.ok()) << r.reason;
  EXPECT_LT(r.measurement.proj_err_rms_px, 1e-4);
  EXPECT_LT(r.measurement.slope, 1e-6);
  const Pose2 t = planarPose(exact.creation_T_current);
  EXPECT_NEAR(r.measurement.relative.x, t.x, 1e-6);
  EXPECT_NEAR(r.measurement.relative.y, t.y, 1e-6);
  EXPECT_NEAR(r.measurement.relative.theta, t.theta, 1e-7);
}

TEST(PoseMeasurement, NumPointsIsTheInlierCount) {
  SceneSpec spec;
  spec.num_points = 40;
  spec.outlier_fraction = 0.25;
  const Scene scene = makeScene(spec, 5);
  const PoseMeasurementResult r = measurePose(scene.points, scene.obs, spec.current, {});
  ASSERT_TRUE(r.ok()) << r.reason;
  EXPECT_EQ(r.measurement.num_points, 30);  // 40 - 10 outliers
  EXPECT_EQ(r.measurement.num_points, static_cast<int>(r.measurement.inliers.size()));
  EXPECT_TRUE(std::is_sorted(r.measurement.inliers.begin(), r.measurement.inliers.end()));
  EXPECT_GE(r.measurement.ransac_inliers, 26);
  EXPECT_GE(r.measurement.ransac_iteration_bound, 1);
  EXPECT_GE(r.measurement.refinement_rounds, 1);
  EXPECT_GT(r.measurement.total_ms, 0);
}

// Slope is the estimated tilt of the robot (paper 4: "the estimated Slope
// of the robot, which ... on a leveled floor, should be approximately
// zero"): tan of the angle between the two robot frames' z axes.
TEST(PoseMeasurement, SlopeIsTheEstimatedTiltOfTheRobot) {
  SceneSpec spec;
  Eigen::Isometry3d tilted = planarMotion(0.3, -0.2, degToRad(15));
  tilted.linear() = tilted.linear() * Eigen::AngleAxisd(degToRad(-6), Eigen::Vector3d::UnitY()) *
                    Eigen::AngleAxisd(degToRad(3), Eigen::Vector3d::UnitX());
  tilted.translation().z() = 0.05;
  spec.creation_T_current = tilted;
  const Scene scene = makeScene(spec, 8);
  const PoseMeasurementResult r = measurePose(scene.points, scene.obs, spec.current, {});
  ASSERT_TRUE(r.ok()) << r.reason;
  const double tilt = std::acos(std::cos(degToRad(6)) * std::cos(degToRad(3)));
  EXPECT_NEAR(r.measurement.slope, std::tan(tilt), 0.005);  // 0.3 deg of tilt
  EXPECT_NEAR(radToDeg(r.measurement.pitch_rad), -6.0, 0.3);
  EXPECT_NEAR(radToDeg(r.measurement.roll_rad), 3.0, 0.3);
  EXPECT_NEAR(r.measurement.z_m, 0.05, 0.01);
  EXPECT_EQ(prefilter(r.measurement), MeasurementStatus::kRejectedSlope);  // 0.117 > 0.1
}

// A point set that constrains the pose poorly (a small distant patch) gives
// noisier tilt estimates, so a larger Slope, than a well-spread one, and
// larger predicted standard deviations. Medians over 15 scenes.
TEST(PoseMeasurement, SlopeAndSigmasGrowForIllConditionedPointSets) {
  SceneSpec good;
  SceneSpec patch;
  patch.min_depth = 4.5;
  patch.max_depth = 5.0;
  patch.u_half = patch.v_half = 0.04;  // ~0.4 m wide at 4.75 m
  std::vector<double> slope_good, slope_patch, sx_good, sx_patch;
  for (unsigned seed = 1; seed <= 15; ++seed) {
    const Scene a = makeScene(good, seed), b = makeScene(patch, seed);
    const PoseMeasurementResult ra = measurePose(a.points, a.obs, good.current, {});
    const PoseMeasurementResult rb = measurePose(b.points, b.obs, patch.current, {});
    ASSERT_TRUE(ra.ok()) << ra.reason;
    if (!rb.ok()) continue;
    slope_good.push_back(ra.measurement.slope);
    slope_patch.push_back(rb.measurement.slope);
    sx_good.push_back(ra.measurement.sigma_x_m);
    sx_patch.push_back(rb.measurement.sigma_x_m);
  }
  ASSERT_GE(slope_patch.size(), 10u);
  auto median = [](std::vector<double> v) {
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
  };
  EXPECT_GT(median(slope_patch), 5 * median(slope_good));
  EXPECT_GT(median(sx_patch), 5 * median(sx_good));
  EXPECT_LT(median(sx_good), 0.01);  // a well-spread landmark pins x to < 1 cm
}

TEST(PoseMeasurement, FailsCleanly) {
  SceneSpec spec;
  spec.num_points = 5;
  spec.outlier_fraction = 0;
  Scene s = makeScene(spec, 1);
  PoseMeasurementResult r = measurePose(s.points, s.obs, spec.current, {});
  EXPECT_EQ(r.failure, MeasurementFailure::kTooFewCorrespondences);
  EXPECT_FALSE(r.ok());
  EXPECT_FALSE(r.reason.empty());

  spec.num_points = 30;
  s = makeScene(spec, 1);
  std::vector<Eigen::Vector2d> short_obs(s.obs.begin(), s.obs.end() - 1);
  EXPECT_EQ(measurePose(s.points, short_obs, spec.current, {}).failure,
            MeasurementFailure::kInvalidInput);
  std::vector<Eigen::Vector2d> nan_obs = s.obs;
  nan_obs[3].x() = std::nan("");
  EXPECT_EQ(measurePose(s.points, nan_obs, spec.current, {}).failure,
            MeasurementFailure::kInvalidInput);
  MeasurementCamera no_focal = spec.current;
  no_focal.fx = 0;
  EXPECT_EQ(measurePose(s.points, s.obs, no_focal, {}).failure, MeasurementFailure::kInvalidInput);

  // Only outliers: no consistent pose.
  spec.outlier_fraction = 1.0;
  s = makeScene(spec, 2);
  r = measurePose(s.points, s.obs, spec.current, {});
  EXPECT_FALSE(r.ok());
  EXPECT_TRUE(r.failure == MeasurementFailure::kRansacFailed ||
              r.failure == MeasurementFailure::kTooFewInliers ||
              r.failure == MeasurementFailure::kRefinementDiverged)
      << toString(r.failure);

  PoseMeasurementParams bad;
  bad.ransac_threshold_px = 0;
  EXPECT_THROW(measurePose(s.points, s.obs, spec.current, bad), std::invalid_argument);
}

TEST(PlanarProjection, YawXyAndOutOfPlaneParts) {
  const double yaw = degToRad(40), pitch = degToRad(-7), roll = degToRad(4);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(1.5, -0.5, 0.2);
  const Pose2 p = planarPose(T);
  EXPECT_NEAR(p.x, 1.5, 1e-12);
  EXPECT_NEAR(p.y, -0.5, 1e-12);
  EXPECT_NEAR(p.theta, yaw, 1e-12);
  const OutOfPlane o = outOfPlane(T);
  EXPECT_NEAR(o.z_m, 0.2, 1e-12);
  EXPECT_NEAR(o.pitch_rad, pitch, 1e-12);
  EXPECT_NEAR(o.roll_rad, roll, 1e-12);
  EXPECT_NEAR(o.slope, std::tan(std::acos(std::cos(pitch) * std::cos(roll))), 1e-12);
  // Upside down: slope is infinite, which the pre-filter rejects as a slope.
  T.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  EXPECT_TRUE(std::isinf(outOfPlane(T).slope));
}

TEST(PoseReprojectionCost, ZeroAtTruthAndJacobianMatchesCentralDifferences) {
  const Eigen::Vector3d X(2.0, -0.4, 0.7);
  const double w[3] = {0.1, -0.3, 0.2}, t[3] = {0.05, 0.1, 1.5};
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(Eigen::Vector3d(w[0], w[1], w[2]).norm(),
                                 Eigen::Vector3d(w[0], w[1], w[2]).normalized())
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
  const Eigen::Vector3d p = T * X;
  const Eigen::Vector2d uv(p.x() / p.z(), p.y() / p.z());
  std::unique_ptr<ceres::CostFunction> at_truth(PoseReprojectionCost::Create(X, uv, 300, 310));
  const double* params[2] = {w, t};
  double r[2];
  ASSERT_TRUE(at_truth->Evaluate(params, r, nullptr));
  EXPECT_NEAR(r[0], 0, 1e-10);
  EXPECT_NEAR(r[1], 0, 1e-10);

  // Off the truth by 0.01 in normalized units: residual is f * 0.01.
  std::unique_ptr<ceres::CostFunction> cost(
      PoseReprojectionCost::Create(X, uv + Eigen::Vector2d(0.01, -0.02), 300, 310));
  double J_w[6], J_t[6];
  double* jac[2] = {J_w, J_t};
  ASSERT_TRUE(cost->Evaluate(params, r, jac));
  EXPECT_NEAR(r[0], -3.0, 1e-9);
  EXPECT_NEAR(r[1], 6.2, 1e-9);
  const double h = 1e-6;
  for (int block = 0; block < 2; ++block)
    for (int k = 0; k < 3; ++k) {
      double wp[3] = {w[0], w[1], w[2]}, tp[3] = {t[0], t[1], t[2]};
      double wm[3] = {w[0], w[1], w[2]}, tm[3] = {t[0], t[1], t[2]};
      (block == 0 ? wp : tp)[k] += h;
      (block == 0 ? wm : tm)[k] -= h;
      const double* pp[2] = {wp, tp};
      const double* pm[2] = {wm, tm};
      double rp[2], rm[2];
      ASSERT_TRUE(cost->Evaluate(pp, rp, nullptr));
      ASSERT_TRUE(cost->Evaluate(pm, rm, nullptr));
      const double* J = block == 0 ? J_w : J_t;
      for (int i = 0; i < 2; ++i)  // row-major 2x3
        EXPECT_NEAR(J[i * 3 + k], (rp[i] - rm[i]) / (2 * h), 1e-5) << block << " " << k << " " << i;
    }

  // Behind the camera: no residual.
  const double t_behind[3] = {0, 0, -10};
  const double* behind[2] = {w, t_behind};
  EXPECT_FALSE(cost->Evaluate(behind, r, nullptr));
}

// ---------------------------------------------------------------------------
// Pre-filter.

static_assert(static_cast<int>(MeasurementStatus::kUnfiltered) ==
              vslam::visual_measurement_t::STATUS_UNFILTERED);
static_assert(static_cast<int>(MeasurementStatus::kAccepted) ==
              vslam::visual_measurement_t::STATUS_ACCEPTED);
static_assert(static_cast<int>(MeasurementStatus::kRejectedProjErr) ==
              vslam::visual_measurement_t::STATUS_REJECTED_PROJ_ERR);
static_assert(static_cast<int>(MeasurementStatus::kRejectedNumPoints) ==
              vslam::visual_measurement_t::STATUS_REJECTED_NUM_POINTS);
static_assert(static_cast<int>(MeasurementStatus::kRejectedSlope) ==
              vslam::visual_measurement_t::STATUS_REJECTED_SLOPE);
static_assert(static_cast<int>(MeasurementStatus::kRejectedInvalid) ==
              vslam::visual_measurement_t::STATUS_REJECTED_INVALID);

PoseMeasurement goodMeasurement() {
  PoseMeasurement m;
  m.relative = {0.3, -0.2, 0.26};
  m.proj_err_rms_px = 0.7;
  m.num_points = 25;
  m.slope = 0.01;
  return m;
}

TEST(Prefilter, PaperDefaultsAndBoundaries) {
  const PrefilterParams p;
  EXPECT_EQ(p.max_proj_err_rms_px, 3.0);
  EXPECT_EQ(p.min_num_points, 10);
  EXPECT_EQ(p.max_slope, 0.1);
  PoseMeasurement m = goodMeasurement();
  EXPECT_EQ(prefilter(m), MeasurementStatus::kAccepted);

  m.proj_err_rms_px = 3.0;  // "reject if ProjErrRMS > 3.0": 3.0 itself passes
  EXPECT_EQ(prefilter(m), MeasurementStatus::kAccepted);
  m.proj_err_rms_px = 3.0001;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedProjErr);

  m = goodMeasurement();
  m.num_points = 10;  // "reject if NPoints < 10"
  EXPECT_EQ(prefilter(m), MeasurementStatus::kAccepted);
  m.num_points = 9;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedNumPoints);

  m = goodMeasurement();
  m.slope = 0.1;  // "reject if Slope > 0.1"
  EXPECT_EQ(prefilter(m), MeasurementStatus::kAccepted);
  m.slope = 0.1001;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedSlope);
  m.slope = std::numeric_limits<double>::infinity();
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedSlope);
}

TEST(Prefilter, FirstFailedTestInThePapersOrder) {
  PoseMeasurement m = goodMeasurement();
  m.proj_err_rms_px = 5;
  m.num_points = 3;
  m.slope = 1;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedProjErr);
  m.proj_err_rms_px = 1;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedNumPoints);
  m.num_points = 30;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedSlope);
}

TEST(Prefilter, NonFiniteIsInvalid) {
  const double nan = std::nan("");
  for (int field = 0; field < 5; ++field) {
    PoseMeasurement m = goodMeasurement();
    switch (field) {
      case 0:
        m.relative.x = nan;
        break;
      case 1:
        m.relative.theta = std::numeric_limits<double>::infinity();
        break;
      case 2:
        m.proj_err_rms_px = nan;
        break;
      case 3:
        m.slope = nan;
        break;
      case 4:
        m.num_points = -1;
        break;
    }
    EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedInvalid) << field;
  }
}

TEST(Prefilter, CustomRegion) {
  PrefilterParams wide;
  wide.max_proj_err_rms_px = 5;
  wide.min_num_points = 6;
  wide.max_slope = 0.2;
  PoseMeasurement m = goodMeasurement();
  m.proj_err_rms_px = 4;
  m.num_points = 7;
  m.slope = 0.15;
  EXPECT_EQ(prefilter(m, wide), MeasurementStatus::kAccepted);
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedProjErr);
}

}  // namespace
}  // namespace vslam::frontend
