#pragma once
// Timestamp association, with the semantics of the TUM RGB-D benchmark's
// associate.py (used by evaluate_ate.py):
//   - candidates are all pairs (a, b) of a reference stamp a and an estimate
//     stamp b with |a - (b + offset)| < max_diff (strictly less);
//   - they are taken greedily in order of increasing difference (ties: smaller
//     a, then smaller b), each stamp used at most once;
//   - the result is sorted by reference time.
// So every pose is matched at most once, and a pose whose nearest partner was
// taken by a closer one may match its second-nearest if that is within
// max_diff.

#include <cstddef>
#include <vector>

namespace vslam::eval {

struct Match {
  std::size_t ref = 0;  // index into the reference
  std::size_t est = 0;  // index into the estimate
  bool operator==(const Match& o) const { return ref == o.ref && est == o.est; }
};

// ref and est must be sorted ascending (Trajectory::stamps() of a sorted one).
std::vector<Match> associate(const std::vector<double>& ref, const std::vector<double>& est,
                             double offset, double max_diff);

// The TUM scripts' find_closest_index: a binary search over sorted `values`
// that returns the index of the element closest to t (of two equally close,
// the one the search meets first). `values` must not be empty.
std::size_t findClosestIndex(const std::vector<double>& values, double t);

}  // namespace vslam::eval
