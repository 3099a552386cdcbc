#pragma once
// The pre-filter of the vSLAM paper (Karlsson et al., section 5): an
// acceptance region over the three statistics of a visual measurement
// (ProjErrRMS, NPoints, Slope). A measurement outside the region is rejected
// and never reaches the back-end. The region is a parameter, as the paper
// intends; the defaults are the paper's.
//
// Shared by the back-end (which filters every measurement) and the front-end
// (which uses the verdict to decide whether a place needs a new landmark).
// No LCM: MeasurementStatus values equal vslam.visual_measurement_t's
// STATUS_* (checked by static_assert in the tests and the back-end stage).

#include "odometry/pose2.hpp"

namespace vslam::backend {

enum class MeasurementStatus : int {
  kUnfiltered = 0,
  kAccepted = 1,
  kRejectedProjErr = 2,
  kRejectedNumPoints = 3,
  kRejectedSlope = 4,
  kRejectedInvalid = 5,
};
constexpr int kNumMeasurementStatus = 6;
const char* toString(MeasurementStatus s);
// snake_case name for health metrics: "accepted", "rejected_proj_err", ...
const char* metricName(MeasurementStatus s);

struct PrefilterParams {
  double max_proj_err_rms_px = 3.0;  // reject if ProjErrRMS > this (pixels)
  int min_num_points = 10;           // reject if NPoints < this
  double max_slope = 0.1;            // reject if Slope > this (tan of the robot's tilt)

  // Throws std::invalid_argument naming the first bad field.
  void validate() const;
};

// What the pre-filter judges: the relative pose (only for finiteness) and
// the three statistics.
struct PrefilterInput {
  Pose2 relative;
  double proj_err_rms_px = 0;
  int num_points = 0;
  double slope = 0;
};

// The first failed test in the paper's order (ProjErrRMS, NPoints, Slope;
// the bounds themselves pass). A non-finite pose, ProjErrRMS or Slope (NaN;
// +inf Slope is a slope rejection), or a negative value, is kRejectedInvalid.
MeasurementStatus prefilter(const PrefilterInput& m, const PrefilterParams& params = {});

}  // namespace vslam::backend
