// The front-end's pipeline on real rendered pixels with known geometry (the
// issue's acceptance test for landmark creation + visual measurement): a
// landmark is created from three views 20 cm apart, then the robot is placed
// at known offsets from the creation pose, the frame is rendered, the
// landmark recognized and measured, and the measured (dx, dy, dtheta) must
// equal the offset. For the forward camera, the backward camera, and across
// cameras (a forward landmark measured by the backward camera after the
// robot turned round). Cameras and their mounting come from the simulated
// robot's file, as in a run.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "config/robot_config.hpp"
#include "frontend/features.hpp"
#include "frontend/landmark_creation.hpp"
#include "frontend/landmark_index.hpp"
#include "frontend/pose_measurement.hpp"
#include "world/renderer.hpp"
#include "world/world.hpp"

namespace vslam::frontend {
namespace {

namespace fs = std::filesystem;
const fs::path kSource = VSLAM_SOURCE_DIR;
constexpr double kDeg = M_PI / 180.0;

// Tolerances on clean renders with exact odometry for creation: the paper's
// median error is 10 cm and 1.7 deg over a real run; a single measurement
// 0.2-0.7 m from the creation pose should do far better.
constexpr double kMaxXyError = 0.05;             // metres
constexpr double kMaxHeadingError = 1.0 * kDeg;  // radians

class RenderedMeasurement : public ::testing::Test {
 protected:
  RenderedMeasurement()
      : robot_(config::RobotConfig::loadFile(kSource / "config/robot/sim_two_camera.yaml")),
        world_(world::World::loadFile(kSource / "config/worlds/apartment.yaml")) {}

  const config::CameraConfig& camera(const std::string& name) const { return robot_.camera(name); }

  cv::Mat render(const config::CameraConfig& cam, const Pose2& robot, double exposure = 1.0,
                 double noise_sigma = 0.0) {
    world::Renderer renderer(world_, world::CameraModel{cam.width, cam.height, cam.fx, cam.fy,
                                                        cam.cx, cam.cy, cam.distortion});
    world::RenderEffects effects;
    effects.exposure = exposure;
    effects.noise_sigma = noise_sigma;
    cv::Mat image;
    renderer.render(isometryFromPose2(robot) * cam.robot_T_camera, {}, effects, false, image);
    return image;
  }

  Features view(const config::CameraConfig& cam, const Pose2& robot) {
    FeatureExtractor extractor(cam);
    Features f;
    extractor.extract(render(cam, robot), &f);
    return f;
  }

  // A landmark created by `cam` from three views 0, 20 and 40 cm forward of
  // `creation` (odometry exact), added to the index under id 1.
  void createLandmark(const config::CameraConfig& cam, const Pose2& creation) {
    std::array<Pose2, 3> poses;
    std::array<Features, 3> views;
    for (int k = 0; k < 3; ++k) {
      poses[k] = creation.compose(Pose2{0.2 * k, 0.0, 0.0});
      views[k] = view(cam, poses[k]);
    }
    LandmarkCreator creator(cam);
    const CreationResult r = creator.create(views[0], views[1], views[2], poses);
    ASSERT_TRUE(r.ok()) << toString(r.status) << ": " << r.reason;
    LandmarkModel model;
    model.id = 1;
    model.points_robot = r.landmark.points_robot;
    model.descriptors.create(static_cast<int>(r.landmark.feature_index.size()), 128, CV_32F);
    for (size_t j = 0; j < r.landmark.feature_index.size(); ++j) {
      views[0]
          .descriptors.row(r.landmark.feature_index[j])
          .copyTo(model.descriptors.row(static_cast<int>(j)));
    }
    std::printf("%s landmark: %zu points, rms %.2f px\n", cam.name.c_str(),
                model.points_robot.size(), r.landmark.rms_reprojection_px);
    ASSERT_GE(model.points_robot.size(), 30u);
    index_.add(std::move(model));
  }

  // Renders `cam` with the robot at creation * offset, recognizes the
  // landmark and checks the measurement against the offset.
  void expectMeasured(const config::CameraConfig& cam, const Pose2& creation, const Pose2& offset) {
    expectMeasured(cam, offset, view(cam, creation.compose(offset)));
  }
  void expectMeasured(const config::CameraConfig& cam, const Pose2& offset, const Features& f) {
    SCOPED_TRACE(cam.name + " camera at offset (" + std::to_string(offset.x) + ", " +
                 std::to_string(offset.y) + ", " + std::to_string(offset.theta / kDeg) + " deg)");
    const std::vector<Recognition> seen = index_.recognize(f);
    ASSERT_EQ(seen.size(), 1u) << "the landmark is not recognized";
    const PoseMeasurementResult r =
        measurePose(seen[0].points_robot, seen[0].observations, MeasurementCamera::fromConfig(cam),
                    PoseMeasurementParams{});
    ASSERT_TRUE(r.ok()) << toString(r.failure) << ": " << r.reason;
    const PoseMeasurement& m = r.measurement;
    const double xy = std::hypot(m.relative.x - offset.x, m.relative.y - offset.y);
    const double heading = std::abs(wrapAngle(m.relative.theta - offset.theta));
    std::printf(
        "  %-8s offset (%5.2f, %5.2f, %6.1f deg): measured (%5.2f, %5.2f, %6.1f deg), "
        "error %.1f cm %.2f deg, NPoints %d, ProjErrRMS %.2f, Slope %.4f\n",
        cam.name.c_str(), offset.x, offset.y, offset.theta / kDeg, m.relative.x, m.relative.y,
        m.relative.theta / kDeg, xy * 100, heading / kDeg, m.num_points, m.proj_err_rms_px,
        m.slope);
    EXPECT_LT(xy, kMaxXyError);
    EXPECT_LT(heading, kMaxHeadingError);
    EXPECT_EQ(prefilter(m), MeasurementStatus::kAccepted);
  }

  Pose2 start() const { return {world_.start.x(), world_.start.y(), world_.start.z()}; }

  config::RobotConfig robot_;
  world::World world_;
  LandmarkIndex index_;
};

// The apartment's start faces furniture 1.5-4 m away.
TEST_F(RenderedMeasurement, ForwardCameraMeasuresKnownOffsets) {
  const auto& cam = camera("forward");
  const Pose2 creation = start();
  createLandmark(cam, creation);
  for (const Pose2& offset : {Pose2{0.5, 0.0, 0.0}, Pose2{0.3, 0.15, 8 * kDeg},
                              Pose2{0.6, -0.1, -10 * kDeg}, Pose2{-0.2, 0.05, 5 * kDeg}}) {
    expectMeasured(cam, creation, offset);
  }
}

// Robot facing away from the furniture: the backward camera sees it, and
// creation drives away from it.
TEST_F(RenderedMeasurement, BackwardCameraMeasuresKnownOffsets) {
  const auto& cam = camera("backward");
  const Pose2 creation = start().compose(Pose2{0.6, 0.0, M_PI});
  createLandmark(cam, creation);
  for (const Pose2& offset :
       {Pose2{-0.2, 0.0, 0.0}, Pose2{0.2, 0.1, 8 * kDeg}, Pose2{0.4, -0.1, -6 * kDeg}}) {
    expectMeasured(cam, creation, offset);
  }
}

// The forward camera's landmark, measured by the backward camera after the
// robot turned round: only the backward camera's mounting enters, and the
// result is still the robot's pose relative to the creation robot.
TEST_F(RenderedMeasurement, BackwardCameraMeasuresAForwardLandmark) {
  const Pose2 creation = start();
  createLandmark(camera("forward"), creation);
  for (const Pose2& offset : {Pose2{0.9, 0.0, M_PI}, Pose2{1.0, 0.1, M_PI - 8 * kDeg}}) {
    expectMeasured(camera("backward"), creation, offset);
  }
}

// At dusk (a third of the exposure, no auto-exposure) SIFT's absolute
// contrast threshold loses most keypoints; the front-end's digital gain
// brings them back, and the landmark built in normal light is measured as
// well as in normal light. A normal frame is left as it is.
TEST_F(RenderedMeasurement, DimFramesAreMeasuredAfterTheDigitalGain) {
  const auto& cam = camera("forward");
  const Pose2 creation = start();
  createLandmark(cam, creation);
  const Pose2 offset{0.5, 0.0, 0.0};
  // The scenarios' exposure at dusk and their sensor noise.
  const cv::Mat normal = render(cam, creation.compose(offset), 1.0, 1.5);
  const cv::Mat dim = render(cam, creation.compose(offset), 0.35, 1.5);

  SiftParams gained;
  gained.gain_target_level = 100;  // as in config/vslam.yaml
  FeatureExtractor plain_extractor(cam), gain_extractor(cam, gained);
  Features f_normal, f_normal_gained, f_dim, f_dim_gained;
  plain_extractor.extract(normal, &f_normal);
  gain_extractor.extract(normal, &f_normal_gained);
  EXPECT_EQ(f_normal_gained.gain, 1.0) << "a normal frame is used as it is";
  EXPECT_EQ(f_normal_gained.size(), f_normal.size());
  plain_extractor.extract(dim, &f_dim);
  gain_extractor.extract(dim, &f_dim_gained);
  std::printf("keypoints: normal %zu, dim %zu, dim with gain %.2f: %zu\n", f_normal.size(),
              f_dim.size(), f_dim_gained.gain, f_dim_gained.size());
  EXPECT_GT(f_dim_gained.gain, 1.5);
  EXPECT_LT(f_dim.size(), f_normal.size() / 2) << "without the gain most keypoints are lost";
  EXPECT_GT(f_dim_gained.size(), 2 * f_dim.size());
  expectMeasured(cam, offset, f_dim_gained);

  SiftParams bad;
  bad.max_gain = 0.5;
  EXPECT_THROW(FeatureExtractor(cam, bad), std::invalid_argument);
}

}  // namespace
}  // namespace vslam::frontend
