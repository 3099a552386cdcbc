#include "backend/odometry_calibration.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace vslam::backend {

namespace {

// The line r2 = c + k x by least squares with c, k >= 0; returns k.
double nonNegativeSlope(const std::vector<double>& x, const std::vector<double>& r2) {
  const double n = static_cast<double>(x.size());
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    sx += x[i];
    sy += r2[i];
    sxx += x[i] * x[i];
    sxy += x[i] * r2[i];
  }
  const double det = n * sxx - sx * sx;
  if (det > 1e-12 * n * sxx) {
    const double k = (n * sxy - sx * sy) / det;
    const double c = (sy - k * sx) / n;
    if (k >= 0 && c >= 0) return k;
    if (k < 0) return 0;
  }
  // Intercept at zero (or x without spread): the line through the origin.
  return sxx > 0 ? std::max(0.0, sxy / sxx) : 0.0;
}

}  // namespace

void OdometryCalibrationParams::validate() const {
  if (!(min_travel > 0 && max_travel > min_travel && max_span_s > 0))
    throw std::invalid_argument(
        "backend: odometry_calibration needs 0 < min_travel < max_travel and max_span_s > 0");
  if (!(max_residual_m > 0 && max_residual_rad > 0))
    throw std::invalid_argument("backend: odometry_calibration residual bounds must be > 0");
  if (!(min_pairs >= 3 && max_pairs >= min_pairs))
    throw std::invalid_argument("backend: odometry_calibration needs 3 <= min_pairs <= max_pairs");
  if (!(min_sigma_translation > 0 && max_sigma_translation >= min_sigma_translation &&
        min_sigma_rotation > 0 && max_sigma_rotation >= min_sigma_rotation))
    throw std::invalid_argument(
        "backend: odometry_calibration sigma bounds must be 0 < min <= max");
}

OdometryNoiseEstimator::OdometryNoiseEstimator(OdometryCalibrationParams params)
    : params_(std::move(params)) {
  params_.validate();
}

bool OdometryNoiseEstimator::add(int64_t landmark_id, int64_t utime, const Pose2& relative,
                                 const OdometryAt& odometry) {
  const auto it = open_.find(landmark_id);
  if (it == open_.end()) {
    open_.emplace(landmark_id, Open{utime, relative, odometry});
    return false;
  }
  Open& first = it->second;
  const double d = odometry.distance_m - first.odometry.distance_m;
  const double travel = d + odometry.rotation_rad - first.odometry.rotation_rad;
  const double span_s = 1e-6 * static_cast<double>(utime - first.utime);
  if (span_s < 0 || span_s > params_.max_span_s || travel > params_.max_travel) {
    first = Open{utime, relative, odometry};  // too far apart: start a new pair here
    return false;
  }
  if (travel < params_.min_travel) return false;  // wait for more motion
  const Pose2 visual = first.relative.between(relative);
  const Pose2 odo = first.odometry.pose.between(odometry.pose);
  const double length = std::hypot(odo.x, odo.y);
  const double e_theta = wrapAngle(visual.theta - odo.theta);
  const double e_along =
      length > 1e-6 ? ((visual.x - odo.x) * odo.x + (visual.y - odo.y) * odo.y) / length : 0.0;
  open_.erase(it);  // non-overlapping pairs: the next one starts afresh
  if (std::abs(e_theta) > params_.max_residual_rad || std::abs(e_along) > params_.max_residual_m)
    return false;
  pairs_.push_back({d, travel, length, e_along, e_theta});
  while (static_cast<int>(pairs_.size()) > params_.max_pairs) pairs_.pop_front();
  return true;
}

MotionNoise OdometryNoiseEstimator::adoptable(const OdometryNoiseEstimate& e) const {
  const OdometryCalibrationParams& p = params_;
  return {std::clamp(e.sigma_translation, p.min_sigma_translation, p.max_sigma_translation),
          std::clamp(e.sigma_rotation, p.min_sigma_rotation, p.max_sigma_rotation)};
}

OdometryNoiseEstimate OdometryNoiseEstimator::estimate() const {
  OdometryNoiseEstimate e;
  e.pairs = static_cast<int>(pairs_.size());
  if (e.pairs < params_.min_pairs) return e;
  double sum_theta = 0, sum_d = 0, sum_along_len = 0, sum_len2 = 0;
  for (const Pair& p : pairs_) {
    sum_theta += p.e_theta;
    sum_d += p.distance;
    sum_along_len += p.e_along * p.odometry_length;
    sum_len2 += p.odometry_length * p.odometry_length;
  }
  // The residuals are vision minus odometry; the biases are what the
  // odometry adds (the simulator's scale_bias and heading_bias).
  e.heading_bias = sum_d > 0 ? -sum_theta / sum_d : 0.0;
  e.scale_bias = sum_len2 > 0 ? -sum_along_len / sum_len2 : 0.0;
  // The sigmas include the biases' share of the error: the motion model has
  // no bias term, so its noise must cover them.
  std::vector<double> travel, distance, r2_theta, r2_along;
  for (const Pair& p : pairs_) {
    travel.push_back(p.travel);
    distance.push_back(p.distance);
    r2_theta.push_back(p.e_theta * p.e_theta);
    r2_along.push_back(p.e_along * p.e_along);
  }
  e.sigma_rotation = std::sqrt(nonNegativeSlope(travel, r2_theta));
  e.sigma_translation = std::sqrt(nonNegativeSlope(distance, r2_along));
  e.valid = true;
  return e;
}

}  // namespace vslam::backend
