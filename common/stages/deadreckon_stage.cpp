#include "stages/deadreckon_stage.hpp"

#include <vslam/pose_estimate_t.hpp>

#include "util/log.hpp"

namespace vslam::stages {

const config::ParamTable<DeadReckonParams>& DeadReckonParams::table() {
  static const config::ParamTable<DeadReckonParams> declared = [] {
    config::ParamTable<DeadReckonParams> t;
    t.add(
         "sigma_translation", [](auto& p) -> auto& { return p.noise.sigma_translation; },
         config::nonNegative(), "m/√m", "σ_T: translation noise, variance σ_T²·distance")
        .required()
        .add(
            "sigma_rotation", [](auto& p) -> auto& { return p.noise.sigma_rotation; },
            config::nonNegative(), "rad/√(m or rad)",
            "σ_R: heading noise, variance σ_R²·(distance + rotation)")
        .required()
        .add("max_step_m", &DeadReckonParams::max_step_m, config::positive(), "m",
             "larger jumps between two readings are faults: reference reset, no motion")
        .add("max_step_deg", &DeadReckonParams::max_step_deg, config::InRange{1, 180}, "deg",
             "same for rotation")
        .add("odometry_timeout_s", &DeadReckonParams::odometry_timeout_s,
             config::InRange{0.05, 3600}, "s",
             "odometry quieter than this (the stage's clock) is logged once and raises health to "
             "WARN until it resumes");
    return t;
  }();
  return declared;
}

DeadReckonParams DeadReckonParams::load(const config::ConfigNode& node,
                                        const config::RobotConfig& robot) {
  DeadReckonParams p;
  table().load(node, p);
  p.odometry_channel = robot.channels.odometry;
  p.pose_channel = robot.channels.pose_odometry;
  return p;
}

DeadReckonStage::DeadReckonStage(DeadReckonParams params)
    : params_(std::move(params)), increments_(params_.max_step_m, degToRad(params_.max_step_deg)) {}

void DeadReckonStage::start(bus::StageContext& ctx) {
  ctx_ = &ctx;
  odometry_watchdog_ = std::make_unique<bus::InputWatchdog>(
      "odometry on " + params_.odometry_channel, "odometry_age_s", params_.odometry_timeout_s,
      ": the dead-reckoned pose does not move");
  odometry_watchdog_->begin(ctx.clock.now());
  ctx.bus.subscribe<vslam::odometry_t>(params_.odometry_channel,
                                       [this](const vslam::odometry_t& m) { onOdometry(m); });
}

void DeadReckonStage::onOdometry(const vslam::odometry_t& msg) {
  odometry_watchdog_->arrived(ctx_->clock.now(), msg.utime);
  Pose2 step;
  const auto outcome = increments_.add({msg.utime, msg.seq, {msg.x, msg.y, msg.theta}}, &step);
  switch (outcome) {
    case OdometryIncrements::Outcome::kStep:
      estimate_.apply(step, params_.noise.stepCovariance(step));
      distance_m_ += std::hypot(step.x, step.y);
      ++period_steps_;
      break;
    case OdometryIncrements::Outcome::kFirst:
      break;
    case OdometryIncrements::Outcome::kInvalid:
      ctx_->bus.reportMalformed(
          params_.odometry_channel,
          "odometry seq " + std::to_string(msg.seq) + " has a non-finite pose");
      return;
    case OdometryIncrements::Outcome::kStale:
      ++ignored_;
      ctx_->bus.countDropped();
      return;
    case OdometryIncrements::Outcome::kReset:
    case OdometryIncrements::Outcome::kImplausible:
      log::warn("odometry seq ", msg.seq, ": ", OdometryIncrements::describe(outcome));
      ++ignored_;
      return;
  }

  vslam::pose_estimate_t out;
  out.utime = msg.utime;
  out.seq = seq_++;
  out.estimator = ctx_->instance;
  out.x = estimate_.pose().x;
  out.y = estimate_.pose().y;
  out.theta = estimate_.pose().theta;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.covariance[r * 3 + c] = estimate_.covariance()(r, c);
  }
  out.odom_x = msg.x;
  out.odom_y = msg.y;
  out.odom_theta = msg.theta;
  out.num_particles = 0;
  out.effective_sample_size = 0;
  out.kidnapped = false;
  ctx_->bus.publish(params_.pose_channel, out);
}

void DeadReckonStage::collectHealth(bus::HealthReport& report) {
  if (odometry_watchdog_) odometry_watchdog_->report(ctx_->clock.now(), report);
  report.add("steps", static_cast<double>(period_steps_), "count");
  report.add("ignored_readings", static_cast<double>(ignored_), "count");
  report.add("distance", distance_m_, "m");
  report.add("position_sigma",
             std::sqrt(estimate_.covariance()(0, 0) + estimate_.covariance()(1, 1)), "m");
  period_steps_ = 0;
}

void registerDeadReckon(bus::StageRegistry& registry) {
  registry.add(
      "deadreckon",
      [](const bus::StageSetup& setup) {
        return std::make_unique<DeadReckonStage>(
            DeadReckonParams::load(setup.params, setup.stack.robot));
      },
      bus::describeWith(DeadReckonParams::table()));
}

}  // namespace vslam::stages
