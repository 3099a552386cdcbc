// Landmark creation (paper 4.1): matching, two-view geometry, the three-view
// bundle adjustment and the whole creation against synthetic ground truth,
// and on rendered simulator views checked against a fourth view.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <random>
#include <set>
#include <vector>

#include "config/robot_config.hpp"
#include "frontend/creation_geometry.hpp"
#include "frontend/features.hpp"
#include "frontend/landmark_creation.hpp"
#include "frontend/landmark_refinement.hpp"
#include "frontend/matching.hpp"
#include "frontend/three_view_ba.hpp"
#include "util/statistics.hpp"
#include "world/renderer.hpp"
#include "world/world.hpp"

namespace vslam::frontend {
namespace {

namespace fs = std::filesystem;
const fs::path kSource = VSLAM_SOURCE_DIR;

constexpr double kDeg = M_PI / 180.0;

// The simulated camera (config/calib/sim_320x240.yml) with a stronger,
// complete OpenCV distortion so that the undistortion path matters.
const cv::Matx33d kK(277.13, 0, 160.0, 0, 277.13, 120.0, 0, 0, 1);
const std::vector<double> kDist = {-0.12, 0.03, 0.001, -0.0015, -0.004};

double angleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

double rotationAngle(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle();
}

Eigen::Isometry3d mount(double yaw, const Eigen::Vector3d& position) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = config::robotRotationCamera(yaw, 0, 0);
  t.translation() = position;
  return t;
}

// Three views of random points 1-5 m in front of camera 1, seen through the
// distorted camera with pixel noise, undistorted by the extractor; a
// fraction of the correspondences replaced by outliers.
struct Scene {
  Eigen::Isometry3d robot_T_camera;
  std::array<Pose2, 3> robot;                  // true robot poses (also the odometry)
  std::vector<Eigen::Vector3d> points_robot1;  // truth, robot frame at view 1
  ThreeViewObservations obs;
  std::vector<int> ids;             // feature_index given to the creator: index in points_robot1
  std::set<int> outliers;           // ids of corrupted correspondences
  std::vector<int> outlier_view;    // per id: the view (1 or 2, 0-based) corrupted, or -1
  Eigen::Isometry3d cam_T_cam1[3];  // truth
};

Scene makeScene(const std::array<Pose2, 3>& robot, const Eigen::Isometry3d& robot_T_camera,
                int num_points, double outlier_fraction, double noise_px, uint32_t seed,
                double min_depth = 1.0, double max_depth = 5.0) {
  Scene s;
  s.robot_T_camera = robot_T_camera;
  s.robot = robot;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, noise_px);
  Eigen::Isometry3d world_T_cam[3];
  for (int k = 0; k < 3; ++k) world_T_cam[k] = isometryFromPose2(robot[k]) * robot_T_camera;
  for (int k = 0; k < 3; ++k) s.cam_T_cam1[k] = world_T_cam[k].inverse() * world_T_cam[0];
  const FeatureExtractor extractor(kK, kDist);
  std::vector<cv::Point2f> pix[3];
  while (static_cast<int>(s.points_robot1.size()) < num_points) {
    const double z = min_depth + (max_depth - min_depth) * u01(rng);
    const Eigen::Vector3d p_cam1((u01(rng) - 0.5) * 1.0 * z, (u01(rng) - 0.5) * 0.74 * z, z);
    cv::Point2d px[3];
    bool inside = true;
    for (int k = 0; k < 3 && inside; ++k) {
      const Eigen::Vector3d q = s.cam_T_cam1[k] * p_cam1;
      std::vector<cv::Point3d> in{{q.x(), q.y(), q.z()}};
      std::vector<cv::Point2d> out;
      cv::projectPoints(in, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), kK, kDist, out);
      px[k] = out[0] + cv::Point2d(noise(rng), noise(rng));
      inside = q.z() > 0.2 && px[k].x >= 0 && px[k].x < 320 && px[k].y >= 0 && px[k].y < 240;
    }
    if (!inside) continue;
    for (int k = 0; k < 3; ++k) pix[k].emplace_back(px[k]);
    s.points_robot1.push_back(robot_T_camera * p_cam1);
  }
  // Outliers: one view's position replaced, half by a random pixel, half by
  // a nearby wrong one (5-30 px away), which epipolar checks alone may miss.
  s.outlier_view.assign(num_points, -1);
  for (int i = 0; i < num_points; ++i) {
    if (u01(rng) >= outlier_fraction) continue;
    const int view = u01(rng) < 0.5 ? 1 : 2;
    if (u01(rng) < 0.5) {
      pix[view][i] =
          cv::Point2f(static_cast<float>(320 * u01(rng)), static_cast<float>(240 * u01(rng)));
    } else {
      const double r = 5 + 25 * u01(rng), a = 2 * M_PI * u01(rng);
      pix[view][i] +=
          cv::Point2f(static_cast<float>(r * std::cos(a)), static_cast<float>(r * std::sin(a)));
    }
    s.outliers.insert(i);
    s.outlier_view[i] = view;
  }
  extractor.undistort(pix[0], &s.obs.x1);
  extractor.undistort(pix[1], &s.obs.x2);
  extractor.undistort(pix[2], &s.obs.x3);
  for (int i = 0; i < num_points; ++i) s.ids.push_back(i);
  return s;
}

const std::array<Pose2, 3> kForward = {Pose2{1.0, 2.0, 0.3}, Pose2{1.19, 2.06, 0.33},
                                       Pose2{1.375, 2.13, 0.37}};

// Checks a created landmark against the scene's truth.
void expectMatchesTruth(const Scene& s, const CreationResult& r, double max_rot_deg = 0.5,
                        double max_dir_deg = 2.0, double max_scale_error = 0.02,
                        double max_median_relative_error = 0.02) {
  ASSERT_TRUE(r.ok()) << toString(r.status) << ": " << r.reason;
  const Eigen::Isometry3d robot1_T_cam[3] = {s.robot_T_camera,
                                             s.robot_T_camera * s.cam_T_cam1[1].inverse(),
                                             s.robot_T_camera * s.cam_T_cam1[2].inverse()};
  const Eigen::Isometry3d est[3] = {s.robot_T_camera, r.landmark.robot1_T_camera2,
                                    r.landmark.robot1_T_camera3};
  for (int k = 1; k < 3; ++k) {
    EXPECT_LT(rotationAngle(est[k].linear(), robot1_T_cam[k].linear()) / kDeg, max_rot_deg)
        << "view " << k + 1;
    const Eigen::Vector3d true_move =
        robot1_T_cam[k].translation() - s.robot_T_camera.translation();
    const Eigen::Vector3d est_move = est[k].translation() - s.robot_T_camera.translation();
    EXPECT_LT(angleBetween(true_move, est_move) / kDeg, max_dir_deg) << "view " << k + 1;
    EXPECT_NEAR(est_move.norm() / true_move.norm(), 1.0, max_scale_error) << "view " << k + 1;
  }
  std::vector<double> rel;
  int within_sigma = 0;
  for (size_t j = 0; j < r.landmark.points_robot.size(); ++j) {
    const int id = r.landmark.feature_index[j];
    const Eigen::Vector3d truth = s.points_robot1[id];
    const double range = (truth - s.robot_T_camera.translation()).norm();
    const double error = (r.landmark.points_robot[j] - truth).norm();
    rel.push_back(error / range);
    // The stated uncertainty is honest: 3 sigma plus the shared scale error.
    within_sigma += error <= 3 * r.landmark.range_sigma_m[j] + max_scale_error * range;
  }
  std::sort(rel.begin(), rel.end());
  ASSERT_FALSE(rel.empty());
  EXPECT_LT(rel[rel.size() / 2], max_median_relative_error);
  EXPECT_GE(within_sigma, static_cast<int>(rel.size() * 9 / 10));
}

// ---------------------------------------------------------------- features

// The extractor's undistortion inverts OpenCV's full lens model (k1 k2 p1
// p2 k3) to far below a pixel, across the image including the corners.
TEST(FeatureExtractor, UndistortInvertsOpenCvProjection) {
  const FeatureExtractor extractor(kK, kDist);
  std::vector<cv::Point3d> rays;
  for (double y = -0.45; y <= 0.45; y += 0.05)
    for (double x = -0.6; x <= 0.6; x += 0.05) rays.emplace_back(x, y, 1.0);
  std::vector<cv::Point2d> px;
  cv::projectPoints(rays, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), kK, kDist, px);
  std::vector<cv::Point2f> pxf(px.begin(), px.end());
  std::vector<Eigen::Vector2d> normalized;
  extractor.undistort(pxf, &normalized);
  ASSERT_EQ(normalized.size(), rays.size());
  double worst = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    // Float pixels carry ~1e-5 px of rounding: compare at 1e-3 px.
    worst =
        std::max(worst, 277.13 * (normalized[i] - Eigen::Vector2d(rays[i].x, rays[i].y)).norm());
  }
  EXPECT_LT(worst, 1e-3);
  EXPECT_THROW(FeatureExtractor(kK, {0.1, 0.2, 0.3}), std::invalid_argument);
}

// Without the doubled first octave (SiftParams::double_first_octave false)
// SIFT runs on the halved image and its keypoints are mapped back: blobs at
// known sub-pixel positions are found where they are, at the scale the
// doubled octave gives them, in both modes (a wrong mapping, say 2c + 0.5
// instead of 2c, misplaces every keypoint by half a pixel).
TEST(FeatureExtractor, WithoutTheDoubledOctaveKeypointsStayOnTheImagesPixels) {
  cv::Mat image(240, 320, CV_8UC1, cv::Scalar(30));
  std::vector<cv::Point2d> blobs;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 6; ++c) blobs.emplace_back(30.3 + 52.0 * c + 0.1 * r, 33.7 + 55.0 * r);
  const double sigma = 4.0;
  for (int y = 0; y < image.rows; ++y) {
    for (int x = 0; x < image.cols; ++x) {
      double v = 30;
      for (const auto& b : blobs)
        v += 200 * std::exp(-((x - b.x) * (x - b.x) + (y - b.y) * (y - b.y)) / (2 * sigma * sigma));
      image.at<uint8_t>(y, x) = cv::saturate_cast<uint8_t>(v);
    }
  }
  Features doubled, own;
  FeatureExtractor(kK, kDist).extract(image, &doubled);
  SiftParams halved;
  halved.double_first_octave = false;
  FeatureExtractor(kK, kDist, halved).extract(image, &own);
  const auto nearest = [](const Features& f, const cv::Point2d& p) {
    const cv::KeyPoint* best = nullptr;
    for (const auto& k : f.keypoints)
      if (!best || cv::norm(cv::Point2d(k.pt) - p) < cv::norm(cv::Point2d(best->pt) - p)) best = &k;
    return best;
  };
  for (const auto& b : blobs) {
    const cv::KeyPoint* d = nearest(doubled, b);
    const cv::KeyPoint* o = nearest(own, b);
    ASSERT_TRUE(d && o);
    // OpenCV 4.6's doubled octave: a quarter pixel right and down.
    EXPECT_LT(cv::norm(cv::Point2d(d->pt) - b - cv::Point2d(0.25, 0.25)), 0.1) << b << d->pt;
    EXPECT_LT(cv::norm(cv::Point2d(o->pt) - b), 0.1) << b << o->pt;
    EXPECT_NEAR(o->size / d->size, 1.0, 0.15) << b;
  }
  ASSERT_EQ(own.normalized.size(), own.keypoints.size());
  EXPECT_EQ(own.descriptors.rows, static_cast<int>(own.keypoints.size()));
}

// ---------------------------------------------------------------- matching

cv::Mat randomDescriptors(int rows, std::mt19937* rng) {
  cv::Mat d(rows, 128, CV_32F);
  std::uniform_real_distribution<float> u(0.0f, 60.0f);
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < 128; ++j) d.at<float>(i, j) = std::floor(u(*rng));
  return d;
}

// Same neighbours and ratio decisions as OpenCV's brute force knnMatch (k =
// 2, L2) with the ratio test, on descriptors where a third of the queries
// have a noisy copy in the train set.
TEST(RatioMatcher, AgreesWithBruteForceKnn) {
  std::mt19937 rng(7);
  const cv::Mat train = randomDescriptors(400, &rng);
  cv::Mat query = randomDescriptors(300, &rng);
  std::normal_distribution<float> noise(0.0f, 6.0f);
  for (int i = 0; i < 100; ++i) {
    train.row(3 * i + 1).copyTo(query.row(i));
    for (int j = 0; j < 128; ++j) query.at<float>(i, j) += std::round(noise(rng));
  }
  for (bool mutual : {false, true}) {
    MatchParams params;
    params.mutual = mutual;
    RatioMatcher matcher(params);
    std::vector<cv::DMatch> ours;
    matcher.match(query, train, &ours);

    cv::BFMatcher bf(cv::NORM_L2);
    std::vector<std::vector<cv::DMatch>> knn;
    bf.knnMatch(query, train, knn, 2);
    std::vector<cv::DMatch> back;
    bf.match(train, query, back);  // train -> nearest query
    std::vector<std::pair<int, int>> expected, got;
    for (const auto& k : knn) {
      if (k.size() == 2 && k[0].distance < 0.8f * k[1].distance &&
          (!mutual || back[k[0].trainIdx].trainIdx == k[0].queryIdx))
        expected.emplace_back(k[0].queryIdx, k[0].trainIdx);
    }
    for (const auto& m : ours) got.emplace_back(m.queryIdx, m.trainIdx);
    EXPECT_EQ(got, expected) << "mutual " << mutual;
    EXPECT_GE(got.size(), 95u);  // the noisy copies are found
    for (const auto& m : ours) EXPECT_EQ(m.trainIdx, 3 * m.queryIdx + 1);
  }
  // Fewer than two train descriptors: no ratio test, no match.
  RatioMatcher matcher;
  std::vector<cv::DMatch> none;
  matcher.match(query, train.rowRange(0, 1), &none);
  EXPECT_TRUE(none.empty());
}

TEST(ThreeWayMatches, KeepsOnlyConsistentTriplets) {
  // 0: consistent (0,10,20). 1: 2-3 maps its view-2 feature elsewhere.
  // 2: no 1-3 match. 3: no 2-3 match. 4 and 5: consistent but share the
  // same view-3 feature through different view-2 features (ambiguous).
  const std::vector<cv::DMatch> m12 = {{0, 10, 1.f}, {1, 11, 1.f}, {2, 12, 1.f},
                                       {3, 13, 1.f}, {4, 14, 1.f}, {5, 15, 1.f}};
  const std::vector<cv::DMatch> m13 = {
      {0, 20, 1.f}, {1, 21, 1.f}, {3, 23, 1.f}, {4, 24, 1.f}, {5, 24, 1.f}};
  const std::vector<cv::DMatch> m23 = {
      {10, 20, 1.f}, {11, 29, 1.f}, {12, 22, 1.f}, {14, 24, 1.f}, {15, 24, 1.f}};
  std::vector<Triplet> t;
  threeWayMatches(m12, m13, m23, &t);
  ASSERT_EQ(t.size(), 1u);
  EXPECT_EQ(t[0].i1, 0);
  EXPECT_EQ(t[0].i2, 10);
  EXPECT_EQ(t[0].i3, 20);
}

// ---------------------------------------------------------------- geometry

TEST(TwoView, RecoversMotionDespiteOutliers) {
  const Scene s = makeScene(kForward, mount(0, {0.1, 0, 0.3}), 150, 0.2, 0.5, 11);
  TwoViewParams params;
  params.threshold = 1.5 / 277.13;
  for (int k : {1, 2}) {
    TwoViewResult r;
    ASSERT_TRUE(estimateTwoView(s.obs.x1, k == 1 ? s.obs.x2 : s.obs.x3, params, &r));
    EXPECT_LT(rotationAngle(r.cam2_T_cam1.linear(), s.cam_T_cam1[k].linear()) / kDeg, 0.5);
    EXPECT_LT(angleBetween(r.cam2_T_cam1.translation(), s.cam_T_cam1[k].translation()) / kDeg, 3.0);
    EXPECT_NEAR(r.cam2_T_cam1.translation().norm(), 1.0, 1e-9);
    // Outliers in this view are out, except the few displaced along their
    // epipolar line (two views cannot tell those); true points stay in.
    int outliers = 0, outliers_in = 0, good = 0, good_in = 0;
    for (size_t i = 0; i < r.inliers.size(); ++i) {
      if (s.outlier_view[i] == k) {
        ++outliers;
        outliers_in += r.inliers[i];
      } else if (!s.outliers.count(static_cast<int>(i))) {
        ++good;
        good_in += r.inliers[i];
      }
    }
    EXPECT_GT(outliers, 8);
    EXPECT_LE(outliers_in, outliers / 4) << "view 1-" << k + 1;
    EXPECT_GE(good_in, good * 9 / 10) << "view 1-" << k + 1;
  }
}

// A pure rotation leaves no parallax; 20 cm forward leaves several pixels.
TEST(TwoView, RotationOnlyResidualSeparatesRotationFromTranslation) {
  const std::array<Pose2, 3> spin = {Pose2{0, 0, 0}, Pose2{0, 0, 0.05}, Pose2{0, 0, 0.1}};
  const Scene rot = makeScene(spin, mount(0, {0, 0, 0.3}), 100, 0.0, 0.5, 3);
  const Scene fwd = makeScene(kForward, mount(0, {0.1, 0, 0.3}), 100, 0.0, 0.5, 3);
  // Noise alone: 0.5 px in each view, 2-D difference median ~0.83 px.
  EXPECT_LT(277.13 * medianRotationOnlyResidual(rot.obs.x1, rot.obs.x3), 1.0);
  EXPECT_GT(277.13 * medianRotationOnlyResidual(fwd.obs.x1, fwd.obs.x3), 3.0);
}

// The range std from the Jacobian matches the spread of triangulated ranges
// under simulated pixel noise (Monte Carlo, cameras fixed).
TEST(Geometry, RangeSigmaMatchesMonteCarlo) {
  const Eigen::Isometry3d cams[3] = {Eigen::Isometry3d::Identity(),
                                     Eigen::Isometry3d(Eigen::Translation3d(0, 0, -0.2)),
                                     Eigen::Isometry3d(Eigen::Translation3d(0.01, 0, -0.4))};
  const double f = 277.13, sigma_px = 0.5;
  for (const Eigen::Vector3d& p :
       {Eigen::Vector3d(0.8, 0.3, 2.5), Eigen::Vector3d(-1.0, 0.5, 4.0)}) {
    const double predicted = rangeSigma(p, cams, 3, f, sigma_px);
    std::mt19937 rng(5);
    std::normal_distribution<double> noise(0.0, sigma_px / f);
    double sum = 0, sum2 = 0;
    const int trials = 4000;
    for (int t = 0; t < trials; ++t) {
      Eigen::Vector2d x[3];
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d q = cams[k] * p;
        x[k] = q.head<2>() / q.z() + Eigen::Vector2d(noise(rng), noise(rng));
      }
      Eigen::Vector3d est;
      ASSERT_TRUE(triangulateDlt(cams, x, 3, &est));
      const double range = est.norm();
      sum += range;
      sum2 += range * range;
    }
    const double mean = sum / trials;
    const double empirical = std::sqrt(sum2 / trials - mean * mean);
    EXPECT_NEAR(predicted / empirical, 1.0, 0.15) << "point " << p.transpose();
    EXPECT_GT(predicted, 0.01);  // not trivially small at this geometry
  }
}

// ---------------------------------------------------------------- bundle adjustment

// From a perturbed start (poses off by ~2 degrees and 20% in relative scale,
// points by 10%), the BA reaches the noise level, drops the injected
// outliers and keeps |t2| = 1.
TEST(ThreeViewBa, ReducesReprojectionErrorAndRejectsOutliers) {
  const Scene s = makeScene(kForward, mount(0, {0.1, 0, 0.3}), 120, 0.15, 0.5, 21);
  const double f = 277.13;
  const double unit = s.cam_T_cam1[1].translation().norm();
  ThreeViewModel model;
  model.cam2_T_cam1 = s.cam_T_cam1[1];
  model.cam3_T_cam1 = s.cam_T_cam1[2];
  model.cam2_T_cam1.linear() =
      Eigen::AngleAxisd(2 * kDeg, Eigen::Vector3d::UnitY()) * model.cam2_T_cam1.linear();
  model.cam3_T_cam1.linear() =
      Eigen::AngleAxisd(-2 * kDeg, Eigen::Vector3d::UnitX()) * model.cam3_T_cam1.linear();
  model.cam3_T_cam1.translation() *= 1.2;
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> jitter(0.9, 1.1);
  for (const auto& pr : s.points_robot1)
    model.points.push_back(jitter(rng) * (s.robot_T_camera.inverse() * pr));
  std::vector<uint8_t> active(s.obs.size(), 1);
  const ThreeViewBaReport rep = threeViewBundleAdjust(s.obs, f, {}, &model, &active);
  ASSERT_TRUE(rep.converged) << rep.message;
  EXPECT_GT(rep.initial_rms_px, 10.0);
  // Noise 0.5 px per coordinate: RMS of 2-D errors ~0.7 px before the fit
  // absorbs some of it.
  EXPECT_LT(rep.final_rms_px, 0.8);
  EXPECT_GT(rep.final_rms_px, 0.3);
  EXPECT_NEAR(rep.robust_sigma_px, 0.45, 0.15);
  EXPECT_GE(rep.rounds, 2);
  EXPECT_NEAR(model.cam2_T_cam1.translation().norm(), 1.0, 1e-9);
  for (int i : s.outliers) EXPECT_FALSE(active[i]) << "outlier " << i << " kept";
  int inliers_lost = 0;
  for (size_t i = 0; i < active.size(); ++i) inliers_lost += !active[i] && !s.outliers.count(i);
  EXPECT_LE(inliers_lost, 3);
  // Motion and structure in units of |t12|.
  EXPECT_LT(rotationAngle(model.cam3_T_cam1.linear(), s.cam_T_cam1[2].linear()) / kDeg, 0.3);
  EXPECT_NEAR(model.cam3_T_cam1.translation().norm(), s.cam_T_cam1[2].translation().norm() / unit,
              0.03 * s.cam_T_cam1[2].translation().norm() / unit);
}

// ---------------------------------------------------------------- creation

TEST(LandmarkCreation, RecoversMotionScaleAndStructureWithOutliers) {
  for (uint32_t seed : {1u, 2u, 3u}) {
    SCOPED_TRACE(seed);
    const Scene s = makeScene(kForward, mount(0, {0.1, 0, 0.3}), 200, 0.2, 0.5, seed);
    LandmarkCreator creator(277.13, s.robot_T_camera);
    const CreationResult r = creator.createFromCorrespondences(s.obs, s.ids, s.robot);
    expectMatchesTruth(s, r);
    for (int id : r.landmark.feature_index) EXPECT_FALSE(s.outliers.count(id)) << "outlier " << id;
    EXPECT_GE(static_cast<int>(r.landmark.points_robot.size()), 30);
    EXPECT_LT(r.landmark.rms_reprojection_px, 0.9);
    EXPECT_EQ(r.landmark.num_three_way, 200);
    EXPECT_NEAR(r.diagnostics.baseline_ratio_agreement, 1.0, 0.03);
    // Every kept point passes the depth-uncertainty rule.
    for (size_t j = 0; j < r.landmark.points_robot.size(); ++j) {
      EXPECT_LE(r.landmark.range_sigma_m[j], 0.10);
      EXPECT_GT(r.landmark.range_sigma_m[j], 0.0);
    }
    EXPECT_GT(r.diagnostics.num_uncertain, 0);  // far points near the focus of expansion
  }
}

// Views not equally spaced (robot slowed down): the relative scale from the
// depth ratios and the metric scale from both baselines still hold.
TEST(LandmarkCreation, UnequalSpacing) {
  const std::array<Pose2, 3> poses = {Pose2{0, 0, 0}, Pose2{0.08, 0.0, 0.02},
                                      Pose2{0.33, 0.02, 0.06}};
  const Scene s = makeScene(poses, mount(0, {0.1, 0, 0.3}), 150, 0.2, 0.5, 9);
  LandmarkCreator creator(277.13, s.robot_T_camera);
  const CreationResult r = creator.createFromCorrespondences(s.obs, s.ids, s.robot);
  // Views 1-2 only 8 cm apart: direction of t12 and structure a little
  // looser (3 degrees, median 3% of range); the scale still within 2%.
  expectMatchesTruth(s, r, 0.5, 3.0, 0.02, 0.03);
  const double true_ratio =
      s.cam_T_cam1[2].translation().norm() / s.cam_T_cam1[1].translation().norm();
  EXPECT_NEAR(r.diagnostics.relative_scale / true_ratio, 1.0, 0.1);
}

// A backward camera (yaw 180) mounted off-centre: points come out behind
// the robot, in the robot frame, matching the truth.
TEST(LandmarkCreation, BackwardCameraResultInRobotFrame) {
  const Eigen::Isometry3d back = mount(M_PI, {-0.15, 0.05, 0.25});
  const Scene s = makeScene(kForward, back, 150, 0.2, 0.5, 4);
  LandmarkCreator creator(277.13, back);
  const CreationResult r = creator.createFromCorrespondences(s.obs, s.ids, s.robot);
  expectMatchesTruth(s, r);
  for (const auto& p : r.landmark.points_robot) EXPECT_LT(p.x(), -0.9);
}

// Noisy odometry distances move the metric scale by the same fraction, not
// the shape: a 5% longer odometry gives a 5% larger landmark.
TEST(LandmarkCreation, MetricScaleFollowsOdometry) {
  const Scene s = makeScene(kForward, mount(0, {0.1, 0, 0.3}), 150, 0.0, 0.5, 8);
  LandmarkCreator creator(277.13, s.robot_T_camera);
  const CreationResult a = creator.createFromCorrespondences(s.obs, s.ids, s.robot);
  std::array<Pose2, 3> longer = s.robot;
  for (int k = 1; k < 3; ++k) {
    longer[k].x = s.robot[0].x + 1.05 * (s.robot[k].x - s.robot[0].x);
    longer[k].y = s.robot[0].y + 1.05 * (s.robot[k].y - s.robot[0].y);
  }
  const CreationResult b = creator.createFromCorrespondences(s.obs, s.ids, longer);
  ASSERT_TRUE(a.ok() && b.ok()) << a.reason << b.reason;
  // Camera baseline (the camera is off-centre, so not exactly 5%).
  EXPECT_NEAR(b.diagnostics.metric_scale / a.diagnostics.metric_scale, 1.05, 0.01);
}

TEST(LandmarkCreation, PureRotationIsDegenerate) {
  const std::array<Pose2, 3> spin = {Pose2{0, 0, 0}, Pose2{0, 0, 0.05}, Pose2{0, 0, 0.1}};
  const Scene s = makeScene(spin, mount(0, {0, 0, 0.3}), 150, 0.1, 0.5, 5);
  LandmarkCreator creator(277.13, s.robot_T_camera);
  // Odometry that claims 20 cm steps (wheels slipping): the images decide.
  const std::array<Pose2, 3> slipping = {Pose2{0, 0, 0}, Pose2{0.2, 0, 0.05}, Pose2{0.4, 0, 0.1}};
  const CreationResult r = creator.createFromCorrespondences(s.obs, s.ids, slipping);
  EXPECT_EQ(r.status, CreationStatus::kDegenerateMotion);
  EXPECT_NE(r.reason.find("parallax"), std::string::npos) << r.reason;
  // Odometry that says the robot stood still: no metric scale possible.
  const std::array<Pose2, 3> still = {Pose2{0, 0, 0}, Pose2{0, 0, 0}, Pose2{0, 0, 0}};
  const CreationResult q = creator.createFromCorrespondences(s.obs, s.ids, still);
  EXPECT_EQ(q.status, CreationStatus::kDegenerateMotion);
  EXPECT_NE(q.reason.find("odometry"), std::string::npos) << q.reason;
}

TEST(LandmarkCreation, TooFewMatches) {
  const Scene s = makeScene(kForward, mount(0, {0.1, 0, 0.3}), 12, 0.0, 0.5, 6);
  LandmarkCreator creator(277.13, s.robot_T_camera);
  const CreationResult r = creator.createFromCorrespondences(s.obs, s.ids, s.robot);
  EXPECT_EQ(r.status, CreationStatus::kTooFewMatches);
  EXPECT_FALSE(r.reason.empty());
  // Three views of unrelated descriptors: nothing consistent to build on.
  std::mt19937 rng(1);
  Features f[3];
  for (auto& v : f) {
    v.descriptors = randomDescriptors(300, &rng);
    v.keypoints.resize(300);
    v.normalized.assign(300, Eigen::Vector2d::Zero());
  }
  const CreationResult q = creator.create(f[0], f[1], f[2], s.robot);
  EXPECT_EQ(q.status, CreationStatus::kTooFewMatches);
  EXPECT_LT(q.diagnostics.num_three_way, 20);
}

// Points 12-30 m away with a 20 cm baseline: too little parallax. With the
// parallax check it is degenerate motion; without it, the bundle adjustment
// runs but no point's depth is certain enough.
TEST(LandmarkCreation, FarSceneIsDegenerateOrHasTooFewGoodPoints) {
  const Scene s = makeScene(kForward, mount(0, {0.1, 0, 0.3}), 150, 0.0, 0.5, 12, 12.0, 30.0);
  LandmarkCreator creator(277.13, s.robot_T_camera);
  const CreationResult r = creator.createFromCorrespondences(s.obs, s.ids, s.robot);
  EXPECT_EQ(r.status, CreationStatus::kDegenerateMotion) << r.reason;
  CreationParams params;
  params.min_parallax_px = 0.0;
  LandmarkCreator unchecked(277.13, s.robot_T_camera, params);
  const CreationResult q = unchecked.createFromCorrespondences(s.obs, s.ids, s.robot);
  EXPECT_EQ(q.status, CreationStatus::kTooFewGoodPoints) << toString(q.status) << ": " << q.reason;
  EXPECT_GT(q.diagnostics.num_uncertain, 100);
}

TEST(LandmarkCreation, ParamsValidate) {
  CreationParams p;
  EXPECT_NO_THROW(p.validate());
  p.min_three_way = 2;
  EXPECT_THROW(p.validate(), std::invalid_argument);
  p = {};
  p.ba.outlier_sigmas = 0;
  EXPECT_THROW(LandmarkCreator(277.0, Eigen::Isometry3d::Identity(), p), std::invalid_argument);
}

// ---------------------------------------------------------------- refinement

// Median over a landmark's points of |estimate - truth| / range and of the
// range ratio (estimate / truth), both from the view-1 camera.
std::pair<double, double> pointErrors(const Scene& s, const CreatedLandmark& lm) {
  std::vector<double> relative, ratio;
  const Eigen::Vector3d c = s.robot_T_camera.translation();
  for (size_t j = 0; j < lm.points_robot.size(); ++j) {
    const Eigen::Vector3d truth = s.points_robot1[lm.feature_index[j]];
    relative.push_back((lm.points_robot[j] - truth).norm() / (truth - c).norm());
    ratio.push_back((lm.points_robot[j] - c).norm() / (truth - c).norm());
  }
  return {median(relative), median(ratio)};
}

// Later views of the landmark's points from the given robot poses (view 1 at
// the origin), 0.5 px noise; the first `corrupt` observations of the last
// view are replaced by random pixels.
std::vector<LaterView> laterViews(const Scene& s, const CreatedLandmark& lm,
                                  const std::vector<Pose2>& poses, int corrupt, uint32_t seed) {
  const FeatureExtractor extractor(kK, kDist);
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 0.5);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::vector<LaterView> views;
  for (size_t k = 0; k < poses.size(); ++k) {
    const Eigen::Isometry3d robot1_T_robot = isometryFromPose2(poses[k]);
    const Eigen::Isometry3d cam_T_robot1 = (robot1_T_robot * s.robot_T_camera).inverse();
    LaterView v;
    v.odometry = poses[k];
    // Vision's guess: the truth 2 cm and half a degree off.
    v.robot1_T_robot =
        isometryFromPose2(Pose2{poses[k].x + 0.02, poses[k].y - 0.01, poses[k].theta + 0.5 * kDeg});
    std::vector<cv::Point2f> pixels;
    for (size_t j = 0; j < lm.points_robot.size(); ++j) {
      const Eigen::Vector3d q = cam_T_robot1 * s.points_robot1[lm.feature_index[j]];
      if (q.z() < 0.2) continue;
      std::vector<cv::Point3d> in{{q.x(), q.y(), q.z()}};
      std::vector<cv::Point2d> out;
      cv::projectPoints(in, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), kK, kDist, out);
      cv::Point2d px = out[0] + cv::Point2d(noise(rng), noise(rng));
      if (px.x < 0 || px.x >= 320 || px.y < 0 || px.y >= 240) continue;
      if (k + 1 == poses.size() && static_cast<int>(v.points.size()) < corrupt)
        px = cv::Point2d(320 * u01(rng), 240 * u01(rng));
      pixels.emplace_back(px);
      v.points.push_back(static_cast<int>(j));
    }
    extractor.undistort(pixels, &v.observations);
    views.push_back(std::move(v));
  }
  return views;
}

// A creation whose 40 cm of odometry was 8% long makes a landmark 8% too
// large; three later views out to 1 m with their (true) odometry bring the
// scale within 2.5% and the points nearer the truth, and the corrupted
// observations of the last view are dropped.
TEST(LandmarkRefinement, LaterViewsCorrectTheScaleAndTheStructure) {
  const std::array<Pose2, 3> poses = {Pose2{0, 0, 0}, Pose2{0.2, 0.0, 0.01},
                                      Pose2{0.4, 0.01, 0.02}};
  const Eigen::Isometry3d robot_T_camera = mount(0, {0.1, 0, 0.3});
  for (uint32_t seed : {5u, 6u, 7u}) {
    SCOPED_TRACE(seed);
    const Scene s = makeScene(poses, robot_T_camera, 300, 0.0, 0.5, seed, 1.5, 4.5);
    std::array<Pose2, 3> odometry = poses;
    for (int k = 1; k < 3; ++k) {
      odometry[k].x *= 1.08;
      odometry[k].y *= 1.08;
    }
    LandmarkCreator creator(277.13, robot_T_camera);
    CreationResult r = creator.createFromCorrespondences(s.obs, s.ids, odometry);
    ASSERT_TRUE(r.ok()) << r.reason;
    const auto [error_before, ratio_before] = pointErrors(s, r.landmark);
    EXPECT_NEAR(ratio_before, 1.08, 0.02);  // the creation's scale follows its odometry

    const std::vector<LaterView> later = laterViews(
        s, r.landmark, {Pose2{0.6, 0.02, 0.03}, Pose2{0.8, 0.03, 0.03}, Pose2{1.0, 0.03, 0.04}}, 6,
        seed);
    CreatedLandmark refined = r.landmark;
    const RefinementReport report =
        refineLandmark(odometry, later, 277.13, robot_T_camera, RefinementParams{}, &refined);
    ASSERT_TRUE(report.refined) << report.reason;
    EXPECT_EQ(report.later_views, 3);
    EXPECT_NEAR(report.span_m, 1.0, 0.01);
    EXPECT_GE(report.rejected_observations, 5);
    EXPECT_LT(report.rms_after_px, 0.9);
    const auto [error_after, ratio_after] = pointErrors(s, refined);
    EXPECT_NEAR(ratio_after, 1.0, 0.025);
    EXPECT_NEAR(report.scale_change * ratio_before, ratio_after, 0.01);
    EXPECT_LT(error_after, 0.5 * error_before);
    // The views' cameras moved with the scale: view 3's about 40 cm ahead.
    EXPECT_NEAR((refined.robot1_T_camera3.translation() - robot_T_camera.translation()).norm(),
                0.40, 0.015);
  }
}

// With nothing seen far enough away, the landmark is left exactly as made.
TEST(LandmarkRefinement, WithoutDistantViewsTheLandmarkIsLeftAsMade) {
  const std::array<Pose2, 3> poses = {Pose2{0, 0, 0}, Pose2{0.2, 0.0, 0.01},
                                      Pose2{0.4, 0.01, 0.02}};
  const Eigen::Isometry3d robot_T_camera = mount(0, {0.1, 0, 0.3});
  const Scene s = makeScene(poses, robot_T_camera, 300, 0.0, 0.5, 8, 1.5, 4.5);
  LandmarkCreator creator(277.13, robot_T_camera);
  const CreationResult r = creator.createFromCorrespondences(s.obs, s.ids, poses);
  ASSERT_TRUE(r.ok()) << r.reason;
  CreatedLandmark lm = r.landmark;
  RefinementReport report =
      refineLandmark(poses, {}, 277.13, robot_T_camera, RefinementParams{}, &lm);
  EXPECT_FALSE(report.refined);
  EXPECT_EQ(report.reason, "no later view saw enough of its points");
  const std::vector<LaterView> near = laterViews(s, lm, {Pose2{0.45, 0.01, 0.02}}, 0, 8);
  RefinementParams params;
  params.min_span_m = 0.5;
  report = refineLandmark(poses, near, 277.13, robot_T_camera, params, &lm);
  EXPECT_FALSE(report.refined);
  EXPECT_EQ(report.reason, "the later views are too near the first");
  for (size_t j = 0; j < lm.points_robot.size(); ++j)
    EXPECT_EQ(lm.points_robot[j], r.landmark.points_robot[j]);
  RefinementParams bad;
  bad.odometry_sigma_floor_m = 0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

// ---------------------------------------------------------------- rendered views

// Real pixels: three views rendered 20 cm apart driving forward from the
// apartment's start, SIFT + creation with the true odometry; then a fourth
// view 40 cm past the third. Each created point, moved to the world with
// the view-1 pose and projected (with distortion) into view 4, must land
// where SIFT finds its view-1 feature again: the metric structure predicts
// an unseen view.
TEST(LandmarkCreationRendered, PointsPredictAFourthView) {
  // The apartment's start faces furniture 1.5-4 m away (the living room's
  // faces a wall 5.5 m away: too far for 20 cm baselines, every point's
  // depth std exceeds 10 cm there).
  const world::World w = world::World::loadFile(kSource / "config/worlds/apartment.yaml");
  ASSERT_TRUE(w.has_start);
  const config::CameraIntrinsics in =
      config::readOpenCvCalibration(kSource / "config/calib/sim_320x240.yml");
  world::Renderer renderer(
      w, world::CameraModel{in.width, in.height, in.fx, in.fy, in.cx, in.cy, in.distortion});
  const Eigen::Isometry3d robot_T_camera = mount(0, {0.1, 0, 0.3});
  FeatureExtractor extractor(in);
  const Pose2 start{w.start.x(), w.start.y(), w.start.z()};
  const double along[4] = {0.0, 0.2, 0.4, 0.8};
  Pose2 pose[4];
  Features features[4];
  cv::Mat image;
  for (int k = 0; k < 4; ++k) {
    pose[k] = start.compose(Pose2{along[k], 0.0, 0.0});
    renderer.render(isometryFromPose2(pose[k]) * robot_T_camera, {}, {}, false, image);
    extractor.extract(image, &features[k]);
    ASSERT_GT(features[k].size(), 150u) << "view " << k + 1;
    ASSERT_EQ(features[k].descriptors.rows, static_cast<int>(features[k].size()));
    ASSERT_EQ(features[k].descriptors.cols, 128);
    ASSERT_EQ(features[k].normalized.size(), features[k].size());
  }
  LandmarkCreator creator(0.5 * (in.fx + in.fy), robot_T_camera);
  const CreationResult r =
      creator.create(features[0], features[1], features[2], {pose[0], pose[1], pose[2]});
  const auto& d = r.diagnostics;
  std::printf(
      "features %d %d %d, matches %d %d %d, three-way %d, parallax %.1f %.1f px, inliers %d %d, "
      "BA points %d rejected %d rounds %d rms %.2f -> %.2f px, uncertain %d, kept %zu, "
      "ms: matching %.1f two-view %.1f BA %.1f total %.1f\n",
      d.num_features[0], d.num_features[1], d.num_features[2], d.num_matches_12, d.num_matches_13,
      d.num_matches_23, d.num_three_way, d.parallax_12_px, d.parallax_13_px, d.inliers_12,
      d.inliers_13, d.ba_points, d.ba_rejected, d.ba_rounds, d.ba_initial_rms_px, d.ba_final_rms_px,
      d.num_uncertain, r.landmark.points_robot.size(), d.ms_matching, d.ms_two_view,
      d.ms_bundle_adjustment, d.ms_total);
  ASSERT_TRUE(r.ok()) << toString(r.status) << ": " << r.reason;
  EXPECT_GE(static_cast<int>(r.landmark.points_robot.size()), 30);
  EXPECT_LT(r.landmark.rms_reprojection_px, 1.0);
  // Vision's camera motion agrees with the truth (odometry is exact here).
  for (int k = 1; k < 3; ++k) {
    const Eigen::Isometry3d truth = robot_T_camera.inverse().inverse() *
                                    ((isometryFromPose2(pose[0]) * robot_T_camera).inverse() *
                                     (isometryFromPose2(pose[k]) * robot_T_camera));
    const Eigen::Isometry3d& est =
        k == 1 ? r.landmark.robot1_T_camera2 : r.landmark.robot1_T_camera3;
    EXPECT_LT((est.translation() - truth.translation()).norm(), 0.01) << "view " << k + 1;
    EXPECT_LT(rotationAngle(est.linear(), truth.linear()) / kDeg, 0.5) << "view " << k + 1;
  }

  // Fourth view: find each landmark feature again by descriptor.
  cv::Mat query(static_cast<int>(r.landmark.feature_index.size()), 128, CV_32F);
  for (size_t j = 0; j < r.landmark.feature_index.size(); ++j)
    features[0].descriptors.row(r.landmark.feature_index[j]).copyTo(query.row(static_cast<int>(j)));
  RatioMatcher matcher;
  std::vector<cv::DMatch> matches;
  matcher.match(query, features[3].descriptors, &matches);
  const Eigen::Isometry3d cam4_T_robot1 =
      (isometryFromPose2(pose[3]) * robot_T_camera).inverse() * isometryFromPose2(pose[0]);
  std::vector<double> errors;
  for (const auto& m : matches) {
    const Eigen::Vector3d q = cam4_T_robot1 * r.landmark.points_robot[m.queryIdx];
    if (q.z() <= 0.1) continue;
    std::vector<cv::Point3d> pts{{q.x(), q.y(), q.z()}};
    std::vector<cv::Point2d> px;
    cv::projectPoints(pts, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0),
                      cv::Matx33d(in.fx, 0, in.cx, 0, in.fy, in.cy, 0, 0, 1), in.distortion, px);
    const cv::Point2f seen = features[3].keypoints[m.trainIdx].pt;
    errors.push_back(std::hypot(px[0].x - seen.x, px[0].y - seen.y));
  }
  ASSERT_GE(errors.size(), 15u);
  std::sort(errors.begin(), errors.end());
  const double within =
      static_cast<double>(std::upper_bound(errors.begin(), errors.end(), 2.0) - errors.begin()) /
      static_cast<double>(errors.size());
  std::printf("view 4: %zu points re-found, median error %.2f px, %.0f%% within 2 px\n",
              errors.size(), errors[errors.size() / 2], 100 * within);
  EXPECT_GE(within, 0.8);
  EXPECT_LT(errors[errors.size() / 2], 1.0);
}

}  // namespace
}  // namespace vslam::frontend
