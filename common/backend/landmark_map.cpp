#include "backend/landmark_map.hpp"

#include <tbb/scalable_allocator.h>

#include <new>
#include <utility>

namespace vslam::backend {

// Interior nodes and leaves share a header; `leaf` says which one a node is.
struct LandmarkMap::Node {
  Node() = default;
  // A copy starts with one reference: the map that made it.
  Node(const Node& other) : leaf(other.leaf) {}
  Node& operator=(const Node&) = delete;
  std::atomic<uint32_t> refs{1};
  bool leaf = false;
};

namespace {

using Node = LandmarkMap::Node;

// Nodes come from TBB's scalable allocator: every update of a landmark
// copies a path of nodes per particle, on several threads at once, and the
// system allocator's bins were 7-10 % of the filter's time (perf, 2026-12-01).
struct PooledNode : Node {
  static void* operator new(size_t size) {
    if (void* p = scalable_malloc(size)) return p;
    throw std::bad_alloc();
  }
  static void operator delete(void* p) { scalable_free(p); }
};
struct Interior : PooledNode {
  Node* children[LandmarkMap::kBranch] = {};
};
struct Leaf : PooledNode {
  LandmarkEstimate entries[LandmarkMap::kLeafSize];
};

Interior* asInterior(Node* n) { return static_cast<Interior*>(n); }
const Interior* asInterior(const Node* n) { return static_cast<const Interior*>(n); }
Leaf* asLeaf(Node* n) { return static_cast<Leaf*>(n); }
const Leaf* asLeaf(const Node* n) { return static_cast<const Leaf*>(n); }

void retain(Node* n) {
  if (n) n->refs.fetch_add(1, std::memory_order_relaxed);
}

void release(Node* n) {
  while (n && n->refs.fetch_sub(1, std::memory_order_acq_rel) == 1) {
    // Last reference: free the node and drop its references to its children
    // (iteratively along one child, recursively for the others; the depth is
    // a few levels).
    if (n->leaf) {
      delete asLeaf(n);
      return;
    }
    Interior* in = asInterior(n);
    Node* next = nullptr;
    for (Node* c : in->children) {
      if (!c) continue;
      if (!next) {
        next = c;
      } else {
        release(c);
      }
    }
    delete in;
    n = next;
  }
}

// Returns a node this map alone owns in place of *link, copying it if shared.
Node* makeUnique(Node** link) {
  Node* n = *link;
  if (n->refs.load(std::memory_order_acquire) == 1) return n;
  Node* copy;
  if (n->leaf) {
    Leaf* l = new Leaf(*asLeaf(n));  // copies the estimates
    copy = l;
  } else {
    Interior* in = new Interior;
    for (uint32_t i = 0; i < LandmarkMap::kBranch; ++i) {
      in->children[i] = asInterior(n)->children[i];
      retain(in->children[i]);
    }
    copy = in;
  }
  copy->refs.store(1, std::memory_order_relaxed);
  copy->leaf = n->leaf;
  *link = copy;
  release(n);
  return copy;
}

Node* newNode(bool leaf) {
  Node* n = leaf ? static_cast<Node*>(new Leaf) : static_cast<Node*>(new Interior);
  n->leaf = leaf;
  return n;
}

}  // namespace

LandmarkMap::LandmarkMap(const LandmarkMap& other) : root_(other.root_), depth_(other.depth_) {
  retain(root_);
}

LandmarkMap::LandmarkMap(LandmarkMap&& other) noexcept
    : root_(std::exchange(other.root_, nullptr)), depth_(std::exchange(other.depth_, 0)) {}

LandmarkMap& LandmarkMap::operator=(const LandmarkMap& other) {
  if (this != &other) {
    retain(other.root_);
    release(root_);
    root_ = other.root_;
    depth_ = other.depth_;
  }
  return *this;
}

LandmarkMap& LandmarkMap::operator=(LandmarkMap&& other) noexcept {
  if (this != &other) {
    release(root_);
    root_ = std::exchange(other.root_, nullptr);
    depth_ = std::exchange(other.depth_, 0);
  }
  return *this;
}

LandmarkMap::~LandmarkMap() { release(root_); }

uint64_t LandmarkMap::capacity() const { return uint64_t{kLeafSize} << (kBranchBits * depth_); }

bool LandmarkMap::isLeaf(const Node* n) { return n->leaf; }
const LandmarkMap::Node* LandmarkMap::child(const Node* n, uint32_t i) {
  return asInterior(n)->children[i];
}
const LandmarkEstimate& LandmarkMap::entry(const Node* n, uint32_t i) {
  return asLeaf(n)->entries[i];
}

const LandmarkEstimate* LandmarkMap::find(uint32_t slot) const {
  if (!root_ || slot >= capacity()) return nullptr;
  const Node* n = root_;
  for (int level = depth_; level > 0; --level) {
    const int shift = kLeafBits + kBranchBits * (level - 1);
    n = asInterior(n)->children[(slot >> shift) & (kBranch - 1)];
    if (!n) return nullptr;
  }
  const LandmarkEstimate& e = asLeaf(n)->entries[slot & (kLeafSize - 1)];
  return e.num_observations > 0 ? &e : nullptr;
}

LandmarkEstimate& LandmarkMap::mutableSlot(uint32_t slot) {
  if (!root_) {
    root_ = newNode(true);
    depth_ = 0;
  }
  while (slot >= capacity()) {
    Node* r = newNode(false);
    asInterior(r)->children[0] = root_;  // the map's reference moves to the new root
    root_ = r;
    ++depth_;
  }
  Node** link = &root_;
  for (int level = depth_; level > 0; --level) {
    Node* n = makeUnique(link);
    const int shift = kLeafBits + kBranchBits * (level - 1);
    link = &asInterior(n)->children[(slot >> shift) & (kBranch - 1)];
    if (!*link) *link = newNode(level == 1);
  }
  Node* leaf = makeUnique(link);
  return asLeaf(leaf)->entries[slot & (kLeafSize - 1)];
}

LandmarkMap::NodeCount LandmarkMap::countNodes() const {
  NodeCount count;
  struct Walk {
    NodeCount& c;
    void operator()(const Node* n, bool shared_above) {
      const bool shared = shared_above || n->refs.load(std::memory_order_relaxed) > 1;
      ++c.total;
      c.shared += shared;
      if (n->leaf) return;
      for (const Node* ch : asInterior(n)->children) {
        if (ch) (*this)(ch, shared);
      }
    }
  };
  if (root_) Walk{count}(root_, false);
  return count;
}

}  // namespace vslam::backend
