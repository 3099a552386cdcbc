#pragma once
// The back-end as the stage drives it, without LCM: cumulative odometry in,
// visual measurements in (pre-filter, alignment in time, particle filter
// update), estimates out, with counts of everything that was used or not.
//
//   Backend be(BackendParams{...});
//   be.addOdometry({utime, seq, odom_pose});         // every ODOMETRY message
//   MeasurementResult r = be.addMeasurement(m);      // every VISUAL_MEASUREMENT
//   r.status                                         // pre-filter verdict to republish
//   be.filter().estimate();                          // pose, covariance, ESS, kidnapped
//
// Time alignment. The particles are at the time of the newest odometry
// reading; a measurement is of the robot at its image's capture time, a
// little earlier (the front-end's latency) or, live, sometimes later. With
// the odometry of the last max_measurement_age_s kept, the measurement is
// moved to the particles' time by the odometry motion in between:
//   y_now = y (+) D,   D = odom(t_image)^-1 (+) odom(t_now)
// (interpolated at t_image), with covariance J_y R J_y^T + J_D Q(D) J_D^T.
// Older measurements, and ones more than max_measurement_lead_s newer than
// the newest odometry, are not used (counted).

#include <array>
#include <cstdint>
#include <deque>
#include <optional>
#include <unordered_map>

#include "backend/particle_filter.hpp"
#include "backend/prefilter.hpp"
#include "odometry/motion_model.hpp"

namespace vslam::backend {

struct BackendParams {
  FilterParams filter;
  PrefilterParams prefilter;
  double max_step_m = 1.0;  // odometry jumps larger than this are faults, not motion
  double max_step_rad = M_PI / 2;
  double max_measurement_age_s = 5.0;   // odometry history kept to align measurements
  double max_measurement_lead_s = 0.5;  // newer than the newest odometry by more: not used
  // Measurements of one landmark closer in time than this to the last one
  // used are not used (kThinned): a landmark measured at camera rate gives
  // errors that are strongly correlated (they share the landmark's own 3-D
  // error), and treating them as independent makes the weights and the
  // landmark filters overconfident. 0: use every measurement.
  double landmark_min_interval_s = 0.0;
  // Sigma_vis growing with the distance d = |(y_x, y_y)| from the landmark's
  // creation pose: sigma_xy = sqrt(s0^2 + (k d)^2), likewise for theta. A
  // landmark's 3-D points carry depth errors (triangulated over a short
  // odometry baseline), so the measured pose errs roughly in proportion to
  // how far the robot is from where the landmark was built. 0: the paper's
  // constant Sigma_vis.
  double measurement_sigma_xy_per_m = 0.0;
  double measurement_sigma_theta_rad_per_m = 0.0;

  void validate() const;
};

struct MeasurementInput {
  int64_t utime = 0;  // capture time of the image, microseconds
  int64_t landmark_id = 0;
  Pose2 relative;  // y: robot now in the landmark's creation frame
  double proj_err_rms_px = 0;
  int num_points = 0;
  double slope = 0;
};

// What happened to a measurement after the pre-filter.
enum class MeasurementUse {
  kUsed,             // updated the filter (or initialised its landmark)
  kRejected,         // pre-filter rejected it (MeasurementResult::status says why)
  kInvalidLandmark,  // landmark id < 0
  kNoOdometry,       // no odometry yet to place it in time
  kTooOld,           // older than the odometry history
  kTooNew,           // newer than the newest odometry by more than max_measurement_lead_s
  kThinned,          // within landmark_min_interval_s of the landmark's last used measurement
};
constexpr int kNumMeasurementUse = 7;
const char* toString(MeasurementUse u);

struct MeasurementResult {
  MeasurementStatus status = MeasurementStatus::kUnfiltered;  // pre-filter verdict
  MeasurementUse use = MeasurementUse::kRejected;
  UpdateReport update;  // valid when use == kUsed
};

struct BackendCounters {
  std::array<int64_t, kNumMeasurementStatus> status{};  // by MeasurementStatus
  std::array<int64_t, kNumMeasurementUse> use{};        // by MeasurementUse
  int64_t landmarks_initialized = 0;
  int64_t kidnaps_detected = 0;
  int64_t recoveries = 0;
  int64_t resamplings = 0;
  int64_t odometry_steps = 0;
  int64_t odometry_ignored = 0;  // stale, invalid, reset, implausible
};

class Backend {
 public:
  explicit Backend(BackendParams params);

  OdometryIncrements::Outcome addOdometry(const OdometryReading& reading);
  MeasurementResult addMeasurement(const MeasurementInput& m);

  const ParticleFilter& filter() const { return filter_; }
  ParticleFilter& filter() { return filter_; }
  const BackendCounters& counters() const { return counters_; }
  // The newest odometry reading the particles are at (none before the first).
  const std::optional<OdometryReading>& lastOdometry() const { return increments_.last(); }

 private:
  // The odometry pose at `utime` from the history (linear interpolation), or
  // nothing if outside it.
  std::optional<Pose2> odometryAt(int64_t utime, MeasurementUse* why) const;

  BackendParams params_;
  ParticleFilter filter_;
  OdometryIncrements increments_;
  std::deque<OdometryReading> history_;  // accepted readings, oldest first
  std::unordered_map<int64_t, int64_t>
      last_used_;  // landmark id -> utime of its last used measurement
  BackendCounters counters_;
};

}  // namespace vslam::backend
