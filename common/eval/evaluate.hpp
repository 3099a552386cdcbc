#pragma once
// One trajectory evaluation: a reference, one or more estimates (each with
// its own alignment), and optionally the landmarks of a map, turned into ATE,
// RPE and the aligned trajectories for plots and reports.

#include <cstdint>
#include <string>
#include <vector>

#include "eval/metrics.hpp"

namespace vslam::eval {

// What an estimate is, for reports and plot colours (vSLAM paper Fig. 7/9:
// the SLAM estimate red, odometry-only green).
enum class EstimateKind { kEstimate, kOdometry };
std::string toString(EstimateKind kind);

struct EstimateInput {
  Trajectory trajectory;
  EstimateKind kind = EstimateKind::kEstimate;
  std::string source;  // e.g. "vslam.pose_estimate_t" or "TUM file"
};

struct TrajectoryEvalOptions {
  double max_diff = 0.02;  // seconds, association (strictly less than)
  double offset = 0.0;     // seconds added to the estimate's stamps
  AlignMode align = AlignMode::kSE3;
  RpeOptions rpe;  // rpe.offset is set from offset
};

struct EstimateEvaluation {
  std::string name;
  EstimateKind kind = EstimateKind::kEstimate;
  std::string source;
  std::size_t poses = 0;
  double duration = 0;     // seconds
  double path_length = 0;  // metres, as estimated (before alignment)
  AteResult ate;
  RpeResult rpe;
  Trajectory aligned;  // every pose of the estimate, mapped by ate.alignment
  // Reference time and ATE error of each associated pair (vSLAM Fig. 9).
  std::vector<double> error_times;
};

// Throws DataError (empty estimate, no associated poses, too few for the
// alignment).
EstimateEvaluation evaluateEstimate(const Trajectory& ref, const EstimateInput& est,
                                    const TrajectoryEvalOptions& options);

// A landmark's global position from the back-end's map (map frame).
struct LandmarkPosition {
  int64_t id = 0;
  double x = 0, y = 0;
};

struct TrajectoryReport {
  std::string input;     // what was read, for the header
  Trajectory reference;  // sorted
  std::string reference_source;
  TrajectoryEvalOptions options;
  std::vector<EstimateEvaluation> estimates;
  std::vector<LandmarkPosition> landmarks;  // map frame of the first kEstimate estimate
};

}  // namespace vslam::eval
