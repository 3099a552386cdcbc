// Recognition against the landmark index with synthetic SIFT-like descriptors
// whose true correspondences are known.
#include <gtest/gtest.h>

#include <random>

#include "frontend/landmark_index.hpp"
#include "support/synthetic_descriptors.hpp"

using namespace vslam::frontend;
using vslam::test::randomDescriptors;

namespace {

// A frame whose features are noisy copies of some landmark points plus distractors.
struct FrameBuilder {
  Features frame;
  std::vector<std::pair<int64_t, int>> truth;  // per feature: (landmark, point) or (-1, -1)
  void add(const cv::Mat& row, int64_t landmark, int point, std::mt19937& rng, float noise) {
    cv::Mat r = row.clone();
    std::normal_distribution<float> n(0.f, noise);
    for (int c = 0; c < 128; ++c) r.at<float>(0, c) = std::max(0.f, r.at<float>(0, c) + n(rng));
    frame.descriptors.push_back(r);
    frame.keypoints.emplace_back(0.f, 0.f, 1.f);
    frame.normalized.emplace_back(0.01 * static_cast<double>(frame.normalized.size()), 0.0);
    truth.emplace_back(landmark, point);
  }
};

LandmarkModel makeLandmark(int64_t id, const cv::Mat& descriptors) {
  LandmarkModel lm;
  lm.id = id;
  lm.descriptors = descriptors;
  for (int i = 0; i < descriptors.rows; ++i) lm.points_robot.emplace_back(id, i, 1.0);
  return lm;
}

}  // namespace

TEST(LandmarkIndex, RecognizesTheLandmarksInTheFrameWithTheRightCorrespondences) {
  std::mt19937 rng(1);
  LandmarkIndex index;
  std::vector<cv::Mat> descriptors;
  for (int64_t id = 0; id < 30; ++id) {
    descriptors.push_back(randomDescriptors(60, rng));
    index.add(makeLandmark(id, descriptors.back()));
  }
  EXPECT_EQ(index.size(), 30u);
  EXPECT_EQ(index.numDescriptors(), 30u * 60u);

  FrameBuilder b;
  for (int i = 0; i < 35; ++i) b.add(descriptors[4].row(i), 4, i, rng, 8.f);
  for (int i = 10; i < 25; ++i) b.add(descriptors[17].row(i), 17, i, rng, 8.f);
  for (int i = 0; i < 5; ++i) b.add(descriptors[22].row(i), 22, i, rng, 8.f);  // too few
  const cv::Mat distractors = randomDescriptors(200, rng);
  for (int i = 0; i < distractors.rows; ++i) b.add(distractors.row(i), -1, -1, rng, 0.f);

  const auto found = index.recognize(b.frame);
  ASSERT_EQ(found.size(), 2u);
  EXPECT_EQ(found[0].landmark_id, 4);  // most matches first
  EXPECT_EQ(found[1].landmark_id, 17);
  for (const Recognition& r : found) {
    ASSERT_EQ(r.points_robot.size(), r.observations.size());
    int correct = 0;
    for (size_t i = 0; i < r.frame_features.size(); ++i) {
      const auto& [lm, point] = b.truth[static_cast<size_t>(r.frame_features[i])];
      // The synthetic point (id, point, 1) encodes which landmark point it is.
      correct += lm == r.landmark_id && r.points_robot[i].y() == point;
      EXPECT_EQ(r.observations[i], b.frame.normalized[static_cast<size_t>(r.frame_features[i])]);
    }
    EXPECT_GE(correct, static_cast<int>(0.95 * static_cast<double>(r.points_robot.size())));
  }
  EXPECT_GE(found[0].points_robot.size(), 33u);  // recall of the 35 true matches
  EXPECT_GE(found[1].points_robot.size(), 14u);
}

TEST(LandmarkIndex, OverlappingLandmarksAreBothRecognized) {
  // Landmark 2 was created where landmark 1 was: 40 of its points are the same
  // physical points (near-identical descriptors). A global ratio test would
  // reject them as ambiguous; matching per landmark keeps both.
  std::mt19937 rng(2);
  const cv::Mat a = randomDescriptors(60, rng);
  cv::Mat b = randomDescriptors(60, rng);
  std::normal_distribution<float> n(0.f, 4.f);
  for (int i = 0; i < 40; ++i) {
    for (int c = 0; c < 128; ++c) b.at<float>(i, c) = std::max(0.f, a.at<float>(i, c) + n(rng));
  }
  LandmarkIndex index;
  index.add(makeLandmark(1, a));
  index.add(makeLandmark(2, b));
  FrameBuilder f;
  for (int i = 0; i < 40; ++i) f.add(a.row(i), 1, i, rng, 8.f);
  const auto found = index.recognize(f.frame);
  ASSERT_EQ(found.size(), 2u);
  EXPECT_GE(found[0].points_robot.size(), 36u);
  EXPECT_GE(found[1].points_robot.size(), 36u);
}

TEST(LandmarkIndex, RemovedAndReplacedLandmarksAreNotRecognized) {
  std::mt19937 rng(3);
  const cv::Mat a = randomDescriptors(50, rng);
  LandmarkIndex index;
  index.add(makeLandmark(7, a));
  FrameBuilder f;
  for (int i = 0; i < 30; ++i) f.add(a.row(i), 7, i, rng, 8.f);
  ASSERT_EQ(index.recognize(f.frame).size(), 1u);
  index.add(makeLandmark(7, randomDescriptors(50, rng)));  // same id, new content
  EXPECT_TRUE(index.recognize(f.frame).empty());
  EXPECT_TRUE(index.remove(7));
  EXPECT_FALSE(index.remove(7));
  EXPECT_TRUE(index.recognize(f.frame).empty());
  EXPECT_EQ(index.size(), 0u);
}

TEST(LandmarkIndex, RejectsInconsistentLandmarks) {
  LandmarkModel lm;
  lm.id = 1;
  lm.points_robot.resize(3);
  lm.descriptors = cv::Mat::zeros(2, 128, CV_32F);
  LandmarkIndex index;
  EXPECT_THROW(index.add(lm), std::invalid_argument);
  EXPECT_THROW(LandmarkIndex(RecognitionParams{1.5}), std::invalid_argument);
}
