#include "eval/measurement_eval.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <optional>
#include <ostream>
#include <set>

#include "eval/errors.hpp"
#include "eval/output_file.hpp"
#include "odometry/pose2.hpp"

namespace vslam::eval {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

// Planar ground truth interpolated at t; nullopt outside the trajectory or
// across a gap longer than max_gap.
class PlanarTruth {
 public:
  PlanarTruth(const Trajectory& ref, double max_gap) : max_gap_(max_gap) {
    for (const auto& p : ref.poses) {
      t_.push_back(p.t);
      pose_.push_back({p.position.x(), p.position.y(), headingOf(p.orientation)});
    }
  }

  std::optional<Pose2> at(double t) const {
    if (t_.empty() || t < t_.front() || t > t_.back()) return std::nullopt;
    const auto hi =
        static_cast<std::size_t>(std::lower_bound(t_.begin(), t_.end(), t) - t_.begin());
    if (t_[hi] == t) return pose_[hi];
    const std::size_t lo = hi - 1;
    const double span = t_[hi] - t_[lo];
    if (span > max_gap_ + 1e-9) return std::nullopt;  // a gap, not the sampling rate
    return interpolate(pose_[lo], pose_[hi], (t - t_[lo]) / span);
  }

 private:
  double max_gap_;
  std::vector<double> t_;
  std::vector<Pose2> pose_;
};

ErrorSummary summarize(const std::vector<const ScoredMeasurement*>& scored) {
  std::vector<double> xy, heading;
  for (const auto* s : scored) {
    xy.push_back(s->xy_error_m);
    heading.push_back(s->heading_error_rad);
  }
  return {computeStats(xy), computeStats(heading)};
}

std::string fmt(const char* format, double v) {
  if (!std::isfinite(v)) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, v);
  return buf;
}

std::string percent(int64_t part, int64_t whole) {
  return whole > 0 ? fmt("%.2f%%", 100.0 * static_cast<double>(part) / static_cast<double>(whole))
                   : "n/a";
}

std::string edge(double cm) { return fmt("%g", cm); }

// Bins [0, e0), [e0, e1), ..., [e_last, inf).
std::vector<MeasurementErrorBin> binsOf(const std::vector<double>& edges) {
  std::vector<MeasurementErrorBin> bins;
  double low = 0;
  for (const double high : edges) {
    bins.push_back({low, high});
    low = high;
  }
  bins.push_back({low, std::numeric_limits<double>::infinity()});
  return bins;
}

// Fills each bin with the accepted measurements whose key falls in it
// (key NaN: none).
void fillBins(std::vector<MeasurementErrorBin>* bins,
              const std::vector<const ScoredMeasurement*>& accepted,
              const std::vector<MeasurementSample>& samples,
              double (*key)(const ScoredMeasurement&), const MeasurementEvalOptions& o) {
  for (MeasurementErrorBin& bin : *bins) {
    std::vector<double> xy, heading;
    int64_t gross = 0;
    for (const ScoredMeasurement* sc : accepted) {
      const double k = key(*sc);
      if (!(k >= bin.low && k < bin.high)) continue;
      const MeasurementSample& s = samples[sc->index];
      xy.push_back(s.dx - sc->true_dx);
      xy.push_back(s.dy - sc->true_dy);
      heading.push_back(sc->signed_heading_error_rad);
      gross += sc->xy_error_m > o.gross_xy_m ||
               sc->heading_error_rad > o.gross_heading_deg * M_PI / 180.0;
    }
    bin.count = static_cast<int64_t>(heading.size());
    bin.robust_sigma_xy_m = robustSigma(std::move(xy));
    bin.robust_sigma_heading_rad = robustSigma(std::move(heading));
    bin.gross_fraction = bin.count > 0 ? static_cast<double>(gross) / static_cast<double>(bin.count)
                                       : std::numeric_limits<double>::quiet_NaN();
  }
}

}  // namespace

double robustSigma(std::vector<double> values) {
  if (values.empty()) return std::numeric_limits<double>::quiet_NaN();
  auto median = [](std::vector<double>& v) {
    const size_t mid = v.size() / 2;
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid), v.end());
    double m = v[mid];
    if (v.size() % 2 == 0)
      m = 0.5 * (m + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(mid)));
    return m;
  };
  const double centre = median(values);
  for (double& v : values) v = std::abs(v - centre);
  return 1.4826 * median(values);
}

int64_t MeasurementReport::acceptedCount() const {
  const auto it = verdicts.find(MeasurementVerdict::kAccepted);
  return it == verdicts.end() ? 0 : it->second;
}

double MeasurementReport::acceptedFraction() const {
  return samples.empty()
             ? std::numeric_limits<double>::quiet_NaN()
             : static_cast<double>(acceptedCount()) / static_cast<double>(samples.size());
}

MeasurementReport evaluateMeasurements(const Trajectory& reference,
                                       std::vector<MeasurementSample> samples,
                                       const std::map<int64_t, LandmarkCreationTime>& creations,
                                       const MeasurementEvalOptions& options,
                                       const std::map<std::string, double>& camera_heading_rad) {
  if (reference.empty()) throw DataError("no ground-truth poses to score measurements against");
  Trajectory sorted = reference;
  sortByTime(&sorted);
  const PlanarTruth truth(sorted, options.max_gap);

  MeasurementReport r;
  r.options = options;
  r.landmarks_created = static_cast<int64_t>(creations.size());
  std::set<int64_t> measured;
  for (std::size_t i = 0; i < samples.size(); ++i) {
    const MeasurementSample& s = samples[i];
    ++r.verdicts[s.verdict];
    ++r.per_camera[s.camera];
    measured.insert(s.landmark_id);
    const auto created = creations.find(s.landmark_id);
    if (created == creations.end()) {
      ++r.unknown_landmark;
      continue;
    }
    const auto at_creation = truth.at(created->second.t);
    const auto now = truth.at(s.t);
    if (!at_creation || !now) {
      ++r.no_truth;
      continue;
    }
    const Pose2 expected = at_creation->between(*now);
    const double heading_error = wrapAngle(s.dtheta - expected.theta);
    // The measuring camera's heading in the world against the creating one's.
    double view_change = std::numeric_limits<double>::quiet_NaN();
    const auto measuring = camera_heading_rad.find(s.camera);
    const auto creating = camera_heading_rad.find(created->second.camera);
    if (measuring != camera_heading_rad.end() && creating != camera_heading_rad.end())
      view_change = std::abs(wrapAngle(expected.theta + measuring->second - creating->second));
    r.scored.push_back({i, expected.x, expected.y, expected.theta,
                        std::hypot(s.dx - expected.x, s.dy - expected.y), std::abs(heading_error),
                        heading_error, std::hypot(expected.x, expected.y), view_change});
  }
  r.landmarks = static_cast<int64_t>(measured.size());
  if (!samples.empty()) {
    const auto [first, last] = std::minmax_element(
        samples.begin(), samples.end(),
        [](const MeasurementSample& a, const MeasurementSample& b) { return a.t < b.t; });
    r.duration_s = last->t - first->t;
  }

  std::vector<const ScoredMeasurement*> all, accepted;
  double low = 0;
  for (const double high : options.band_edges_cm) {
    r.bands.push_back({low, high, 0, 0});
    low = high;
  }
  r.bands.push_back({low, std::numeric_limits<double>::infinity(), 0, 0});
  for (const auto& sc : r.scored) {
    const bool ok = samples[sc.index].verdict == MeasurementVerdict::kAccepted;
    all.push_back(&sc);
    if (ok) accepted.push_back(&sc);
    const double cm = sc.xy_error_m * 100.0;
    for (auto& band : r.bands) {
      if (cm >= band.low_cm && cm < band.high_cm) {
        ++(ok ? band.accepted : band.rejected);
        break;
      }
    }
  }
  std::map<int64_t, std::vector<double>> xy_by_landmark;
  for (const auto& sc : r.scored)
    xy_by_landmark[samples[sc.index].landmark_id].push_back(sc.xy_error_m);
  std::map<int64_t, LandmarkMeasurementStats> by_landmark;
  for (const auto& s : samples) {
    auto& l = by_landmark[s.landmark_id];
    l.landmark_id = s.landmark_id;
    ++l.measurements;
    if (s.verdict == MeasurementVerdict::kAccepted) ++l.accepted;
  }
  for (auto& [id, l] : by_landmark) {
    const auto created = creations.find(id);
    if (created != creations.end()) l.camera = created->second.camera;
    l.xy_m = computeStats(xy_by_landmark[id]);
    r.per_landmark.push_back(l);
  }
  r.accepted = summarize(accepted);
  r.all = summarize(all);
  r.by_distance = binsOf(options.distance_edges_m);
  fillBins(
      &r.by_distance, accepted, samples,
      [](const ScoredMeasurement& sc) { return sc.creation_distance_m; }, options);
  std::vector<double> view_edges_rad;
  for (const double deg : options.view_change_edges_deg) view_edges_rad.push_back(deg * M_PI / 180);
  r.by_view_change = binsOf(view_edges_rad);
  fillBins(
      &r.by_view_change, accepted, samples,
      [](const ScoredMeasurement& sc) { return sc.view_change_rad; }, options);
  r.samples = std::move(samples);
  return r;
}

void writeMeasurementCsv(const std::string& path, const MeasurementReport& r) {
  createParentFolder(path);
  std::ofstream f(path);
  if (!f) throw DataError(path + ": cannot open for writing");
  f << "t,camera,landmark_id,verdict,proj_err_rms,num_points,slope,dx,dy,dtheta,"
       "true_dx,true_dy,true_dtheta,xy_error_m,heading_error_rad,creation_distance_m,"
       "view_change_rad\n";
  std::vector<const ScoredMeasurement*> by_sample(r.samples.size(), nullptr);
  for (const auto& sc : r.scored) by_sample[sc.index] = &sc;
  f.precision(10);
  for (std::size_t i = 0; i < r.samples.size(); ++i) {
    const MeasurementSample& s = r.samples[i];
    // Time to the microsecond (LCM utime): 10 significant digits would round
    // epoch seconds to whole seconds.
    f << fmt("%.6f", s.t) << "," << s.camera << "," << s.landmark_id << ","
      << static_cast<int>(s.verdict) << "," << s.proj_err_rms << "," << s.num_points << ","
      << s.slope << "," << s.dx << "," << s.dy << "," << s.dtheta;
    if (const ScoredMeasurement* sc = by_sample[i]) {
      f << "," << sc->true_dx << "," << sc->true_dy << "," << sc->true_dtheta << ","
        << sc->xy_error_m << "," << sc->heading_error_rad << "," << sc->creation_distance_m << ",";
      if (std::isfinite(sc->view_change_rad)) f << sc->view_change_rad;
      f << "\n";
    } else {
      f << ",,,,,,,\n";
    }
  }
  if (!f) throw DataError(path + ": write failed");
}

void printMeasurementReport(std::ostream& os, const MeasurementReport& r) {
  const int64_t total = static_cast<int64_t>(r.samples.size());
  os << "Visual measurements: " << r.input << "\n";
  os << "  " << total << " measurements of " << r.landmarks << " landmarks (" << r.landmarks_created
     << " created) over " << fmt("%.1f", r.duration_s) << " s";
  if (r.duration_s > 0 && total > 0)
    os << ", one every " << fmt("%.2f", r.duration_s / static_cast<double>(total)) << " s";
  os << "\n  per camera:";
  for (const auto& [camera, n] : r.per_camera) os << " " << camera << " " << n;
  os << "\n  pre-filter:";
  for (const auto& [verdict, n] : r.verdicts)
    os << " " << toString(verdict) << " " << n << " (" << percent(n, total) << ");";
  os << "\n";
  if (r.unknown_landmark > 0 || r.no_truth > 0) {
    os << "  not scored: " << r.unknown_landmark << " of landmarks with no creation record, "
       << r.no_truth << " without ground truth at the measurement or creation time\n";
  }
  os << "\n  error against ground truth   count   xy mean / median / rms (cm)"
        "   heading mean / median / rms (deg)\n";
  auto row = [&](const char* name, const ErrorSummary& e) {
    char buf[200];
    std::snprintf(buf, sizeof(buf), "  %-28s %6zu   %6s / %6s / %6s          %6s / %6s / %6s\n",
                  name, e.xy_m.count, fmt("%.2f", e.xy_m.mean * 100).c_str(),
                  fmt("%.2f", e.xy_m.median * 100).c_str(), fmt("%.2f", e.xy_m.rmse * 100).c_str(),
                  fmt("%.2f", e.heading_rad.mean * kRadToDeg).c_str(),
                  fmt("%.2f", e.heading_rad.median * kRadToDeg).c_str(),
                  fmt("%.2f", e.heading_rad.rmse * kRadToDeg).c_str());
    os << buf;
  };
  row("accepted", r.accepted);
  row("all", r.all);

  os << "\n  per landmark: id (camera) measurements accepted, xy median / max (cm)\n";
  for (const auto& l : r.per_landmark) {
    os << "    " << l.landmark_id << " (" << (l.camera.empty() ? "?" : l.camera) << ") "
       << l.measurements << " " << l.accepted << ", " << fmt("%.1f", l.xy_m.median * 100) << " / "
       << fmt("%.1f", l.xy_m.max * 100) << "\n";
  }
  const MeasurementEvalOptions& o = r.options;
  auto bins = [&](const char* title, const std::vector<MeasurementErrorBin>& b, double scale,
                  const char* unit) {
    os << "\n  accepted measurements " << title << "\n";
    char buf[200];
    std::snprintf(buf, sizeof(buf), "    %-10s  %8s  %21s  %13s  gross errors (> %g m or %g deg)\n",
                  unit, "count", "robust sigma xy (cm)", "heading (deg)", o.gross_xy_m,
                  o.gross_heading_deg);
    os << buf;
    for (const auto& bin : b) {
      const std::string name = std::isfinite(bin.high)
                                   ? fmt("%g", bin.low * scale) + "-" + fmt("%g", bin.high * scale)
                                   : ">" + fmt("%g", bin.low * scale);
      std::snprintf(buf, sizeof(buf), "    %-10s  %8lld  %21s  %13s  %s\n", name.c_str(),
                    static_cast<long long>(bin.count),
                    fmt("%.1f", bin.robust_sigma_xy_m * 100).c_str(),
                    fmt("%.2f", bin.robust_sigma_heading_rad * kRadToDeg).c_str(),
                    fmt("%.1f%%", 100 * bin.gross_fraction).c_str());
      os << buf;
    }
  };
  bins("by distance from the creation pose", r.by_distance, 1.0, "m");
  int64_t with_view = 0;
  for (const auto& bin : r.by_view_change) with_view += bin.count;
  if (with_view > 0 || r.accepted.xy_m.count == 0) {
    bins("by change of viewing direction", r.by_view_change, kRadToDeg, "deg");
  } else {
    os << "\n  by change of viewing direction: no camera calibration in the input (the cameras'"
          " headings on the robot)\n";
  }

  os << "\n  Distribution of accuracy (vSLAM paper Table 1)\n";
  os << "  xy err (cm)  accepted  rejected  accepted/total   xy err (cm)  accepted  rejected  "
        "accepted/total\n";
  int64_t cum_acc = 0, cum_rej = 0;
  for (const auto& b : r.bands) {
    cum_acc += b.accepted;
    cum_rej += b.rejected;
    const bool last = !std::isfinite(b.high_cm);
    const std::string cum_name = last ? ">" + edge(b.low_cm) : "<" + edge(b.high_cm);
    const std::string band_name =
        last ? ">" + edge(b.low_cm) : edge(b.low_cm) + "-" + edge(b.high_cm);
    char buf[240];
    if (last) {
      std::snprintf(buf, sizeof(buf), "  %-11s  %8lld  %8lld  %14s\n", cum_name.c_str(),
                    static_cast<long long>(b.accepted), static_cast<long long>(b.rejected),
                    percent(b.accepted, b.accepted + b.rejected).c_str());
    } else {
      std::snprintf(buf, sizeof(buf), "  %-11s  %8lld  %8lld  %14s   %-11s  %8lld  %8lld  %14s\n",
                    cum_name.c_str(), static_cast<long long>(cum_acc),
                    static_cast<long long>(cum_rej), percent(cum_acc, cum_acc + cum_rej).c_str(),
                    band_name.c_str(), static_cast<long long>(b.accepted),
                    static_cast<long long>(b.rejected),
                    percent(b.accepted, b.accepted + b.rejected).c_str());
    }
    os << buf;
  }
}

}  // namespace vslam::eval
