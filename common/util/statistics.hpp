#pragma once
// Small statistics over samples, one implementation for the whole stack.

#include <vector>

namespace vslam {

// The element that would stand at index n/2 were `v` sorted: the median of
// an odd count, the upper of the two middle ones of an even count (a robust
// location that is one of the samples, found in linear time). Reorders `v`.
// NaN when `v` is empty.
double upperMedian(std::vector<double>* v);
// The median: the mean of the two middle samples of an even count. NaN when empty.
double median(std::vector<double> v);
// The arithmetic mean. NaN when empty.
double mean(const std::vector<double>& v);

}  // namespace vslam
