#include "frontend/landmark_index.hpp"

#include <algorithm>
#include <stdexcept>
#include <unordered_map>

namespace vslam::frontend {

LandmarkIndex::LandmarkIndex(const RecognitionParams& params) : params_(params) {
  if (!(params_.ratio > 0 && params_.ratio <= 1) || params_.min_matches < 3 ||
      params_.neighbours < 2) {
    throw std::invalid_argument(
        "RecognitionParams: ratio in (0, 1], min_matches >= 3, neighbours >= 2");
  }
}

LandmarkIndex::~LandmarkIndex() = default;

void LandmarkIndex::add(LandmarkModel landmark) {
  if (landmark.descriptors.type() != CV_32F ||
      landmark.descriptors.rows != static_cast<int>(landmark.points_robot.size())) {
    throw std::invalid_argument("landmark " + std::to_string(landmark.id) +
                                ": needs one CV_32F descriptor row per point");
  }
  const int64_t id = landmark.id;
  landmarks_[id] = std::move(landmark);
  dirty_ = true;
}

bool LandmarkIndex::remove(int64_t id) {
  const bool removed = landmarks_.erase(id) > 0;
  dirty_ = dirty_ || removed;
  return removed;
}

size_t LandmarkIndex::numDescriptors() const {
  size_t n = 0;
  for (const auto& [id, lm] : landmarks_) n += static_cast<size_t>(lm.descriptors.rows);
  return n;
}

const LandmarkModel* LandmarkIndex::find(int64_t id) const {
  const auto it = landmarks_.find(id);
  return it == landmarks_.end() ? nullptr : &it->second;
}

void LandmarkIndex::rebuild() {
  dirty_ = false;
  index_.reset();
  owner_.clear();
  std::vector<cv::Mat> blocks;
  for (const auto& [id, lm] : landmarks_) {
    blocks.push_back(lm.descriptors);
    for (int i = 0; i < lm.descriptors.rows; ++i) owner_.emplace_back(id, i);
  }
  if (owner_.empty()) return;
  cv::vconcat(blocks, all_descriptors_);
  index_ = std::make_unique<cv::flann::Index>(all_descriptors_,
                                              cv::flann::KDTreeIndexParams(params_.kdtree_trees));
}

std::vector<Recognition> LandmarkIndex::recognize(const Features& frame) {
  if (dirty_) rebuild();
  std::vector<Recognition> out;
  if (!index_ || frame.descriptors.rows == 0) return out;
  const int k = std::min<int>(params_.neighbours, static_cast<int>(owner_.size()));
  if (k < 1) return out;
  cv::Mat indices, dists;  // squared L2 distances
  index_->knnSearch(frame.descriptors, indices, dists, k,
                    cv::flann::SearchParams(params_.kdtree_checks));

  // Per landmark: point -> (frame feature, distance) of its best match.
  struct Match {
    int feature;
    float dist;
  };
  std::unordered_map<int64_t, std::unordered_map<int, Match>> per_landmark;
  const float ratio2 = static_cast<float>(params_.ratio * params_.ratio);
  for (int f = 0; f < indices.rows; ++f) {
    const int* idx = indices.ptr<int>(f);
    const float* d = dists.ptr<float>(f);
    // Walk the neighbours; for each landmark its first hit is the best and
    // its next hit (or, if none, the farthest neighbour fetched, a lower
    // bound on it) the second best.
    std::vector<int64_t> seen;
    for (int j = 0; j < k; ++j) {
      if (idx[j] < 0) break;
      const auto [id, point] = owner_[static_cast<size_t>(idx[j])];
      if (std::find(seen.begin(), seen.end(), id) != seen.end()) continue;
      seen.push_back(id);
      float second = d[k - 1];
      for (int m = j + 1; m < k; ++m) {
        if (idx[m] >= 0 && owner_[static_cast<size_t>(idx[m])].first == id) {
          second = d[m];
          break;
        }
      }
      const bool last_is_this = (j == k - 1);
      if (last_is_this || !(d[j] < ratio2 * second)) continue;
      auto& matches = per_landmark[id];
      const auto it = matches.find(point);
      if (it == matches.end() || d[j] < it->second.dist) matches[point] = {f, d[j]};
    }
  }

  for (auto& [id, matches] : per_landmark) {
    if (static_cast<int>(matches.size()) < params_.min_matches) continue;
    const LandmarkModel& lm = landmarks_.at(id);
    // One landmark point per frame feature: keep the closer one.
    std::unordered_map<int, std::pair<int, float>> by_feature;
    for (const auto& [point, m] : matches) {
      const auto it = by_feature.find(m.feature);
      if (it == by_feature.end() || m.dist < it->second.second)
        by_feature[m.feature] = {point, m.dist};
    }
    if (static_cast<int>(by_feature.size()) < params_.min_matches) continue;
    std::vector<std::pair<int, int>> pairs;  // (frame feature, point), sorted for determinism
    for (const auto& [feature, pd] : by_feature) pairs.emplace_back(feature, pd.first);
    std::sort(pairs.begin(), pairs.end());
    Recognition r;
    r.landmark_id = id;
    for (const auto& [feature, point] : pairs) {
      r.points_robot.push_back(lm.points_robot[static_cast<size_t>(point)]);
      r.observations.push_back(frame.normalized[static_cast<size_t>(feature)]);
      r.frame_features.push_back(feature);
    }
    out.push_back(std::move(r));
  }
  std::sort(out.begin(), out.end(), [](const Recognition& a, const Recognition& b) {
    return a.points_robot.size() != b.points_robot.size()
               ? a.points_robot.size() > b.points_robot.size()
               : a.landmark_id < b.landmark_id;
  });
  return out;
}

}  // namespace vslam::frontend
