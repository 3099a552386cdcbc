#include "frontend/matching.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <unordered_map>

namespace vslam::frontend {

namespace {

using ConstMapF =
    Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>,
               Eigen::Unaligned, Eigen::OuterStride<>>;

ConstMapF asEigen(const cv::Mat& m) {
  return ConstMapF(m.ptr<float>(), m.rows, m.cols,
                   Eigen::OuterStride<>(static_cast<Eigen::Index>(m.step1())));
}

}  // namespace

RatioMatcher::RatioMatcher(const MatchParams& params) : params_(params) {
  if (!(params_.ratio > 0.0 && params_.ratio <= 1.0))
    throw std::invalid_argument("MatchParams.ratio must be in (0, 1]");
}

void RatioMatcher::match(const cv::Mat& query, const cv::Mat& train,
                         std::vector<cv::DMatch>* matches) {
  matches->clear();
  if (query.empty() || train.rows < 2) return;
  if (query.type() != CV_32F || train.type() != CV_32F || query.cols != train.cols)
    throw std::invalid_argument("RatioMatcher::match: needs CV_32F descriptors of equal length");
  const ConstMapF q = asEigen(query);
  const ConstMapF t = asEigen(train);
  const Eigen::Index nq = q.rows(), nt = t.rows();
  query_norm_ = q.rowwise().squaredNorm();
  train_norm_ = t.rowwise().squaredNorm();
  dot_.resize(nq, nt);
  dot_.noalias() = q * t.transpose();

  // Squared distance of (i, j), clamped against rounding below zero.
  auto dist2 = [&](Eigen::Index i, Eigen::Index j) {
    return std::max(0.0f, query_norm_[i] + train_norm_[j] - 2.0f * dot_(i, j));
  };
  if (params_.mutual) {
    train_best_.assign(nt, -1);
    train_best_dist_.assign(nt, std::numeric_limits<float>::infinity());
    for (Eigen::Index i = 0; i < nq; ++i) {
      for (Eigen::Index j = 0; j < nt; ++j) {
        const float d = dist2(i, j);
        if (d < train_best_dist_[j]) {
          train_best_dist_[j] = d;
          train_best_[j] = static_cast<int>(i);
        }
      }
    }
  }
  const float ratio2 = static_cast<float>(params_.ratio * params_.ratio);
  for (Eigen::Index i = 0; i < nq; ++i) {
    float best = std::numeric_limits<float>::infinity(), second = best;
    Eigen::Index best_j = -1;
    for (Eigen::Index j = 0; j < nt; ++j) {
      const float d = dist2(i, j);
      if (d < best) {
        second = best;
        best = d;
        best_j = j;
      } else if (d < second) {
        second = d;
      }
    }
    if (best_j < 0 || !(best < ratio2 * second)) continue;
    if (params_.mutual && train_best_[best_j] != i) continue;
    matches->emplace_back(static_cast<int>(i), static_cast<int>(best_j), std::sqrt(best));
  }
}

void threeWayMatches(const std::vector<cv::DMatch>& m12, const std::vector<cv::DMatch>& m13,
                     const std::vector<cv::DMatch>& m23, std::vector<Triplet>* triplets) {
  triplets->clear();
  std::unordered_map<int, int> one_to_three, two_to_three;
  one_to_three.reserve(m13.size());
  two_to_three.reserve(m23.size());
  for (const auto& m : m13) one_to_three.emplace(m.queryIdx, m.trainIdx);
  for (const auto& m : m23) two_to_three.emplace(m.queryIdx, m.trainIdx);
  std::unordered_map<int, int> uses2, uses3;
  for (const auto& m : m12) {
    const auto a = one_to_three.find(m.queryIdx);
    const auto b = two_to_three.find(m.trainIdx);
    if (a == one_to_three.end() || b == two_to_three.end() || a->second != b->second) continue;
    triplets->push_back({m.queryIdx, m.trainIdx, a->second});
    ++uses2[m.trainIdx];
    ++uses3[a->second];
  }
  triplets->erase(
      std::remove_if(triplets->begin(), triplets->end(),
                     [&](const Triplet& t) { return uses2[t.i2] > 1 || uses3[t.i3] > 1; }),
      triplets->end());
  std::sort(triplets->begin(), triplets->end(),
            [](const Triplet& a, const Triplet& b) { return a.i1 < b.i1; });
}

}  // namespace vslam::frontend
