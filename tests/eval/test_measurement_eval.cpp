// vslam-eval --measurements on hand-made data with known answers: the truth
// of a relative measurement G(t_c)^-1 G(t) with interpolated ground truth,
// the error statistics of accepted and all measurements, Table 1's bands,
// what is not scored, the errors by creation distance and by change of
// viewing direction, and the same report read from an LCM log.
#include <gtest/gtest.h>

#include <cmath>
#include <sstream>
#include <vslam/camera_calibration_t.hpp>
#include <vslam/ground_truth_pose_t.hpp>
#include <vslam/landmark_update_t.hpp>
#include <vslam/visual_measurement_t.hpp>

#include "eval/errors.hpp"
#include "eval/log_measurements.hpp"
#include "eval/measurement_eval.hpp"
#include "eval_test_util.hpp"

using namespace vslam::eval;

namespace {

// Straight line along +y at 0.1 m/s, heading +90 deg, ground truth at 10 Hz
// from t = 0 to 20 s: at time t the robot is at (1, 0.1 t).
Trajectory lineAlongY() {
  Trajectory tr;
  for (int i = 0; i <= 200; ++i) {
    const double t = 0.1 * i;
    tr.poses.push_back(planarPose(t, 1.0, 0.1 * t, 0.0, M_PI / 2));
  }
  return tr;
}

// A measurement of landmark 7 (created at t = 2 s) at time t, with an error
// (ex, ey, eth) added to the truth: the robot has moved 0.1 (t - 2) forward,
// in its own frame +x.
MeasurementSample sample(double t, double ex, double ey, double eth,
                         MeasurementVerdict v = MeasurementVerdict::kAccepted) {
  MeasurementSample s;
  s.t = t;
  s.camera = "forward";
  s.landmark_id = 7;
  s.dx = 0.1 * (t - 2.0) + ex;
  s.dy = ey;
  s.dtheta = eth;
  s.verdict = v;
  return s;
}

const std::map<int64_t, LandmarkCreationTime> kCreations = {{7, {2.0, "forward"}}};

TEST(MeasurementEval, TruthIsTheRelativePoseAndErrorsAreDistances) {
  // t = 7.05 falls between two ground-truth poses: interpolated truth dx = 0.505.
  std::vector<MeasurementSample> s = {sample(7.05, 0.03, 0.04, 0.0), sample(12.0, 0.0, 0.0, 0.1),
                                      sample(4.0, -0.06, 0.08, -0.02)};
  const MeasurementReport r = evaluateMeasurements(lineAlongY(), s, kCreations);
  ASSERT_EQ(r.scored.size(), 3u);
  EXPECT_NEAR(r.scored[0].true_dx, 0.505, 1e-9);
  EXPECT_NEAR(r.scored[0].true_dy, 0.0, 1e-9);
  EXPECT_NEAR(r.scored[0].true_dtheta, 0.0, 1e-9);
  EXPECT_NEAR(r.scored[0].xy_error_m, 0.05, 1e-9);
  EXPECT_NEAR(r.scored[1].heading_error_rad, 0.1, 1e-9);
  EXPECT_NEAR(r.scored[2].xy_error_m, 0.10, 1e-9);
  EXPECT_NEAR(r.scored[2].heading_error_rad, 0.02, 1e-9);
  EXPECT_NEAR(r.accepted.xy_m.median, 0.05, 1e-9);
  EXPECT_NEAR(r.accepted.xy_m.mean, 0.05, 1e-9);
  EXPECT_NEAR(r.accepted.xy_m.rmse, std::sqrt((0.05 * 0.05 + 0.1 * 0.1) / 3), 1e-9);
  EXPECT_NEAR(r.accepted.heading_rad.median, 0.02, 1e-9);
  EXPECT_EQ(r.landmarks, 1);
  EXPECT_NEAR(r.duration_s, 8.0, 1e-9);
}

TEST(MeasurementEval, HeadingErrorWrapsAroundPi) {
  // A robot facing back along the line: truth dtheta = pi; measured -pi + 0.01.
  Trajectory tr;
  for (int i = 0; i <= 100; ++i) {
    tr.poses.push_back(planarPose(0.1 * i, 0, 0, 0, i < 50 ? 0.0 : M_PI));
  }
  MeasurementSample s;
  s.t = 8.0;
  s.landmark_id = 7;
  s.dtheta = -M_PI + 0.01;
  const MeasurementReport r = evaluateMeasurements(tr, {s}, kCreations);
  ASSERT_EQ(r.scored.size(), 1u);
  EXPECT_NEAR(r.scored[0].heading_error_rad, 0.01, 1e-9);
}

TEST(MeasurementEval, BandsCountAcceptedAndRejectedByXyError) {
  using V = MeasurementVerdict;
  std::vector<MeasurementSample> s = {
      sample(5, 0.05, 0, 0),                         // 5 cm, accepted: band 0-10
      sample(6, 0.09, 0, 0, V::kRejectedNumPoints),  // 9 cm, rejected: band 0-10
      sample(7, 0.15, 0, 0),                         // 15 cm: 10-20
      sample(8, 0.0, 0.55, 0, V::kRejectedSlope),    // 55 cm: 50-70
      sample(9, 2.5, 0, 0),                          // 250 cm: > 200
      sample(10, 0.105, 0, 0),                       // 10.5 cm: 10-20
  };
  const MeasurementReport r = evaluateMeasurements(lineAlongY(), s, kCreations);
  ASSERT_EQ(r.bands.size(), 10u);
  EXPECT_EQ(r.bands[0].accepted, 1);
  EXPECT_EQ(r.bands[0].rejected, 1);
  EXPECT_EQ(r.bands[1].accepted, 2);
  EXPECT_EQ(r.bands[5].rejected, 1);
  EXPECT_EQ(r.bands[9].accepted, 1);
  EXPECT_TRUE(std::isinf(r.bands[9].high_cm));
  EXPECT_EQ(r.acceptedCount(), 4);
  EXPECT_NEAR(r.acceptedFraction(), 4.0 / 6.0, 1e-12);
  EXPECT_EQ(r.verdicts.at(V::kRejectedNumPoints), 1);
  EXPECT_EQ(r.all.xy_m.count, 6u);
  EXPECT_EQ(r.accepted.xy_m.count, 4u);

  std::ostringstream os;
  printMeasurementReport(os, r);
  EXPECT_NE(os.str().find("<20                 3         1          75.00%"), std::string::npos)
      << os.str();
  EXPECT_NE(os.str().find(">200                1         0         100.00%"), std::string::npos)
      << os.str();
}

TEST(MeasurementEval, UnknownLandmarksAndMissingTruthAreCountedNotScored) {
  std::vector<MeasurementSample> s = {sample(5, 0, 0, 0), sample(25, 0, 0, 0)};  // 25 s: after GT
  s.push_back(sample(6, 0, 0, 0));
  s.back().landmark_id = 99;  // never created
  const MeasurementReport r = evaluateMeasurements(lineAlongY(), s, kCreations);
  EXPECT_EQ(r.scored.size(), 1u);
  EXPECT_EQ(r.no_truth, 1);
  EXPECT_EQ(r.unknown_landmark, 1);
  EXPECT_EQ(r.landmarks, 2);
}

TEST(MeasurementEval, GroundTruthGapIsNotBridged) {
  Trajectory tr = lineAlongY();
  tr.poses.erase(tr.poses.begin() + 60, tr.poses.begin() + 70);  // no truth 6.0..6.9 s
  const MeasurementReport r =
      evaluateMeasurements(tr, {sample(6.5, 0, 0, 0), sample(8.0, 0, 0, 0)}, kCreations);
  EXPECT_EQ(r.no_truth, 1);
  EXPECT_EQ(r.scored.size(), 1u);
  EXPECT_THROW(evaluateMeasurements(Trajectory{}, {}, kCreations), DataError);
}

TEST(MeasurementEval, RobustSigmaIgnoresAMinorityOfGrossErrors) {
  // Median 3, absolute deviations {2, 1, 0, 1, 97}: their median 1.
  EXPECT_NEAR(robustSigma({1, 2, 3, 4, 100}), 1.4826, 1e-12);
  // Even count: the mean of the two middle values, for both medians.
  EXPECT_NEAR(robustSigma({-1, 1}), 1.4826, 1e-12);
  EXPECT_TRUE(std::isnan(robustSigma({})));
}

TEST(MeasurementEval, ErrorsAreBinnedByCreationDistanceAndViewChange) {
  // Landmark 7 was made by the forward camera (heading 0 on the robot);
  // measured by it at 0.2 and 0.4 m from the creation pose and by the
  // backward camera (heading pi) at 1.2 m: a view change of 180 degrees.
  std::vector<MeasurementSample> s = {
      sample(4.0, 0.01, 0.0, 0.0), sample(6.0, 0.0, -0.01, 0.01), sample(14.0, 0.5, 0.0, 0.0),
      sample(15.0, 0.0, 0.0, 0.0, MeasurementVerdict::kRejectedSlope)};
  s[2].camera = "backward";
  const std::map<std::string, double> headings = {{"forward", 0.0}, {"backward", M_PI}};
  const MeasurementReport r = evaluateMeasurements(lineAlongY(), s, kCreations, {}, headings);
  ASSERT_EQ(r.scored.size(), 4u);
  EXPECT_NEAR(r.scored[0].creation_distance_m, 0.2, 1e-9);
  EXPECT_NEAR(r.scored[0].view_change_rad, 0.0, 1e-9);
  EXPECT_NEAR(r.scored[2].creation_distance_m, 1.2, 1e-9);
  EXPECT_NEAR(r.scored[2].view_change_rad, M_PI, 1e-9);
  EXPECT_NEAR(r.scored[1].signed_heading_error_rad, 0.01, 1e-9);

  // Default edges 0.5, 1, 1.5, 2, 3 m: the two forward ones in the first
  // bin, the backward one in the third; the rejected one in none.
  ASSERT_EQ(r.by_distance.size(), 6u);
  EXPECT_EQ(r.by_distance[0].count, 2);
  EXPECT_EQ(r.by_distance[1].count, 0);
  EXPECT_EQ(r.by_distance[2].count, 1);
  EXPECT_TRUE(std::isinf(r.by_distance.back().high));
  // ex, ey of the first bin: {0.01, 0, 0, -0.01}: median 0, deviations'
  // median 0.005.
  EXPECT_NEAR(r.by_distance[0].robust_sigma_xy_m, 1.4826 * 0.005, 1e-9);
  EXPECT_NEAR(r.by_distance[0].robust_sigma_heading_rad, 1.4826 * 0.005, 1e-9);
  EXPECT_DOUBLE_EQ(r.by_distance[0].gross_fraction, 0.0);
  EXPECT_DOUBLE_EQ(r.by_distance[2].gross_fraction, 1.0);  // 0.5 m off
  EXPECT_TRUE(std::isnan(r.by_distance[1].robust_sigma_xy_m));
  // Default edges 10, 20, 30, 45, 60, 90 deg.
  ASSERT_EQ(r.by_view_change.size(), 7u);
  EXPECT_EQ(r.by_view_change.front().count, 2);
  EXPECT_EQ(r.by_view_change.back().count, 1);

  // Without the cameras' headings the view change is unknown: in no bin.
  const MeasurementReport unknown = evaluateMeasurements(lineAlongY(), s, kCreations);
  EXPECT_TRUE(std::isnan(unknown.scored[0].view_change_rad));
  for (const auto& bin : unknown.by_view_change) EXPECT_EQ(bin.count, 0);
  EXPECT_EQ(unknown.by_distance[0].count, 2);
  std::ostringstream os;
  printMeasurementReport(os, unknown);
  EXPECT_NE(os.str().find("no camera calibration"), std::string::npos) << os.str();
}

TEST(MeasurementEval, ReadsALogAndJudgesUnfilteredMeasurementsByThePrefilter) {
  const auto dir = vslam::test::freshDir("measurement_eval");
  const auto path = dir / "run.lcmlog";
  {
    vslam::bus::LogWriter log(path);
    auto write = [&](const std::string& channel, const auto& msg, int64_t utime) {
      log.writeMessage(utime, channel, msg);
    };
    for (const auto& p : lineAlongY().poses) {
      vslam::ground_truth_pose_t g{};
      g.utime = static_cast<int64_t>(std::llround(p.t * 1e6));
      g.x = p.position.x();
      g.y = p.position.y();
      g.theta = headingOf(p.orientation);
      write("GROUND_TRUTH", g, g.utime);
    }
    vslam::landmark_update_t u{};
    u.op = vslam::landmark_update_t::OP_PROPOSED;
    u.landmark.landmark_id = 7;
    u.landmark.camera = "forward";
    u.landmark.created_utime = 2000000;
    write("LANDMARK_PROPOSAL", u, 2000000);
    auto meas = [&](int64_t utime, double proj_err, int points, double slope, int8_t status) {
      vslam::visual_measurement_t m{};
      m.utime = utime;
      m.camera = "forward";
      m.landmark_id = 7;
      m.dx = 0.1 * (utime * 1e-6 - 2.0) + 0.02;
      m.proj_err_rms = proj_err;
      m.num_points = points;
      m.slope = slope;
      m.status = status;
      write("VISUAL_MEASUREMENT", m, utime);
    };
    meas(5000000, 1.0, 30, 0.01, 0);  // unfiltered, inside the region: accepted
    meas(6000000, 3.5, 30, 0.01, 0);  // ProjErrRMS > 3
    meas(7000000, 1.0, 9, 0.01, 0);   // NPoints < 10
    meas(8000000, 1.0, 30, 0.2, 0);   // Slope > 0.1
    meas(9000000, 1.0, 30, 0.2, 1);   // judged accepted elsewhere: kept
    // A camera looking backward: its optical axis (camera z) turned -90
    // degrees about the robot's y axis is the robot's -x.
    vslam::camera_calibration_t c{};
    c.camera = "backward";
    c.robot_q_camera[0] = std::cos(-M_PI / 4);
    c.robot_q_camera[2] = std::sin(-M_PI / 4);
    write("CAM_BACKWARD_CALIBRATION", c, 1000000);
  }
  MeasurementLogOptions options;
  const MeasurementLog m = readMeasurementLog(path, options);
  ASSERT_EQ(m.samples.size(), 5u);
  EXPECT_EQ(m.samples[0].verdict, MeasurementVerdict::kAccepted);
  EXPECT_EQ(m.samples[1].verdict, MeasurementVerdict::kRejectedProjErr);
  EXPECT_EQ(m.samples[2].verdict, MeasurementVerdict::kRejectedNumPoints);
  EXPECT_EQ(m.samples[3].verdict, MeasurementVerdict::kRejectedSlope);
  EXPECT_EQ(m.samples[4].verdict, MeasurementVerdict::kAccepted);
  ASSERT_EQ(m.creations.count(7), 1u);
  EXPECT_DOUBLE_EQ(m.creations.at(7).t, 2.0);
  ASSERT_EQ(m.camera_heading_rad.count("backward"), 1u);
  EXPECT_NEAR(std::abs(m.camera_heading_rad.at("backward")), M_PI, 1e-9);
  const MeasurementReport r = evaluateMeasurements(m.reference, m.samples, m.creations);
  ASSERT_EQ(r.scored.size(), 5u);
  EXPECT_NEAR(r.accepted.xy_m.median, 0.02, 1e-6);

  options.rejudge = true;  // the region applies to the judged one too
  EXPECT_EQ(readMeasurementLog(path, options).samples[4].verdict,
            MeasurementVerdict::kRejectedSlope);
  options.prefilter.max_slope = 0.5;  // a wider region
  EXPECT_EQ(readMeasurementLog(path, options).samples[3].verdict, MeasurementVerdict::kAccepted);

  options.measurement_channel = "NOPE";
  try {
    readMeasurementLog(path, options);
    FAIL() << "a missing measurement channel must be an error";
  } catch (const DataError& e) {
    EXPECT_NE(std::string(e.what()).find("VISUAL_MEASUREMENT (5)"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
