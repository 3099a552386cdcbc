#pragma once
// The odometry's noise and bias, estimated online from the visual
// measurements, so that a user does not have to guess sigma_T and sigma_R.
//
// Two consistent measurements of one landmark, y1 at t1 and y2 at t2, give
// the robot's motion between t1 and t2 through the landmark's frame,
// V = y1^-1 (+) y2, independently of where the landmark is in the map (and
// largely of its 3-D structure's errors, which both measurements share). The
// odometry gives O = o1^-1 (+) o2 over the path length d and rotation a
// driven in between. Under the motion model (odometry/motion_model.hpp)
//   e_theta = wrap(V_theta - O_theta) = -b_h d + n,  var n = sigma_R^2 (d + a) + c_theta
//   e_along = (V_xy - O_xy) . O_xy/|O_xy| = n,       var n = sigma_T^2 d + c_xy
// where b_h is the heading bias per metre and c the measurements' own
// variance. The heading bias is a ratio estimate; each sigma the slope of a
// line of the squared residuals over d (+ a), robust to outliers
// (odometry_calibration.cpp), whose intercept takes up c. The
// odometry's scale bias is not observable here: a monocular landmark's
// depth, and so every measurement's length, comes from these same wheels'
// baselines (frontend/landmark_creation.hpp), so V_xy and O_xy carry the same
// scale. Pairs are non-overlapping (each measurement is in one pair), span
// min_travel..max_travel, and a window of the newest max_pairs is kept: the
// cost does not grow with the run.

#include <cstdint>
#include <deque>
#include <unordered_map>

#include "backend/pose_graph.hpp"
#include "odometry/motion_model.hpp"
#include "odometry/pose2.hpp"

namespace vslam::backend {

struct OdometryCalibrationParams {
  bool enabled = false;      // estimate (published in health)
  bool adopt = false;        // and use the estimates in the motion model once valid
  double min_travel = 0.3;   // a pair spans at least this much d + a (m + rad)...
  double max_travel = 3.0;   // ...and at most this much
  double max_span_s = 30.0;  // and at most this long
  // Residuals this large are not odometry noise (a look-alike, a bad
  // measurement): left out.
  double max_residual_m = 0.3;
  double max_residual_rad = 0.2;
  int min_pairs = 40;    // before an estimate is valid
  int max_pairs = 1000;  // window of the newest pairs
  // The adopted sigmas stay within these bounds.
  double min_sigma_translation = 0.005;
  double min_sigma_rotation = 0.005;
  double max_sigma_translation = 0.2;
  double max_sigma_rotation = 0.2;

  void validate() const;
};

struct OdometryNoiseEstimate {
  bool valid = false;
  int pairs = 0;
  double sigma_translation = 0;  // m / sqrt(m)
  double sigma_rotation = 0;     // rad / sqrt(m + rad)
  double heading_bias = 0;       // rad/m: the odometry's turn per metre beyond the robot's
};

class OdometryNoiseEstimator {
 public:
  explicit OdometryNoiseEstimator(OdometryCalibrationParams params);

  // A measurement the filter found consistent: the robot in the landmark's
  // frame at capture time, and the odometry then.
  // Returns whether it completed a pair.
  bool add(int64_t landmark_id, int64_t utime, const Pose2& relative, const OdometryAt& odometry);
  // The odometry's frame changed (a reset, a kidnapping): pairs must not span it.
  void breakOdometry() { open_.clear(); }
  OdometryNoiseEstimate estimate() const;
  // The motion model's noise from an estimate, within the configured bounds.
  MotionNoise adoptable(const OdometryNoiseEstimate& e) const;
  const OdometryCalibrationParams& params() const { return params_; }

 private:
  struct Open {
    int64_t utime;
    Pose2 relative;
    OdometryAt odometry;
  };
  struct Pair {
    double distance;  // d
    double travel;    // d + a
    double e_along;
    double e_theta;
  };
  OdometryCalibrationParams params_;
  std::unordered_map<int64_t, Open> open_;  // per landmark: the measurement awaiting its pair
  std::deque<Pair> pairs_;
};

}  // namespace vslam::backend
