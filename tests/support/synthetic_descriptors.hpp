#pragma once
// Synthetic SIFT-like descriptors for recognition tests and benchmarks.

#include <opencv2/core.hpp>
#include <random>

namespace vslam::test {

// n random non-negative 128-D descriptors with SIFT's norm (~512), CV_32F.
inline cv::Mat randomDescriptors(int n, std::mt19937& rng) {
  cv::Mat d(n, 128, CV_32F);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < 128; ++c) d.at<float>(r, c) = u(rng);
    d.row(r) *= 512.0 / cv::norm(d.row(r));
  }
  return d;
}

}  // namespace vslam::test
