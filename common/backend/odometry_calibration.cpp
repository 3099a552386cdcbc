#include "backend/odometry_calibration.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>
#include <vector>

#include "util/statistics.hpp"

namespace vslam::backend {

namespace {

// The line y = c + k x by least squares with c, k >= 0.
struct Line {
  double c = 0, k = 0;
};
Line nonNegativeLine(const std::vector<double>& x, const std::vector<double>& y) {
  const double n = static_cast<double>(x.size());
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    sx += x[i];
    sy += y[i];
    sxx += x[i] * x[i];
    sxy += x[i] * y[i];
  }
  if (n == 0) return {};
  const double det = n * sxx - sx * sx;
  if (det > 1e-12 * n * sxx) {
    const double k = (n * sxy - sx * sy) / det;
    const double c = (sy - k * sx) / n;
    if (k >= 0 && c >= 0) return {c, k};
    if (k < 0) return {std::max(0.0, sy / n), 0.0};  // flat: the mean
  }
  // Intercept at zero (or x without spread): the line through the origin.
  return {0.0, sxx > 0 ? std::max(0.0, sxy / sxx) : 0.0};
}

constexpr int kSpreadBins = 4;       // robustVarianceSlope's first groups
constexpr double kTrimSigmas = 3.0;  // ...and the residuals its line keeps
constexpr int kTrimRounds = 3;
// E[r^2 | |r| <= 3 sigma] / sigma^2 for a Gaussian r: 1 - 2 t phi(t) / (2 Phi(t) - 1), t = 3.
constexpr double kTrimmedVarianceFactor = 0.97334;

// The slope k of var(r) = c + k x, robust to the few look-alike or badly
// built landmarks' pairs that a sum of squares would take for odometry
// noise. A first line through kSpreadBins groups of equal count by x, each
// group's variance from its median absolute residual (1.4826 MAD about
// zero: a Gaussian's variance); then least squares over the pairs within
// kTrimSigmas of that line's sigma, which uses every inlier, as the groups'
// medians do not (they leave a small sigma_T under the measurements' noise
// unresolved).
double robustVarianceSlope(std::vector<std::pair<double, double>> xr) {
  std::sort(xr.begin(), xr.end());
  std::vector<double> x, y, abs_r;
  for (int b = 0; b < kSpreadBins; ++b) {
    const size_t from = xr.size() * static_cast<size_t>(b) / kSpreadBins;
    const size_t to = xr.size() * static_cast<size_t>(b + 1) / kSpreadBins;
    if (to <= from) continue;
    double sum_x = 0;
    abs_r.clear();
    for (size_t i = from; i < to; ++i) {
      sum_x += xr[i].first;
      abs_r.push_back(std::abs(xr[i].second));
    }
    const double sigma = 1.4826 * upperMedian(&abs_r);
    x.push_back(sum_x / static_cast<double>(to - from));
    y.push_back(sigma * sigma);
  }
  Line line = nonNegativeLine(x, y);
  for (int round = 0; round < kTrimRounds; ++round) {
    x.clear();
    y.clear();
    for (const auto& [xi, r] : xr) {
      if (r * r > kTrimSigmas * kTrimSigmas * (line.c + line.k * xi)) continue;
      x.push_back(xi);
      y.push_back(r * r / kTrimmedVarianceFactor);
    }
    if (x.size() < static_cast<size_t>(kSpreadBins)) break;
    line = nonNegativeLine(x, y);
  }
  return line.k;
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
  pairs_.push_back({d, travel, e_along, e_theta});
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
  // The residuals are vision minus odometry; the bias is what the odometry
  // adds (the simulator's heading_bias): a ratio estimate over the pairs.
  double sum_theta = 0, sum_d = 0;
  for (const Pair& p : pairs_) {
    sum_theta += p.e_theta;
    sum_d += p.distance;
  }
  e.heading_bias = sum_d > 0 ? -sum_theta / sum_d : 0.0;
  // The sigmas include the bias's share of the error (zero-centred
  // spreads): the motion model has no bias term, so its noise must cover it.
  std::vector<std::pair<double, double>> theta, along;
  for (const Pair& p : pairs_) {
    theta.emplace_back(p.travel, p.e_theta);
    along.emplace_back(p.distance, p.e_along);
  }
  e.sigma_rotation = std::sqrt(robustVarianceSlope(std::move(theta)));
  e.sigma_translation = std::sqrt(robustVarianceSlope(std::move(along)));
  e.valid = true;
  return e;
}

}  // namespace vslam::backend
