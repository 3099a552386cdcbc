// Recognition against the landmark index with synthetic SIFT-like descriptors
// whose true correspondences are known.
#include <gtest/gtest.h>
#include <malloc.h>

#include <algorithm>
#include <limits>
#include <map>
#include <memory>
#include <opencv2/features2d.hpp>
#include <random>
#include <set>
#include <tuple>

#include "frontend/descriptor_distance.hpp"
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
    if (noise > 0) {
      std::normal_distribution<float> n(0.f, noise);
      for (int c = 0; c < 128; ++c) r.at<float>(0, c) = std::max(0.f, r.at<float>(0, c) + n(rng));
    }
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

// ---- scale: vocabulary, inverted file, recall against the exact search ----

namespace {

using vslam::test::SiftLikeGenerator;

// Landmarks of SIFT-like points, and frames seeing some of them, with the
// physical point behind every landmark point and frame feature.
struct SiftLikeWorld {
  explicit SiftLikeWorld(uint32_t seed) : gen(seed) {}
  SiftLikeGenerator gen;
  std::vector<std::vector<SiftLikeGenerator::Patch>> patches;  // per landmark

  LandmarkModel landmark(int64_t id, int n) {
    std::vector<SiftLikeGenerator::Patch> p;
    cv::Mat d(0, 128, CV_32F);
    for (int i = 0; i < n; ++i) {
      p.push_back(gen.patch());
      d.push_back(SiftLikeGenerator::describe(p.back()));
    }
    if (patches.size() <= static_cast<size_t>(id)) patches.resize(static_cast<size_t>(id) + 1);
    patches[static_cast<size_t>(id)] = p;
    return makeLandmark(id, d);
  }
  // A frame seeing `count` points of each landmark in `seen`, plus distractors up to 600.
  FrameBuilder frame(const std::vector<std::pair<int64_t, int>>& seen) {
    FrameBuilder b;
    for (const auto& [id, count] : seen) {
      for (int i = 0; i < count; ++i) {
        const cv::Mat row = SiftLikeGenerator::describe(
            gen.observe(patches[static_cast<size_t>(id)][static_cast<size_t>(i)]));
        b.add(row, id, i, gen.rng(), 0.f);
      }
    }
    const cv::Mat distractors = gen.descriptors(600 - b.frame.descriptors.rows);
    for (int i = 0; i < distractors.rows; ++i) b.add(distractors.row(i), -1, -1, gen.rng(), 0.f);
    return b;
  }
};

// Matches of the exact search between a frame feature and the same physical
// point, and how many of them `found` has.
struct RecallCount {
  int genuine = 0, found = 0;
};
RecallCount genuineRecall(const std::vector<Recognition>& exact,
                          const std::vector<Recognition>& found, const FrameBuilder& b,
                          int min_matches) {
  RecallCount c;
  for (const Recognition& e : exact) {
    std::vector<size_t> genuine;
    for (size_t i = 0; i < e.frame_features.size(); ++i) {
      const auto& [lm, point] = b.truth[static_cast<size_t>(e.frame_features[i])];
      if (lm == e.landmark_id && point == e.landmark_points[i]) genuine.push_back(i);
    }
    if (static_cast<int>(genuine.size()) < min_matches) continue;  // a chance recognition
    const auto it = std::find_if(found.begin(), found.end(), [&](const Recognition& r) {
      return r.landmark_id == e.landmark_id;
    });
    c.genuine += static_cast<int>(genuine.size());
    if (it == found.end()) continue;
    for (size_t i : genuine) {
      for (size_t j = 0; j < it->frame_features.size(); ++j) {
        c.found += it->frame_features[j] == e.frame_features[i] &&
                   it->landmark_points[j] == e.landmark_points[i];
      }
    }
  }
  return c;
}

}  // namespace

TEST(LandmarkIndex, DescriptorsAreHeldAsBytesAndDistancesAreExact) {
  std::mt19937 rng(4);
  cv::Mat f = randomDescriptors(20, rng);
  f.at<float>(0, 0) = 300.f;  // saturates
  f.at<float>(0, 1) = 2.5f;   // rounds (to even, as cv::saturate_cast)
  const cv::Mat u = toDescriptorsU8(f);
  ASSERT_EQ(u.type(), CV_8U);
  EXPECT_EQ(u.at<uint8_t>(0, 0), 255);
  EXPECT_EQ(u.at<uint8_t>(0, 1), 2);
  for (int i = 1; i < u.rows; ++i) {
    cv::Mat a, b;
    u.row(0).convertTo(a, CV_64F);
    u.row(i).convertTo(b, CV_64F);
    EXPECT_EQ(squaredDistanceU8(u.ptr<uint8_t>(0), u.ptr<uint8_t>(i)),
              static_cast<uint32_t>(std::lround(cv::norm(a, b, cv::NORM_L2SQR))));
  }
  // The batched distances (AVX2 where the CPU has it) are the same integers,
  // also at the extremes: all 0 against all 255 is 128 * 255^2.
  cv::Mat extremes(2, kDescriptorBytes, CV_8U);
  extremes.row(0).setTo(0);
  extremes.row(1).setTo(255);
  std::vector<uint32_t> batch(static_cast<size_t>(u.rows));
  squaredDistancesU8(u.ptr<uint8_t>(0), u.ptr<uint8_t>(0), u.rows, batch.data());
  for (int i = 0; i < u.rows; ++i) {
    EXPECT_EQ(batch[static_cast<size_t>(i)],
              squaredDistanceU8(u.ptr<uint8_t>(0), u.ptr<uint8_t>(i)));
  }
  uint32_t extreme = 0;
  squaredDistancesU8(extremes.ptr<uint8_t>(0), extremes.ptr<uint8_t>(1), 1, &extreme);
  EXPECT_EQ(extreme, 128u * 255u * 255u);

  LandmarkIndex index;
  index.add(makeLandmark(3, f));
  ASSERT_NE(index.find(3), nullptr);
  EXPECT_EQ(index.find(3)->descriptors.type(), CV_8U);
  EXPECT_EQ(cv::norm(index.find(3)->descriptors, u, cv::NORM_INF), 0.0);
  EXPECT_THROW(toDescriptorsU8(cv::Mat::zeros(2, 64, CV_32F)), std::invalid_argument);
}

namespace {

// OpenCV's brute-force 2-NN per landmark, then the ratio test against the
// landmark's second-nearest point and the background: the nearest point of
// the (overlap + 1)-th nearest landmark.
std::set<std::tuple<int64_t, int, int>> bruteForceMatches(const LandmarkIndex& index,
                                                          int64_t num_landmarks,
                                                          const Features& frame, size_t overlap) {
  cv::BFMatcher bf(cv::NORM_L2);
  std::vector<std::vector<std::vector<cv::DMatch>>> knn(static_cast<size_t>(num_landmarks));
  for (int64_t id = 0; id < num_landmarks; ++id) {
    cv::Mat train;
    index.find(id)->descriptors.convertTo(train, CV_32F);
    bf.knnMatch(frame.descriptors, train, knn[static_cast<size_t>(id)], 2);
  }
  std::vector<float> background(static_cast<size_t>(frame.descriptors.rows),
                                std::numeric_limits<float>::infinity());
  for (size_t f = 0; f < background.size() && static_cast<size_t>(num_landmarks) > overlap; ++f) {
    std::vector<float> nearest;
    for (const auto& per_landmark : knn) nearest.push_back(per_landmark[f][0].distance);
    std::nth_element(nearest.begin(), nearest.begin() + static_cast<std::ptrdiff_t>(overlap),
                     nearest.end());
    background[f] = nearest[overlap];
  }
  std::set<std::tuple<int64_t, int, int>> out;
  for (int64_t id = 0; id < num_landmarks; ++id) {
    std::map<int, std::pair<int, float>> by_point;  // point -> (feature, distance)
    for (const auto& m : knn[static_cast<size_t>(id)]) {
      if (m.size() < 2) continue;
      const float reference =
          std::min(m[1].distance, background[static_cast<size_t>(m[0].queryIdx)]);
      if (!(m[0].distance < 0.8f * reference)) continue;
      const auto it = by_point.find(m[0].trainIdx);
      if (it == by_point.end() || m[0].distance < it->second.second)
        by_point[m[0].trainIdx] = {m[0].queryIdx, m[0].distance};
    }
    if (by_point.size() < 10) continue;
    for (const auto& [point, fd] : by_point) out.emplace(id, fd.first, point);
  }
  return out;
}

std::set<std::tuple<int64_t, int, int>> matchSet(const std::vector<Recognition>& found) {
  std::set<std::tuple<int64_t, int, int>> out;
  for (const Recognition& r : found) {
    for (size_t i = 0; i < r.frame_features.size(); ++i)
      out.emplace(r.landmark_id, r.frame_features[i], r.landmark_points[i]);
  }
  return out;
}

}  // namespace

TEST(LandmarkIndex, ExactSearchEqualsBruteForceRatioTestWithBackground) {
  // recognizeExact is the reference recall is measured against: check it
  // against OpenCV's brute-force matcher with the same tests.
  SiftLikeWorld w(5);
  LandmarkIndex index;
  for (int64_t id = 0; id < 12; ++id) index.add(w.landmark(id, 40 + static_cast<int>(id)));
  const FrameBuilder b = w.frame({{2, 30}, {7, 18}});
  const auto expected = bruteForceMatches(index, 12, b.frame, 3);
  EXPECT_GT(expected.size(), 40u);
  EXPECT_EQ(matchSet(index.recognizeExact(b.frame)), expected);
}

TEST(LandmarkIndex, ChanceMatchesAreRejectedByTheBackground) {
  // The frame above with the ratio test per landmark only (as if matched
  // against each landmark's image alone): a 40-point landmark the frame does
  // not see collects >= 10 chance matches among 600 features, a recognition
  // that can only give a wrong measurement. The background removes it and
  // keeps every match of the landmarks the frame sees.
  SiftLikeWorld w(5);
  RecognitionParams per_landmark_only;
  per_landmark_only.verify_overlap = 1000;  // more than the landmarks: no background
  LandmarkIndex plain(per_landmark_only), with_background;
  for (int64_t id = 0; id < 12; ++id) {
    const LandmarkModel lm = w.landmark(id, 40 + static_cast<int>(id));
    plain.add(lm);
    with_background.add(lm);
  }
  const FrameBuilder b = w.frame({{2, 30}, {7, 18}});
  const auto ids = [](const std::vector<Recognition>& found) {
    std::set<int64_t> out;
    for (const Recognition& r : found) out.insert(r.landmark_id);
    return out;
  };
  const auto plain_found = plain.recognizeExact(b.frame);
  EXPECT_EQ(bruteForceMatches(plain, 12, b.frame, 1000), matchSet(plain_found));
  EXPECT_GT(ids(plain_found).size(), 2u);  // a chance recognition besides 2 and 7
  const auto found = with_background.recognizeExact(b.frame);
  EXPECT_EQ(ids(found), (std::set<int64_t>{2, 7}));
  // The genuine matches all stay.
  int genuine_plain = 0, genuine = 0;
  for (const auto& [id, feature, point] : matchSet(plain_found))
    genuine_plain += b.truth[static_cast<size_t>(feature)] == std::make_pair(id, point);
  for (const auto& [id, feature, point] : matchSet(found))
    genuine += b.truth[static_cast<size_t>(feature)] == std::make_pair(id, point);
  EXPECT_EQ(genuine, genuine_plain);
  EXPECT_GE(genuine, 45);
}

TEST(LandmarkIndex, RecallAgainstExactSearchOnHundredsOfLandmarks) {
  SiftLikeWorld w(6);
  LandmarkIndex index;
  std::uniform_int_distribution<int> size(30, 70);
  for (int64_t id = 0; id < 400; ++id) index.add(w.landmark(id, size(w.gen.rng())));
  EXPECT_FALSE(index.vocabulary().empty());
  RecallCount total;
  int candidates = 0, returned = 0, extra = 0;
  std::uniform_int_distribution<int64_t> any(0, 399);
  for (int q = 0; q < 10; ++q) {
    const int64_t a = any(w.gen.rng()), b = (a + 1 + any(w.gen.rng()) % 398) % 400;
    const int na = static_cast<int>(index.find(a)->descriptors.rows * 6 / 10);
    const int nb = static_cast<int>(index.find(b)->descriptors.rows * 3 / 10);
    const FrameBuilder f = w.frame({{a, na}, {b, nb}});
    RecognitionStats st;
    const auto found = index.recognize(f.frame, &st);
    EXPECT_FALSE(st.exhaustive);
    candidates += st.candidates;
    const RecallCount c = genuineRecall(index.recognizeExact(f.frame), found, f, 10);
    total.genuine += c.genuine;
    total.found += c.found;
    // What the index returns, the exact search returns too, but for the
    // few matches whose background the candidates set higher than all
    // landmarks do.
    const auto exact = matchSet(index.recognizeExact(f.frame));
    for (const auto& m : matchSet(found)) {
      ++returned;
      extra += exact.count(m) == 0;
    }
  }
  EXPECT_GT(total.genuine, 10 * 20);
  EXPECT_GE(total.found, static_cast<int>(0.95 * total.genuine));
  EXPECT_LE(extra, returned / 50) << extra << " of " << returned;
  EXPECT_LT(candidates, 10 * 48);  // not everything: candidates are selected
}

TEST(LandmarkIndex, IncrementalAddAndRemoveWithoutRetraining) {
  SiftLikeWorld w(7);
  RecognitionParams params;
  params.vocabulary_retrain_growth = 0;  // train once, then only incremental updates
  LandmarkIndex index(params);
  for (int64_t id = 0; id < 60; ++id) index.add(w.landmark(id, 50));
  ASSERT_FALSE(index.vocabulary().empty());
  const size_t trained_on = index.vocabulary().trainingSize();
  const size_t bytes60 = index.memoryBytes();
  // Landmarks added after training are found through the inverted file.
  for (int64_t id = 60; id < 200; ++id) index.add(w.landmark(id, 50));
  EXPECT_EQ(index.vocabulary().trainingSize(), trained_on);
  EXPECT_EQ(index.numDescriptors(), 200u * 50u);
  const FrameBuilder f = w.frame({{150, 35}, {20, 25}});
  RecognitionStats st;
  auto found = index.recognize(f.frame, &st);
  EXPECT_FALSE(st.exhaustive);
  ASSERT_EQ(found.size(), 2u);
  EXPECT_EQ(found[0].landmark_id, 150);
  EXPECT_EQ(found[1].landmark_id, 20);
  // Removed: gone from the inverted file too.
  EXPECT_TRUE(index.remove(150));
  found = index.recognize(f.frame);
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].landmark_id, 20);
  EXPECT_EQ(index.numDescriptors(), 199u * 50u);
  // Replaced under the same id by another place: the old points are gone.
  index.add(w.landmark(20, 50));
  EXPECT_TRUE(index.recognize(f.frame).empty());
  for (int64_t id = 0; id < 200; ++id) index.remove(id);
  EXPECT_EQ(index.size(), 0u);
  EXPECT_EQ(index.numDescriptors(), 0u);
  EXPECT_TRUE(index.recognize(f.frame).empty());
  EXPECT_LT(index.memoryBytes(), bytes60);
}

TEST(LandmarkIndex, VocabularyIsRetrainedAsLandmarksGrow) {
  SiftLikeWorld w(8);
  RecognitionParams params;
  params.vocabulary_min_descriptors = 1000;
  params.vocabulary_retrain_growth = 4;
  LandmarkIndex index(params);
  for (int64_t id = 0; id < 19; ++id) index.add(w.landmark(id, 50));
  EXPECT_TRUE(index.vocabulary().empty());  // 950 descriptors
  index.add(w.landmark(19, 50));
  EXPECT_EQ(index.vocabulary().trainingSize(), 1000u);
  for (int64_t id = 20; id < 79; ++id) index.add(w.landmark(id, 50));
  EXPECT_EQ(index.vocabulary().trainingSize(), 1000u);  // 3,950 < 4 x 1,000
  index.add(w.landmark(79, 50));
  EXPECT_EQ(index.vocabulary().trainingSize(), 4000u);
  EXPECT_GT(index.vocabulary().numWords(), 100u);
}

TEST(LandmarkIndex, AGenericVocabularyWorksToo) {
  // Trained on descriptors of other places (another generator seed).
  SiftLikeWorld generic(9);
  const VocabularyTree v = VocabularyTree::train(toDescriptorsU8(generic.gen.descriptors(20000)));
  SiftLikeWorld w(10);
  LandmarkIndex index;
  index.setVocabulary(v);
  for (int64_t id = 0; id < 300; ++id) index.add(w.landmark(id, 50));
  EXPECT_EQ(index.vocabulary().trainingSize(), 20000u);  // not retrained
  RecallCount total;
  for (int64_t a : {3, 77, 150, 299}) {
    const FrameBuilder f = w.frame({{a, 30}, {(a + 40) % 300, 15}});
    const RecallCount c =
        genuineRecall(index.recognizeExact(f.frame), index.recognize(f.frame), f, 10);
    total.genuine += c.genuine;
    total.found += c.found;
  }
  EXPECT_GT(total.genuine, 4 * 30);
  EXPECT_GE(total.found, static_cast<int>(0.95 * total.genuine));
}

TEST(LandmarkIndex, MemoryAccountingMatchesTheHeap) {
  SiftLikeWorld w(11);
  std::vector<LandmarkModel> models;
  for (int64_t id = 0; id < 300; ++id) models.push_back(w.landmark(id, 50));
#if defined(__SANITIZE_ADDRESS__)
  GTEST_SKIP() << "AddressSanitizer's allocator does not report through mallinfo2";
#endif
  const auto heap = [] {
    const struct mallinfo2 m = mallinfo2();
    return static_cast<double>(m.uordblks + m.hblkhd);
  };
  const double before = heap();
  auto index = std::make_unique<LandmarkIndex>();
  for (const LandmarkModel& m : models) index->add(m);
  const double grown = heap() - before;
  const double counted = static_cast<double>(index->memoryBytes());
  EXPECT_NEAR(counted, grown, 0.1 * grown);
  EXPECT_LT(counted / 300.0, 50e3);  // the bound per landmark
  // 128 B per point for verification + 128 B + 8 B in the inverted file.
  EXPECT_GT(counted / (300.0 * 50.0), 2 * 128.0);
  index.reset();
  EXPECT_NEAR(heap(), before, 0.02 * grown);
}

TEST(VocabularyTree, TrainsDeterministicallyAndSearchesEveryLeaf) {
  SiftLikeWorld w(12);
  const cv::Mat d = toDescriptorsU8(w.gen.descriptors(5000));
  const VocabularyTree a = VocabularyTree::train(d), b = VocabularyTree::train(d);
  ASSERT_EQ(a.numWords(), b.numWords());
  EXPECT_LE(a.numWords(), 10000u);
  EXPECT_GT(a.numWords(), 100u);
  EXPECT_LE(a.depth(), 4);
  for (int i = 0; i < d.rows; i += 50)
    EXPECT_EQ(a.quantize(d.ptr<uint8_t>(i)), b.quantize(d.ptr<uint8_t>(i)));
  // Best-bin-first: the first leaf is quantize()'s, and every leaf is visited once.
  std::vector<uint32_t> visited;
  a.search(d.ptr<uint8_t>(0), std::numeric_limits<int>::max(), [&](uint32_t word) {
    visited.push_back(word);
    return 1;
  });
  ASSERT_EQ(visited.size(), a.numWords());
  EXPECT_EQ(visited[0], a.quantize(d.ptr<uint8_t>(0)));
  std::sort(visited.begin(), visited.end());
  EXPECT_EQ(std::unique(visited.begin(), visited.end()), visited.end());
  EXPECT_THROW(VocabularyTree::train(cv::Mat::zeros(10, 128, CV_32F)), std::invalid_argument);
}
