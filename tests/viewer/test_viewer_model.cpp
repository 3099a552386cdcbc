// viewer::ViewerModel: what a frame shows, from plain inputs: the ground truth
// moved onto the estimate's start, bounded trajectories, landmarks, particles
// and a camera's SIFT features with the matches of the landmark it measured.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "viewer/viewer_model.hpp"

using namespace vslam::viewer;

namespace {

// Pixels of exactly this BGR colour.
int countColour(const cv::Mat& img, cv::Vec3b colour) {
  int n = 0;
  for (int r = 0; r < img.rows; ++r) {
    for (int c = 0; c < img.cols; ++c) n += img.at<cv::Vec3b>(r, c) == colour;
  }
  return n;
}

// A textured image SIFT finds plenty in.
cv::Mat texture() {
  cv::Mat img(240, 320, CV_8U);
  cv::RNG rng(7);
  rng.fill(img, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(img, img, cv::Size(5, 5), 1.5);
  return img;
}

}  // namespace

TEST(ViewerModel, GroundTruthIsDrawnFromTheEstimatesStart) {
  ViewerModel m;
  // The world frame: the robot starts at (5, 5) facing +y and drives 1 m.
  m.addGroundTruth({0.0, 5, 5, M_PI / 2});
  m.addGroundTruth({1.0, 5, 6, M_PI / 2});
  // The map frame starts at the origin facing +x.
  m.addEstimate({0.0, 0, 0, 0}, false, 100);
  const auto gt = m.alignedGroundTruth();
  ASSERT_EQ(gt.size(), 2u);
  EXPECT_NEAR(gt[0].x, 0, 1e-12);
  EXPECT_NEAR(gt[0].y, 0, 1e-12);
  EXPECT_NEAR(gt[1].x, 1, 1e-12);  // 1 m ahead along the estimate's heading
  EXPECT_NEAR(gt[1].y, 0, 1e-12);
  EXPECT_NEAR(gt[1].theta, 0, 1e-12);
}

TEST(ViewerModel, TrajectoriesStayBoundedOverALongRun) {
  ViewerModel m;
  for (int i = 0; i < 100000; ++i) m.addOdometry({i * 0.02, i * 0.001, 0, 0});
  EXPECT_LE(m.odometry().size(), kMaxTrajectoryPoints);
  EXPECT_GT(m.odometry().size(), kMaxTrajectoryPoints / 2);
  EXPECT_NEAR(m.odometry().front().x, 0, 1e-12);
  EXPECT_NEAR(m.odometry().back().x, 99.999, 1e-9);  // the newest is kept
  m.addOdometry({0, std::numeric_limits<double>::quiet_NaN(), 0, 0});
  EXPECT_NEAR(m.odometry().back().x, 99.999, 1e-9) << "a NaN pose is not drawn";
}

TEST(ViewerModel, AFrameShowsLandmarksParticlesAndTheCamerasMatches) {
  ViewerModel empty;
  const cv::Mat blank = empty.render({960, 540});
  ASSERT_EQ(blank.size(), cv::Size(960, 540));
  const cv::Vec3b landmark(30, 30, 220), nominal(60, 170, 60), dual(200, 60, 200);
  const cv::Vec3b matched(0, 220, 0);
  // (The legend draws a line of each colour: counts are against the blank frame's.)
  const int blank_landmark = countColour(blank, landmark),
            blank_nominal = countColour(blank, nominal);

  ViewerModel m;
  m.addEstimate({0.0, 0, 0, 0}, false, 150);
  m.addEstimate({1.0, 1, 0, 0}, false, 150);
  m.setMap({{7, 2.0, 1.0, 0.04, 0.0, 0.01},
            {8, -1.0, 0.5, std::numeric_limits<double>::quiet_NaN(), 0, 0}});
  std::vector<Particle> particles;
  for (int i = 0; i < 50; ++i) particles.push_back({1 + 0.01 * i, 0.01 * i, 0, 0.02, i % 2 == 1});
  m.setParticles(particles);
  // The camera sees a texture; landmark 7 was built from it, so its
  // measurement matches many of the features.
  const cv::Mat img = texture();
  std::vector<cv::KeyPoint> kp;
  cv::Mat descriptors;
  cv::SIFT::create(300)->detectAndCompute(img, cv::noArray(), kp, descriptors);
  ASSERT_GT(kp.size(), 50u);
  m.setLandmarkDescriptors(7, descriptors);
  m.setImage("forward", img, 1.0);
  m.addMeasurement("forward", 7, true, 1.0);
  const cv::Mat frame = m.render({960, 540});
  EXPECT_GT(countColour(frame, landmark), blank_landmark + 20);
  EXPECT_GT(countColour(frame, nominal), blank_nominal);
  EXPECT_GT(countColour(frame, dual), countColour(blank, dual));
  EXPECT_GT(countColour(frame, matched), 200) << "the matched features are circled";
  EXPECT_EQ(m.cameras(), std::vector<std::string>{"forward"});
  EXPECT_EQ(m.status().measurements_accepted, 1);

  // Values from the network that are not numbers or far away draw nothing
  // and break nothing.
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = HUGE_VAL;
  ViewerModel odd;
  odd.addEstimate({0, 0, 0, nan}, false, nan);
  odd.addEstimate({1, 1e300, -1e300, 0}, true, 10);
  odd.addGroundTruth({0, inf, 0, 0});
  odd.setMap({{1, 1e300, 0, inf, nan, -5}, {2, 0, 0, -1, 0, -1}});
  odd.setParticles({{nan, 0, 0, 1, false}, {1e200, 1e200, 0, 1, true}});
  odd.setAppearanceMap({{1, {nan, inf}}, {2, {1e300, 0}}}, {{1, 2}, {2, 3}});
  odd.setAppearanceBest(1, nan, -3);
  EXPECT_EQ(odd.render({640, 360}).size(), cv::Size(640, 360));

  // A measurement of a landmark the viewer has no descriptors of: no matches.
  m.addMeasurement("forward", 99, false, 1.0);
  EXPECT_EQ(countColour(m.render({960, 540}), matched), 0);
  EXPECT_EQ(m.status().measurements_rejected, 1);
}
