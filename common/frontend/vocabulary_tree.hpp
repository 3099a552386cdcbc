#pragma once
// A hierarchical k-means vocabulary of SIFT descriptors (Nister & Stewenius
// 2006, the scheme DBoW2/FBoW use): each node splits its training
// descriptors into `branching` clusters, down to `max_depth` levels or until
// a node holds too few descriptors; the leaves are the visual words. A
// descriptor's word is found by descending to the nearest child centre at each
// level: branching x depth distances instead of one per word. Centres are
// stored as uint8 (rounded means), like the descriptors. No LCM.

#include <algorithm>
#include <cstdint>
#include <opencv2/core.hpp>
#include <random>
#include <vector>

namespace vslam::frontend {

struct VocabularyParams {
  int branching = 10;            // k of each k-means
  int max_depth = 4;             // levels below the root: up to branching^max_depth words
  int min_leaf_descriptors = 4;  // a node is split only if it holds >= branching * this
  int kmeans_iterations = 10;    // Lloyd iterations per node (stops early when stable)
  uint32_t seed = 1;             // k-means++ seeding; training is deterministic
};

class VocabularyTree {
 public:
  VocabularyTree() = default;

  // Trains on `descriptors` (CV_8U, n x 128, continuous). Throws
  // std::invalid_argument on bad parameters or input.
  static VocabularyTree train(const cv::Mat& descriptors, const VocabularyParams& params = {});

  bool empty() const { return num_words_ == 0; }
  uint32_t numWords() const { return num_words_; }
  int depth() const { return depth_; }
  size_t numNodes() const { return nodes_.size(); }
  // Number of descriptors the vocabulary was trained on.
  size_t trainingSize() const { return training_size_; }

  // The word (0..numWords()-1) of one 128-byte descriptor. Requires !empty().
  uint32_t quantize(const uint8_t* descriptor) const;

  // Best-bin-first search (as FLANN's hierarchical k-means index): visits
  // leaves in order of their branch's distance to `descriptor`, starting with
  // quantize()'s, calling visit(word) -> number of points it compared, until
  // at least `checks` points were compared or every leaf was visited.
  template <class Visit>
  void search(const uint8_t* descriptor, int checks, Visit&& visit) const;

  // Bytes held: centres and nodes.
  size_t memoryBytes() const;

 private:
  struct Node {
    int32_t first_child = -1;  // children are nodes [first_child, first_child + num_children)
    int32_t num_children = 0;
    int32_t word = -1;  // leaves only
  };
  uint32_t distanceToCentre(const uint8_t* descriptor, int32_t node) const;
  void split(const cv::Mat& data, std::vector<int>& members, int node, int level,
             const VocabularyParams& params, std::mt19937& rng);

  std::vector<Node> nodes_;       // nodes_[0] is the root
  std::vector<uint8_t> centres_;  // 128 bytes per node (the root's unused)
  uint32_t num_words_ = 0;
  int depth_ = 0;
  size_t training_size_ = 0;
};

template <class Visit>
void VocabularyTree::search(const uint8_t* descriptor, int checks, Visit&& visit) const {
  if (nodes_.empty()) return;
  // Pending branches: (squared distance of the query to its centre, node).
  std::vector<std::pair<uint32_t, int32_t>> heap;
  auto cmp = [](const auto& a, const auto& b) { return a.first > b.first; };
  int compared = 0;
  int32_t node = 0;
  while (true) {
    // Descend to the nearest leaf, queueing the other children.
    while (nodes_[static_cast<size_t>(node)].num_children > 0) {
      const Node& n = nodes_[static_cast<size_t>(node)];
      uint32_t best = UINT32_MAX;
      int32_t arg = n.first_child;
      for (int32_t c = n.first_child; c < n.first_child + n.num_children; ++c) {
        const uint32_t d = distanceToCentre(descriptor, c);
        if (d < best) {
          if (best != UINT32_MAX) {
            heap.emplace_back(best, arg);
            std::push_heap(heap.begin(), heap.end(), cmp);
          }
          best = d;
          arg = c;
        } else {
          heap.emplace_back(d, c);
          std::push_heap(heap.begin(), heap.end(), cmp);
        }
      }
      node = arg;
    }
    compared += visit(static_cast<uint32_t>(nodes_[static_cast<size_t>(node)].word));
    if (compared >= checks || heap.empty()) return;
    std::pop_heap(heap.begin(), heap.end(), cmp);
    node = heap.back().second;
    heap.pop_back();
  }
}

}  // namespace vslam::frontend
