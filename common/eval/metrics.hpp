#pragma once
// Trajectory error metrics with the definitions of the TUM RGB-D benchmark
// scripts (evaluate_ate.py, evaluate_rpe.py --fixed_delta) and evo; see
// docs/evaluation.md for the exact formulas and where they differ.

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "eval/align.hpp"
#include "eval/associate.hpp"
#include "eval/trajectory.hpp"

namespace vslam::eval {

// Summary of a list of errors, numpy-style: rmse = sqrt(sum e^2 / n), median
// the mean of the two middle values for even n, std the population standard
// deviation (ddof = 0). All NaN when count == 0.
struct ErrorStats {
  std::size_t count = 0;
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0;
};
ErrorStats computeStats(const std::vector<double>& values);

// Absolute trajectory error: associate (associate.py semantics), align the
// associated estimate positions to the reference ones (alignPositions), and
// take the Euclidean distance of each pair. The heading error of a pair is
// |heading(aligned estimate) - heading(reference)| on the shortest arc
// (headingOf; the alignment's rotation applied to the estimate first).
struct AteResult {
  std::vector<Match> matches;  // ref/est indices, sorted by reference time
  Similarity alignment;        // estimate frame -> reference frame
  std::vector<double> errors;  // metres, one per match
  ErrorStats stats;
  std::vector<double> heading_errors;  // radians in [0, pi], one per match
  ErrorStats heading;
};
// Throws DataError if no pair is associated or there are too few for `mode`.
AteResult computeAte(const Trajectory& ref, const Trajectory& est, double offset, double max_diff,
                     AlignMode mode);

enum class DeltaUnit { kSeconds, kMetres };
std::optional<DeltaUnit> parseDeltaUnit(const std::string& word);
std::string toString(DeltaUnit unit);

struct RpeOptions {
  double delta = 1.0;  // in `unit`
  DeltaUnit unit = DeltaUnit::kSeconds;
  double offset = 0.0;  // seconds added to the estimate's stamps
};

struct RpePair {
  double t_est0 = 0, t_est1 = 0;  // estimate stamps of the pair
  double t_ref0 = 0, t_ref1 = 0;  // reference stamps matched to them
  double trans = 0;               // metres
  double rot = 0;                 // radians
};

struct RpeResult {
  std::vector<RpePair> pairs;
  ErrorStats trans;              // metres
  ErrorStats rot;                // radians
  double ref_max_time_diff = 0;  // 2 x median reference interval, seconds
};

// Relative pose error as evaluate_rpe.py --fixed_delta --max_pairs 0 computes
// it, on `est` as given (pass the aligned estimate: rigid alignment does not
// change RPE, a sim3 scale does, like the script's --scale):
//   for every estimate pose i, j = the pose whose stamp (unit s) or distance
//   travelled along the estimate (unit m) is closest to i's plus delta;
//   pairs with j the last pose (the script's end-of-trajectory rule) or
//   j == i (a gap longer than delta; the script counts those as error 0) are
//   skipped; each estimate stamp (+ offset) is matched to the nearest
//   reference stamp, and the pair is dropped if that is more than twice the
//   median reference interval away;
//   E = (P_i^-1 P_j) (Q_i^-1 Q_j)^-1  (P estimate, Q reference),
//   trans = |translation(E)|, rot = arccos((trace(R(E)) - 1) / 2).
// Fewer than two poses in either trajectory gives an empty result.
RpeResult computeRpe(const Trajectory& ref, const Trajectory& est, const RpeOptions& options);

}  // namespace vslam::eval
