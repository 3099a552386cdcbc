#pragma once
// A particle's landmark map: one 3-state Kalman filter per landmark, kept in
// a persistent (copy-on-write) trie so that particles share every part of
// their maps they have not changed since their common ancestor.
//
// Copying a LandmarkMap copies one pointer (O(1), whatever the number of
// landmarks), so resampling costs O(particles). Changing a landmark copies
// only the nodes on the path from the root to that landmark's leaf that are
// shared with another map: depth + 1 nodes, depth = log_8(landmarks / 4), as
// in FastSLAM's balanced landmark tree (Montemerlo et al. 2002). A path
// already owned by this map alone is changed in place.
//
// Landmarks are addressed by slot, a dense index the filter assigns to each
// landmark id on first sight (the same slot in every particle). Nodes are
// reference counted (atomic counts: maps of different particles are changed
// from different threads at once; a node whose count is 1 is reachable from
// one map only, so only that map's thread can touch it).

#include <Eigen/Core>
#include <atomic>
#include <cstddef>
#include <cstdint>

namespace vslam::backend {

// The Kalman filter of one landmark: its pose in the map frame (the robot
// pose at the landmark's creation) and that pose's covariance.
struct LandmarkEstimate {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();        // x, y (m), theta (rad)
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // m^2, m rad, rad^2
  int32_t num_observations = 0;                          // 0: slot empty
};

class LandmarkMap {
 public:
  static constexpr int kBranchBits = 3;  // interior nodes have 8 children
  static constexpr int kLeafBits = 2;    // leaves hold 4 landmarks
  static constexpr uint32_t kBranch = 1u << kBranchBits;
  static constexpr uint32_t kLeafSize = 1u << kLeafBits;

  LandmarkMap() = default;
  LandmarkMap(const LandmarkMap& other);
  LandmarkMap(LandmarkMap&& other) noexcept;
  LandmarkMap& operator=(const LandmarkMap& other);
  LandmarkMap& operator=(LandmarkMap&& other) noexcept;
  ~LandmarkMap();

  // The landmark in `slot`, or nullptr if empty.
  const LandmarkEstimate* find(uint32_t slot) const;
  // The landmark in `slot` for writing (an empty estimate if the slot was
  // empty): copies the shared nodes on its path first, grows the trie if the
  // slot is beyond its capacity.
  LandmarkEstimate& mutableSlot(uint32_t slot);

  // Levels of interior nodes above the leaves.
  int depth() const { return depth_; }
  // Slots addressable without growing.
  uint64_t capacity() const;
  // Nodes (interior and leaf) reachable from this map, and how many of them
  // it shares with another map (reference count above 1, or below a shared
  // node). For tests and diagnostics; O(nodes).
  struct NodeCount {
    size_t total = 0;
    size_t shared = 0;
  };
  NodeCount countNodes() const;
  // Both maps point to the same root (nothing changed since one was copied from the other).
  bool sameRoot(const LandmarkMap& other) const { return root_ == other.root_; }

  // Calls f(slot, estimate) for every non-empty slot in increasing order.
  template <class F>
  void forEach(F&& f) const;

  struct Node;  // implementation detail, defined in the .cpp

 private:
  template <class F>
  static void visit(const Node* n, int level, uint32_t base, F& f);
  static bool isLeaf(const Node* n);
  static const Node* child(const Node* n, uint32_t i);
  static const LandmarkEstimate& entry(const Node* n, uint32_t i);

  Node* root_ = nullptr;
  int depth_ = 0;
};

template <class F>
void LandmarkMap::forEach(F&& f) const {
  if (root_) visit(root_, depth_, 0, f);
}

template <class F>
void LandmarkMap::visit(const Node* n, int level, uint32_t base, F& f) {
  if (level == 0) {
    for (uint32_t i = 0; i < kLeafSize; ++i) {
      const LandmarkEstimate& e = entry(n, i);
      if (e.num_observations > 0) f(base + i, e);
    }
    return;
  }
  const uint32_t span = kLeafSize << (kBranchBits * (level - 1));
  for (uint32_t i = 0; i < kBranch; ++i) {
    if (const Node* c = child(n, i)) visit(c, level - 1, base + i * span, f);
  }
}

}  // namespace vslam::backend
