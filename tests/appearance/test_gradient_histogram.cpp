// Gradient-orientation histograms and the chi-square distance (Lee & Sowmya
// eqs. 4, 5) against values computed by hand.
#include <gtest/gtest.h>

#include <cmath>

#include "appearance/action_detector.hpp"
#include "appearance/gradient_histogram.hpp"

using namespace vslam;
using namespace vslam::appearance;

TEST(OrientationBin, SplitsMinusPiToPiIntoEqualBins) {
  EXPECT_EQ(orientationBin(-M_PI + 1e-9, 4), 0);
  EXPECT_EQ(orientationBin(-M_PI / 2 - 1e-9, 4), 0);
  EXPECT_EQ(orientationBin(-M_PI / 2 + 1e-9, 4), 1);
  EXPECT_EQ(orientationBin(0.0, 4), 2);
  EXPECT_EQ(orientationBin(M_PI / 2, 4), 3);
  EXPECT_EQ(orientationBin(M_PI, 4), 3);   // the closed end
  EXPECT_EQ(orientationBin(-M_PI, 4), 3);  // the same direction as pi
  EXPECT_EQ(orientationBin(M_PI / 4, 8), 5);
}

// A ridge: I(r, c) = 20 min(c, 6 - c), 4 rows x 7 columns. Interior pixels
// (rows 1-2, columns 1-5): Sobel gx = 4 (I(c+1) - I(c-1)) = +160 at columns
// 1, 2 (orientation 0), 0 at column 3 (no gradient: left out), -160 at
// columns 4, 5 (orientation pi); gy = 0. So 4 pixels in the bin of 0 and 4
// in the bin of pi: with k = 4, h = (0, 0, 0.5, 0.5).
TEST(GradientHistogram, RidgeByHand) {
  cv::Mat img(4, 7, CV_8UC1);
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 7; ++c)
      img.at<uint8_t>(r, c) = static_cast<uint8_t>(20 * std::min(c, 6 - c));
  const Histogram h = gradientHistogram(img, {4, 1.0});
  ASSERT_EQ(h.size(), 4u);
  EXPECT_FLOAT_EQ(h[0], 0.f);
  EXPECT_FLOAT_EQ(h[1], 0.f);
  EXPECT_FLOAT_EQ(h[2], 0.5f);
  EXPECT_FLOAT_EQ(h[3], 0.5f);
}

// I(r, c) = 10 r + 10 c: gx = gy = 80 everywhere inside, orientation pi/4,
// magnitude 113: with k = 8 all in bin floor((pi/4 + pi) / (2 pi) 8) = 5; a
// threshold above the magnitude leaves nothing (a blank histogram).
TEST(GradientHistogram, DiagonalRampAndThreshold) {
  cv::Mat img(6, 6, CV_8UC1);
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) img.at<uint8_t>(r, c) = static_cast<uint8_t>(10 * r + 10 * c);
  Histogram h = gradientHistogram(img, {8, 100.0});
  for (int k = 0; k < 8; ++k) EXPECT_FLOAT_EQ(h[static_cast<size_t>(k)], k == 5 ? 1.f : 0.f) << k;
  h = gradientHistogram(img, {8, 120.0});
  for (float v : h) EXPECT_EQ(v, 0.f);
}

// A grid of cells, one histogram each. Two 16 x 7 images, each half a ridge
// (horizontal gradients: orientations 0 and pi) and half a ramp down the
// rows (orientation pi/2), in opposite halves, with a flat row between.
// One histogram over the whole image hardly tells them apart; two bands
// (a 1 x 2 grid) do, as the content of each band differs.
TEST(GradientHistogram, GridCellsKeepWhereTheGradientsAre) {
  const auto image = [](bool ridge_on_top) {
    cv::Mat img(16, 7, CV_8UC1);
    for (int r = 0; r < 16; ++r) {
      const bool ridge = (r < 8) == ridge_on_top;
      const int band_row = r % 8;
      for (int c = 0; c < 7; ++c) {
        img.at<uint8_t>(r, c) = static_cast<uint8_t>(band_row == 0 || band_row == 7 ? 0
                                                     : ridge ? 20 * std::min(c, 6 - c)
                                                             : 20 * band_row);
      }
    }
    return img;
  };
  const HistogramParams one{4, 1.0};
  const HistogramParams bands{4, 1.0, 1, 2};
  ASSERT_EQ(histogramLength(bands), 8);
  const Histogram a = gradientHistogram(image(true), bands);
  ASSERT_EQ(a.size(), 8u);
  double sum = 0;
  for (float v : a) sum += v;
  EXPECT_NEAR(sum, 1.0, 1e-6) << "normalised over the whole image";
  // Top band of `a`: the ridge, bins 2 (orientation 0) and 3 (pi); the
  // bottom band's ramp is all bin 3 (pi/2) but for its flat edges.
  EXPECT_GT(a[2], 0.f);
  EXPECT_GT(a[3], 0.f);
  EXPECT_GT(a[7], a[6]);
  const double d_one =
      chiSquare(gradientHistogram(image(true), one), gradientHistogram(image(false), one));
  const double d_bands = chiSquare(a, gradientHistogram(image(false), bands));
  EXPECT_LT(d_one, 0.05);
  EXPECT_GT(d_bands, 10 * d_one);
  EXPECT_GT(d_bands, 0.5);
  // A grid finer than the image cannot be made.
  EXPECT_THROW(gradientHistogram(image(true), {4, 1.0, 8, 1}), std::invalid_argument);
  EXPECT_THROW(gradientHistogram(image(true), {4, 1.0, 0, 1}), std::invalid_argument);
}

TEST(GradientHistogram, RejectsBadImages) {
  EXPECT_THROW(gradientHistogram(cv::Mat(2, 5, CV_8UC1, cv::Scalar(0)), {}), std::invalid_argument);
  EXPECT_THROW(gradientHistogram(cv::Mat(5, 5, CV_8UC3, cv::Scalar(0)), {}), std::invalid_argument);
}

// chi2 = sum (a - b)^2 / (a + b): (0.25^2 / 0.75) * 2 + 0.5^2 / 0.5 = 2/3;
// the empty fourth bin contributes nothing.
TEST(ChiSquare, ByHand) {
  const Histogram a{0.5f, 0.5f, 0.f, 0.f};
  const Histogram b{0.25f, 0.25f, 0.5f, 0.f};
  EXPECT_NEAR(chiSquare(a, b), 2.0 / 3.0, 1e-7);
  EXPECT_NEAR(chiSquare(b, a), 2.0 / 3.0, 1e-7);
  EXPECT_EQ(chiSquare(a, a), 0.0);
  // Disjoint normalised histograms are the farthest apart: 2.
  EXPECT_NEAR(chiSquare({1.f, 0.f}, {0.f, 1.f}), 2.0, 1e-12);
  EXPECT_THROW(chiSquare(a, {1.f}), std::invalid_argument);
}

// Discrete actions: a 0.97 m move at 0.3 m/s ends when the robot has stood
// still for rest_s; a 92 degree turn ends at 90 degrees; a short creep
// followed by a stop is not an action.
TEST(ActionDetector, MovesTurnsAndStops) {
  ActionParams p;
  ActionDetector d(p);
  int64_t t = 0;
  Pose2 pose;
  d.setReference(t, pose);
  const int64_t dt = 20000;  // 50 Hz
  std::optional<CompletedAction> a;
  for (double x = 0; x < 0.97 - 1e-9 && !a;) {
    x = std::min(0.97, x + 0.3 * 0.02);
    t += dt;
    pose = {x, 0, 0};
    a = d.add(t, pose);
  }
  EXPECT_FALSE(a) << "ended before the robot stopped";
  const int64_t stopped = t;
  while (!a && t < stopped + 2000000) {
    t += dt;
    a = d.add(t, pose);
  }
  ASSERT_TRUE(a);
  EXPECT_NEAR(1e-6 * static_cast<double>(a->utime - stopped), p.rest_s, 0.021);
  EXPECT_NEAR(a->delta.x, 0.97, 1e-9);
  EXPECT_FALSE(d.add(t + dt, pose)) << "one action until the next reference";

  d.setReference(t, pose);
  a.reset();
  double turned = 0;
  while (!a && turned < degToRad(92)) {
    turned += degToRad(45) * 0.02;
    t += dt;
    a = d.add(t, {pose.x, pose.y, turned});
  }
  ASSERT_TRUE(a);
  EXPECT_NEAR(a->delta.theta, degToRad(90), degToRad(0.91));

  d.setReference(t, {pose.x, pose.y, turned});
  for (int i = 0; i < 100; ++i) {
    t += dt;
    EXPECT_FALSE(d.add(t, {pose.x + 0.1, pose.y, turned})) << "a 0.1 m creep is no action";
  }
}
