// Recognition of one frame (~500 SIFT-like descriptors) against 10, 100 and
// 1,000 landmarks of 60 points each, with the frame seeing two of them.
#include <benchmark/benchmark.h>

#include <random>

#include "frontend/landmark_index.hpp"
#include "support/synthetic_descriptors.hpp"

using namespace vslam::frontend;
using vslam::test::randomDescriptors;

namespace {

void BM_Recognize(benchmark::State& state) {
  const int num_landmarks = static_cast<int>(state.range(0));
  std::mt19937 rng(1);
  LandmarkIndex index;
  std::vector<cv::Mat> all;
  for (int id = 0; id < num_landmarks; ++id) {
    LandmarkModel lm;
    lm.id = id;
    lm.descriptors = randomDescriptors(60, rng);
    lm.points_robot.assign(60, Eigen::Vector3d(1, 0, 0));
    all.push_back(lm.descriptors);
    index.add(std::move(lm));
  }
  Features frame;
  std::normal_distribution<float> noise(0.f, 8.f);
  for (int l : {0, num_landmarks / 2}) {
    for (int i = 0; i < 40; ++i) {
      cv::Mat r = all[static_cast<size_t>(l)].row(i).clone();
      for (int c = 0; c < 128; ++c)
        r.at<float>(0, c) = std::max(0.f, r.at<float>(0, c) + noise(rng));
      frame.descriptors.push_back(r);
    }
  }
  frame.descriptors.push_back(randomDescriptors(420, rng));
  frame.normalized.assign(static_cast<size_t>(frame.descriptors.rows), Eigen::Vector2d::Zero());
  frame.keypoints.resize(static_cast<size_t>(frame.descriptors.rows));
  index.recognize(frame);  // builds the index outside the timing
  size_t found = 0;
  for (auto _ : state) found = index.recognize(frame).size();
  state.counters["landmarks_found"] = static_cast<double>(found);
}
BENCHMARK(BM_Recognize)->Arg(10)->Arg(100)->Arg(1000)->Unit(benchmark::kMillisecond);

}  // namespace
