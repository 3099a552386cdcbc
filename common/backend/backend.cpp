#include "backend/backend.hpp"

#include <cmath>
#include <stdexcept>

namespace vslam::backend {

const char* toString(MeasurementUse u) {
  switch (u) {
    case MeasurementUse::kUsed:
      return "used";
    case MeasurementUse::kRejected:
      return "rejected by the pre-filter";
    case MeasurementUse::kInvalidLandmark:
      return "invalid landmark id";
    case MeasurementUse::kNoOdometry:
      return "no odometry yet";
    case MeasurementUse::kTooOld:
      return "older than the odometry history";
    case MeasurementUse::kTooNew:
      return "newer than the newest odometry";
    case MeasurementUse::kThinned:
      return "too soon after the landmark's last used measurement";
  }
  return "?";
}

void BackendParams::validate() const {
  filter.validate();
  prefilter.validate();
  if (!(max_step_m > 0) || !(max_step_rad > 0))
    throw std::invalid_argument("backend: max_step_m and max_step_rad must be > 0");
  if (!(measurement_sigma_xy_per_m >= 0) || !(measurement_sigma_theta_rad_per_m >= 0))
    throw std::invalid_argument("backend: measurement sigma growth rates must be >= 0");
  if (!(landmark_min_interval_s >= 0))
    throw std::invalid_argument("backend: landmark_min_interval_s must be >= 0");
  if (!(max_measurement_age_s > 0) || !(max_measurement_lead_s >= 0))
    throw std::invalid_argument(
        "backend: max_measurement_age_s must be > 0 and max_measurement_lead_s >= 0");
}

Backend::Backend(BackendParams params)
    : params_((params.validate(), std::move(params))),
      filter_(params_.filter),
      increments_(params_.max_step_m, params_.max_step_rad) {}

OdometryIncrements::Outcome Backend::addOdometry(const OdometryReading& reading) {
  Pose2 step;
  const auto outcome = increments_.add(reading, &step);
  switch (outcome) {
    case OdometryIncrements::Outcome::kStep:
      filter_.predict(step);
      ++counters_.odometry_steps;
      break;
    case OdometryIncrements::Outcome::kFirst:
      break;
    case OdometryIncrements::Outcome::kReset:
    case OdometryIncrements::Outcome::kImplausible:
      // A new odometry frame: the history no longer relates to it.
      history_.clear();
      ++counters_.odometry_ignored;
      break;
    case OdometryIncrements::Outcome::kStale:
    case OdometryIncrements::Outcome::kInvalid:
      ++counters_.odometry_ignored;
      return outcome;
  }
  history_.push_back(reading);
  const int64_t keep_us = static_cast<int64_t>(params_.max_measurement_age_s * 1e6);
  while (history_.size() > 2 && history_.front().utime < reading.utime - keep_us) {
    history_.pop_front();
  }
  return outcome;
}

std::optional<Pose2> Backend::odometryAt(int64_t utime, MeasurementUse* why) const {
  if (history_.empty()) {
    *why = MeasurementUse::kNoOdometry;
    return std::nullopt;
  }
  const OdometryReading& newest = history_.back();
  if (utime >= newest.utime) {
    if (static_cast<double>(utime - newest.utime) > params_.max_measurement_lead_s * 1e6) {
      *why = MeasurementUse::kTooNew;
      return std::nullopt;
    }
    return newest.pose;  // at most a little ahead: the robot's newest known pose
  }
  if (utime < history_.front().utime) {
    *why = MeasurementUse::kTooOld;
    return std::nullopt;
  }
  // history_ is in increasing utime (readings with non-increasing seq are dropped,
  // and seq increases with time); find the bracketing pair.
  size_t hi = history_.size() - 1;
  while (hi > 0 && history_[hi - 1].utime > utime) --hi;
  const OdometryReading& a = history_[hi - 1];
  const OdometryReading& b = history_[hi];
  const double span = static_cast<double>(b.utime - a.utime);
  const double f = span > 0 ? static_cast<double>(utime - a.utime) / span : 1.0;
  const Pose2 d = a.pose.between(b.pose);
  return a.pose.compose({f * d.x, f * d.y, f * d.theta});
}

MeasurementResult Backend::addMeasurement(const MeasurementInput& m) {
  MeasurementResult result;
  result.status =
      prefilter({m.relative, m.proj_err_rms_px, m.num_points, m.slope}, params_.prefilter);
  ++counters_.status[static_cast<int>(result.status)];
  auto finish = [&](MeasurementUse use) {
    result.use = use;
    ++counters_.use[static_cast<int>(use)];
    return result;
  };
  if (result.status != MeasurementStatus::kAccepted) return finish(MeasurementUse::kRejected);
  if (m.landmark_id < 0) return finish(MeasurementUse::kInvalidLandmark);

  MeasurementUse why = MeasurementUse::kUsed;
  const std::optional<Pose2> then = odometryAt(m.utime, &why);
  if (!then) return finish(why);
  if (params_.landmark_min_interval_s > 0) {
    const auto last = last_used_.find(m.landmark_id);
    const auto min_us = static_cast<int64_t>(params_.landmark_min_interval_s * 1e6);
    if (last != last_used_.end() && m.utime >= last->second && m.utime - last->second < min_us)
      return finish(MeasurementUse::kThinned);
    last_used_[m.landmark_id] = m.utime;
  }
  // Move the measurement to the particles' time: y_now = y (+) D.
  const Pose2 d = then->between(history_.back().pose);
  const Pose2& y = m.relative;
  Observation obs;
  obs.landmark_id = m.landmark_id;
  obs.relative = y.compose(d);
  const double c = std::cos(y.theta), s = std::sin(y.theta);
  Eigen::Matrix3d jy;              // d(y (+) D)/dy
  jy << 1, 0, -s * d.x - c * d.y,  //
      0, 1, c * d.x - s * d.y,     //
      0, 0, 1;
  Eigen::Matrix3d jd;  // d(y (+) D)/dD
  jd << c, -s, 0,      //
      s, c, 0,         //
      0, 0, 1;
  Eigen::Matrix3d r = params_.filter.measurementCovariance();
  const double dist = std::hypot(y.x, y.y);
  r(0, 0) += std::pow(params_.measurement_sigma_xy_per_m * dist, 2);
  r(1, 1) += std::pow(params_.measurement_sigma_xy_per_m * dist, 2);
  r(2, 2) += std::pow(params_.measurement_sigma_theta_rad_per_m * dist, 2);
  obs.covariance =
      jy * r * jy.transpose() + jd * params_.filter.motion.stepCovariance(d) * jd.transpose();

  result.update = filter_.update(obs);
  counters_.landmarks_initialized += result.update.kind == UpdateKind::kInitialized;
  counters_.kidnaps_detected += result.update.kidnap_detected;
  counters_.recoveries += result.update.recovered;
  counters_.resamplings += result.update.resampled;
  return finish(MeasurementUse::kUsed);
}

}  // namespace vslam::backend
