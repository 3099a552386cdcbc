#include "sim/odometry_sim.hpp"

namespace vslam::sim {

OdometrySimulator::OdometrySimulator(const OdometryParams& params, uint64_t seed)
    : params_(params), noise_{params.sigma_translation, params.sigma_rotation}, rng_(seed) {}

void OdometrySimulator::addStep(const Pose2& true_step, double t) {
  Pose2 measured = true_step;
  for (const SlipEvent& slip : params_.slips) {
    if (t >= slip.at_s && t < slip.at_s + slip.duration_s) {
      measured.x *= slip.translation_factor;
      measured.y *= slip.translation_factor;
      measured.theta *= slip.rotation_factor;
    }
  }
  // Unequal wheels turn the reported heading in proportion to the distance
  // the wheels roll (so not during a slip that stops them), forwards or back.
  measured.theta +=
      params_.heading_bias * std::copysign(std::hypot(measured.x, measured.y), measured.x);
  measured.x *= 1.0 + params_.scale_bias;
  measured.y *= 1.0 + params_.scale_bias;
  const double n_translation = n01_(rng_);
  const double n_rotation = n01_(rng_);
  measured = noise_.perturb(measured, n_translation, n_rotation);
  pose_ = pose_.compose(measured);
  distance_ += std::hypot(measured.x, measured.y);
  rotation_ += std::abs(measured.theta);
  last_step_ = measured;
}

void OdometrySimulator::setPose(const Pose2& pose) {
  const Pose2 step = pose_.between(pose);
  distance_ += std::hypot(step.x, step.y);
  rotation_ += std::abs(step.theta);
  last_step_ = step;
  pose_ = pose;
}

}  // namespace vslam::sim
