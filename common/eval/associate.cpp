#include "eval/associate.hpp"

#include <algorithm>
#include <cmath>
#include <tuple>

namespace vslam::eval {

std::vector<Match> associate(const std::vector<double>& ref, const std::vector<double>& est,
                             double offset, double max_diff) {
  struct Candidate {
    double diff;
    std::size_t a, b;
  };
  std::vector<Candidate> candidates;
  if (!(max_diff > 0)) return {};
  // Window search over the sorted estimate instead of all n*m pairs; the
  // window is a little wider than needed and the exact test below is the
  // scripts' own expression, so rounding cannot change the outcome.
  const double margin = max_diff * 1e-6 + 1e-9;
  for (std::size_t a = 0; a < ref.size(); ++a) {
    const double lo = ref[a] - offset - max_diff - margin;
    auto it = std::lower_bound(est.begin(), est.end(), lo);
    for (; it != est.end() && *it + offset <= ref[a] + max_diff + margin; ++it) {
      const double diff = std::abs(ref[a] - (*it + offset));
      if (diff < max_diff) {
        candidates.push_back({diff, a, static_cast<std::size_t>(it - est.begin())});
      }
    }
  }
  std::sort(candidates.begin(), candidates.end(), [](const Candidate& x, const Candidate& y) {
    return std::tie(x.diff, x.a, x.b) < std::tie(y.diff, y.a, y.b);
  });
  std::vector<bool> ref_used(ref.size(), false), est_used(est.size(), false);
  std::vector<Match> matches;
  for (const auto& c : candidates) {
    if (ref_used[c.a] || est_used[c.b]) continue;
    ref_used[c.a] = est_used[c.b] = true;
    matches.push_back({c.a, c.b});
  }
  std::sort(matches.begin(), matches.end(),
            [](const Match& x, const Match& y) { return x.ref < y.ref; });
  return matches;
}

std::size_t findClosestIndex(const std::vector<double>& values, double t) {
  std::size_t begin = 0, end = values.size(), best = 0;
  double difference = std::abs(values[0] - t);
  while (begin < end) {
    const std::size_t middle = (begin + end) / 2;
    if (std::abs(values[middle] - t) < difference) {
      difference = std::abs(values[middle] - t);
      best = middle;
    }
    if (t == values[middle]) return middle;
    if (values[middle] > t) {
      end = middle;
    } else {
      begin = middle + 1;
    }
  }
  return best;
}

}  // namespace vslam::eval
