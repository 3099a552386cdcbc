#pragma once
// Odometry handling shared by every consumer of vslam.odometry_t.
//
// Odometry arrives as the cumulative dead-reckoned pose, so the motion
// between two readings is the difference of their poses: a lost message loses
// no motion, and a duplicated or out-of-order one (seq not above the last) is
// ignored. A base driver restart (seq going back to a small number with the
// pose jumping) resets the reference without inventing motion.
//
// Noise model (vSLAM paper, section 6: nonholonomic drive, parameters sigma_T
// and sigma_R). The error of a motion step grows with the step, with
// variances proportional to its length so that the accumulated uncertainty
// does not depend on the odometry rate:
//   var(translation) = sigma_T^2 * |d|                 sigma_T in m / sqrt(m)
//   var(rotation)    = sigma_R^2 * (|d| + |dtheta|)    sigma_R in rad / sqrt(m or rad)
// where d is the distance driven and dtheta the rotation of the step; the
// rotation term makes heading drift while driving straight as well as when
// turning on the spot. Translation error acts along the direction of travel.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>

#include "odometry/pose2.hpp"

namespace vslam {

// Covariance of a step's (dx, dy, dtheta) in the robot frame at its start
// whose translation errs along the direction of travel (the chord of the
// step) with variance var_translation, and whose heading with var_rotation.
Eigen::Matrix3d alongTrackCovariance(const Pose2& step, double var_translation,
                                     double var_rotation);

struct MotionNoise {
  double sigma_translation = 0.0;  // sigma_T, m / sqrt(m)
  double sigma_rotation = 0.0;     // sigma_R, rad / sqrt(m or rad)

  // Covariance of the step's (dx, dy, dtheta) in the robot frame at the step's start.
  Eigen::Matrix3d stepCovariance(const Pose2& step) const;
  // The step with noise drawn from that covariance, given two standard normal
  // draws: n_translation along the direction of travel, n_rotation on the
  // heading. (Sampling through a matrix square root of the rank-deficient
  // covariance would turn rounding into NaNs.)
  Pose2 perturb(const Pose2& step, double n_translation, double n_rotation) const;

  // perturb() for many draws of one step (the particle filter's motion
  // step): what does not depend on the draws is computed once.
  class StepNoise {
   public:
    StepNoise(const MotionNoise& noise, const Pose2& step);
    Pose2 perturb(double n_translation, double n_rotation) const {
      const double e_t = sigma_t_ * n_translation;
      return {step_.x + cos_heading_ * e_t, step_.y + sin_heading_ * e_t,
              step_.theta + sigma_r_ * n_rotation};
    }

   private:
    Pose2 step_;
    double sigma_t_, sigma_r_;          // the step's translation and rotation sigmas
    double cos_heading_, sin_heading_;  // the direction of travel
  };
};

// Dead-reckoned pose with first-order covariance propagation:
//   x' = x (+) u,  P' = F P F^T + G Q G^T
// with F = d(x (+) u)/dx and G = d(x (+) u)/du.
class PoseWithCovariance {
 public:
  PoseWithCovariance() { covariance_.setZero(); }
  PoseWithCovariance(const Pose2& pose, const Eigen::Matrix3d& covariance)
      : pose_(pose), covariance_(covariance) {}
  void apply(const Pose2& step, const Eigen::Matrix3d& step_covariance);
  const Pose2& pose() const { return pose_; }
  const Eigen::Matrix3d& covariance() const { return covariance_; }

 private:
  Pose2 pose_;
  Eigen::Matrix3d covariance_;
};

struct OdometryReading {
  int64_t utime = 0;
  int64_t seq = 0;
  Pose2 pose;  // cumulative pose in the odometry frame
};

// Turns cumulative odometry into motion steps.
class OdometryIncrements {
 public:
  enum class Outcome {
    kFirst,       // first reading: reference set, no step
    kStep,        // a step is available
    kStale,       // duplicate or out of order: ignored
    kInvalid,     // non-finite pose: ignored
    kReset,       // the driver restarted (seq went back): new reference, no step
    kImplausible  // a jump larger than max_step: new reference, no step
  };

  // max_step_m / max_step_rad bound a plausible step between two readings;
  // anything larger is a driver fault or a restart, not motion.
  OdometryIncrements(double max_step_m = 1.0, double max_step_rad = M_PI);

  // On kStep, *step is the motion in the robot frame of the previous reading.
  Outcome add(const OdometryReading& reading, Pose2* step);
  const std::optional<OdometryReading>& last() const { return last_; }
  static const char* describe(Outcome outcome);

 private:
  double max_step_m_;
  double max_step_rad_;
  std::optional<OdometryReading> last_;
};

}  // namespace vslam
