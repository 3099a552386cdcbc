#include "eval/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "eval/errors.hpp"
#include "util/statistics.hpp"

namespace vslam::eval {
namespace {

std::string span(const Trajectory& t) {
  std::ostringstream os;
  os.precision(3);
  os << std::fixed << "[" << t.poses.front().t << ", " << t.poses.back().t << "] s";
  return os.str();
}

}  // namespace

ErrorStats computeStats(const std::vector<double>& values) {
  ErrorStats s;
  s.count = values.size();
  if (values.empty()) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    s.rmse = s.mean = s.median = s.std = s.min = s.max = nan;
    return s;
  }
  const double n = static_cast<double>(values.size());
  double sum = 0, sum_sq = 0;
  for (const double v : values) {
    sum += v;
    sum_sq += v * v;
  }
  s.mean = sum / n;
  s.rmse = std::sqrt(sum_sq / n);
  double var = 0;
  for (const double v : values) var += (v - s.mean) * (v - s.mean);
  s.std = std::sqrt(var / n);
  s.median = median(values);
  const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
  s.min = *lo;
  s.max = *hi;
  return s;
}

AteResult computeAte(const Trajectory& ref, const Trajectory& est, double offset, double max_diff,
                     AlignMode mode) {
  if (ref.empty()) throw DataError("reference " + ref.name + " has no poses");
  if (est.empty()) throw DataError("estimate " + est.name + " has no poses");
  AteResult r;
  r.matches = associate(ref.stamps(), est.stamps(), offset, max_diff);
  if (r.matches.empty()) {
    std::ostringstream os;
    os << "no associated poses: no stamp of " << est.name << " " << span(est) << " (offset "
       << offset << " s) is within max-diff " << max_diff << " s of a stamp of " << ref.name << " "
       << span(ref) << "; check --offset and --max-diff";
    throw DataError(os.str());
  }
  std::vector<Eigen::Vector3d> est_p, ref_p;
  for (const auto& m : r.matches) {
    est_p.push_back(est.poses[m.est].position);
    ref_p.push_back(ref.poses[m.ref].position);
  }
  r.alignment = mode == AlignMode::kOrigin ? alignOrigin(est.poses[r.matches.front().est],
                                                         ref.poses[r.matches.front().ref])
                                           : alignPositions(est_p, ref_p, mode);
  r.errors.reserve(r.matches.size());
  r.heading_errors.reserve(r.matches.size());
  const Eigen::Quaterniond align_q(r.alignment.R);
  for (std::size_t i = 0; i < est_p.size(); ++i) {
    r.errors.push_back((r.alignment.apply(est_p[i]) - ref_p[i]).norm());
    const double d = headingOf(align_q * est.poses[r.matches[i].est].orientation) -
                     headingOf(ref.poses[r.matches[i].ref].orientation);
    r.heading_errors.push_back(std::abs(std::remainder(d, 2.0 * M_PI)));
  }
  r.stats = computeStats(r.errors);
  r.heading = computeStats(r.heading_errors);
  return r;
}

std::optional<DeltaUnit> parseDeltaUnit(const std::string& word) {
  if (word == "s") return DeltaUnit::kSeconds;
  if (word == "m") return DeltaUnit::kMetres;
  return std::nullopt;
}

std::string toString(DeltaUnit unit) { return unit == DeltaUnit::kSeconds ? "s" : "m"; }

RpeResult computeRpe(const Trajectory& ref, const Trajectory& est, const RpeOptions& options) {
  RpeResult r;
  if (ref.size() < 2 || est.size() < 2) {
    r.trans = computeStats({});
    r.rot = computeStats({});
    return r;
  }
  const std::vector<double> ref_t = ref.stamps();
  const std::vector<double> est_t = est.stamps();

  // The quantity delta is measured in, per estimate pose.
  std::vector<double> index = est_t;
  if (options.unit == DeltaUnit::kMetres) {
    index[0] = 0;
    for (std::size_t i = 1; i < est.size(); ++i) {
      index[i] = index[i - 1] + (est.poses[i].position - est.poses[i - 1].position).norm();
    }
  }

  std::vector<double> intervals;
  for (std::size_t i = 1; i < ref_t.size(); ++i) intervals.push_back(ref_t[i] - ref_t[i - 1]);
  r.ref_max_time_diff = 2 * median(intervals);

  std::vector<double> trans, rot;
  const std::size_t last = est.size() - 1;
  for (std::size_t i = 0; i < est.size(); ++i) {
    const std::size_t j = findClosestIndex(index, index[i] + options.delta);
    if (j == last || j == i) continue;
    const double s0 = est_t[i] + options.offset, s1 = est_t[j] + options.offset;
    const std::size_t g0 = findClosestIndex(ref_t, s0);
    const std::size_t g1 = findClosestIndex(ref_t, s1);
    if (std::abs(ref_t[g0] - s0) > r.ref_max_time_diff ||
        std::abs(ref_t[g1] - s1) > r.ref_max_time_diff) {
      continue;
    }
    const Eigen::Isometry3d est_rel = est.poses[i].isometry().inverse() * est.poses[j].isometry();
    const Eigen::Isometry3d ref_rel = ref.poses[g0].isometry().inverse() * ref.poses[g1].isometry();
    const Eigen::Isometry3d E = est_rel * ref_rel.inverse();
    RpePair p;
    p.t_est0 = est_t[i];
    p.t_est1 = est_t[j];
    p.t_ref0 = ref_t[g0];
    p.t_ref1 = ref_t[g1];
    p.trans = E.translation().norm();
    p.rot = std::acos(std::clamp((E.linear().trace() - 1.0) / 2.0, -1.0, 1.0));
    r.pairs.push_back(p);
    trans.push_back(p.trans);
    rot.push_back(p.rot);
  }
  r.trans = computeStats(trans);
  r.rot = computeStats(rot);
  return r;
}

}  // namespace vslam::eval
