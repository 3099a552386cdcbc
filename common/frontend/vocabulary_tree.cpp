#include "frontend/vocabulary_tree.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>

#include "frontend/descriptor_distance.hpp"

namespace vslam::frontend {

namespace {

// Lloyd's k-means with k-means++ seeding over the rows `members` of `data`
// (CV_8U). Centres are kept as rounded uint8 means. Returns the centres
// (k x 128) and each member's cluster.
void kmeans(const cv::Mat& data, const std::vector<int>& members, int k, int iterations,
            std::mt19937& rng, std::vector<uint8_t>* centres, std::vector<int>* assignment) {
  const size_t n = members.size();
  centres->assign(static_cast<size_t>(k) * kDescriptorBytes, 0);
  auto row = [&](size_t i) { return data.ptr<uint8_t>(members[i]); };
  auto centre = [&](int c) { return centres->data() + static_cast<size_t>(c) * kDescriptorBytes; };

  // k-means++: each next centre drawn with probability proportional to the
  // squared distance to the nearest centre chosen so far.
  std::vector<double> nearest(n, std::numeric_limits<double>::max());
  size_t pick = std::uniform_int_distribution<size_t>(0, n - 1)(rng);
  for (int c = 0; c < k; ++c) {
    std::copy(row(pick), row(pick) + kDescriptorBytes, centre(c));
    if (c + 1 == k) break;
    double total = 0;
    for (size_t i = 0; i < n; ++i) {
      nearest[i] = std::min(nearest[i], static_cast<double>(squaredDistanceU8(row(i), centre(c))));
      total += nearest[i];
    }
    if (total <= 0) {  // fewer distinct descriptors than clusters: duplicate centres
      pick = std::uniform_int_distribution<size_t>(0, n - 1)(rng);
      continue;
    }
    double u = std::uniform_real_distribution<double>(0, total)(rng);
    pick = n - 1;
    for (size_t i = 0; i < n; ++i) {
      u -= nearest[i];
      if (u < 0) {
        pick = i;
        break;
      }
    }
  }

  assignment->assign(n, -1);
  std::vector<double> sums(static_cast<size_t>(k) * kDescriptorBytes);
  std::vector<size_t> counts(static_cast<size_t>(k));
  std::vector<uint32_t> dist(n);
  for (int it = 0; it < iterations; ++it) {
    bool changed = false;
    for (size_t i = 0; i < n; ++i) {
      uint32_t best = std::numeric_limits<uint32_t>::max();
      int arg = 0;
      for (int c = 0; c < k; ++c) {
        const uint32_t d = squaredDistanceU8(row(i), centre(c));
        if (d < best) {
          best = d;
          arg = c;
        }
      }
      changed = changed || (*assignment)[i] != arg;
      (*assignment)[i] = arg;
      dist[i] = best;
    }
    if (!changed) break;
    std::fill(sums.begin(), sums.end(), 0.0);
    std::fill(counts.begin(), counts.end(), 0);
    for (size_t i = 0; i < n; ++i) {
      const size_t c = static_cast<size_t>((*assignment)[i]);
      ++counts[c];
      const uint8_t* r = row(i);
      double* s = sums.data() + c * kDescriptorBytes;
      for (int j = 0; j < kDescriptorBytes; ++j) s[j] += r[j];
    }
    for (int c = 0; c < k; ++c) {
      const size_t cu = static_cast<size_t>(c);
      if (counts[cu] == 0) {
        // Empty cluster: move it to the member farthest from its centre.
        const size_t far =
            static_cast<size_t>(std::max_element(dist.begin(), dist.end()) - dist.begin());
        std::copy(row(far), row(far) + kDescriptorBytes, centre(c));
        dist[far] = 0;
        continue;
      }
      const double* s = sums.data() + cu * kDescriptorBytes;
      uint8_t* m = centre(c);
      for (int j = 0; j < kDescriptorBytes; ++j) {
        m[j] = static_cast<uint8_t>(std::min(255.0, s[j] / static_cast<double>(counts[cu]) + 0.5));
      }
    }
  }
}

}  // namespace

VocabularyTree VocabularyTree::train(const cv::Mat& descriptors, const VocabularyParams& params) {
  if (params.branching < 2 || params.max_depth < 1 || params.min_leaf_descriptors < 1 ||
      params.kmeans_iterations < 1) {
    throw std::invalid_argument(
        "VocabularyParams: branching >= 2, max_depth >= 1, min_leaf_descriptors >= 1, "
        "kmeans_iterations >= 1");
  }
  if (descriptors.type() != CV_8U || descriptors.cols != kDescriptorBytes ||
      !descriptors.isContinuous() || descriptors.rows < 1) {
    throw std::invalid_argument("VocabularyTree::train: needs continuous CV_8U n x 128, n >= 1");
  }
  VocabularyTree t;
  t.training_size_ = static_cast<size_t>(descriptors.rows);
  t.nodes_.emplace_back();
  t.centres_.assign(kDescriptorBytes, 0);
  std::vector<int> all(static_cast<size_t>(descriptors.rows));
  for (int i = 0; i < descriptors.rows; ++i) all[static_cast<size_t>(i)] = i;
  std::mt19937 rng(params.seed);
  t.split(descriptors, all, 0, 0, params, rng);
  return t;
}

void VocabularyTree::split(const cv::Mat& data, std::vector<int>& members, int node, int level,
                           const VocabularyParams& params, std::mt19937& rng) {
  const int k = params.branching;
  auto makeLeaf = [&] {
    nodes_[static_cast<size_t>(node)].word = static_cast<int32_t>(num_words_++);
    depth_ = std::max(depth_, level);
  };
  if (level >= params.max_depth ||
      members.size() < static_cast<size_t>(k) * static_cast<size_t>(params.min_leaf_descriptors)) {
    makeLeaf();
    return;
  }
  std::vector<uint8_t> centres;
  std::vector<int> assignment;
  kmeans(data, members, k, params.kmeans_iterations, rng, &centres, &assignment);
  std::vector<std::vector<int>> parts(static_cast<size_t>(k));
  for (size_t i = 0; i < members.size(); ++i)
    parts[static_cast<size_t>(assignment[i])].push_back(members[i]);
  const size_t non_empty = static_cast<size_t>(
      std::count_if(parts.begin(), parts.end(), [](const auto& p) { return !p.empty(); }));
  if (non_empty < 2) {  // identical descriptors: nothing to split
    makeLeaf();
    return;
  }
  members.clear();
  members.shrink_to_fit();
  const int32_t first = static_cast<int32_t>(nodes_.size());
  int32_t count = 0;
  for (int c = 0; c < k; ++c) {
    if (parts[static_cast<size_t>(c)].empty()) continue;
    nodes_.emplace_back();
    centres_.insert(centres_.end(), centres.begin() + c * kDescriptorBytes,
                    centres.begin() + (c + 1) * kDescriptorBytes);
    ++count;
  }
  nodes_[static_cast<size_t>(node)].first_child = first;
  nodes_[static_cast<size_t>(node)].num_children = count;
  int child = first;
  for (int c = 0; c < k; ++c) {
    if (parts[static_cast<size_t>(c)].empty()) continue;
    split(data, parts[static_cast<size_t>(c)], child++, level + 1, params, rng);
  }
}

uint32_t VocabularyTree::distanceToCentre(const uint8_t* descriptor, int32_t node) const {
  return squaredDistanceU8(descriptor,
                           centres_.data() + static_cast<size_t>(node) * kDescriptorBytes);
}

uint32_t VocabularyTree::quantize(const uint8_t* descriptor) const {
  const Node* n = &nodes_[0];
  while (n->num_children > 0) {
    uint32_t best = std::numeric_limits<uint32_t>::max();
    int32_t arg = n->first_child;
    for (int32_t c = n->first_child; c < n->first_child + n->num_children; ++c) {
      const uint32_t d = squaredDistanceU8(
          descriptor, centres_.data() + static_cast<size_t>(c) * kDescriptorBytes);
      if (d < best) {
        best = d;
        arg = c;
      }
    }
    n = &nodes_[static_cast<size_t>(arg)];
  }
  return static_cast<uint32_t>(n->word);
}

size_t VocabularyTree::memoryBytes() const {
  auto block = [](size_t b) {
    return b == 0 ? size_t{0} : std::max<size_t>(32, (b + 8 + 15) / 16 * 16);
  };
  return block(nodes_.capacity() * sizeof(Node)) + block(centres_.capacity());
}

}  // namespace vslam::frontend
