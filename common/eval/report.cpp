#include "eval/report.hpp"

#include <cmath>
#include <cstdio>
#include <functional>
#include <initializer_list>
#include <iomanip>
#include <ostream>

namespace vslam::eval {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

std::string fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

Json statsJson(const ErrorStats& s, double factor) {
  Json j;
  j["count"] = s.count;
  j["rmse"] = jsonNumber(s.rmse * factor);
  j["mean"] = jsonNumber(s.mean * factor);
  j["median"] = jsonNumber(s.median * factor);
  j["std"] = jsonNumber(s.std * factor);
  j["min"] = jsonNumber(s.min * factor);
  j["max"] = jsonNumber(s.max * factor);
  return j;
}

Json jsonNumbers(std::initializer_list<double> values) {
  Json j = Json::array();
  for (const double v : values) j.push_back(jsonNumber(v));
  return j;
}

}  // namespace

void printTable(std::ostream& os, const TrajectoryReport& r) {
  const auto& o = r.options;
  os << "Trajectory evaluation of " << r.input << "\n";
  os << "reference   " << r.reference.name << " (" << r.reference_source
     << "): " << r.reference.size() << " poses, " << fixed(r.reference.duration(), 2) << " s, "
     << fixed(r.reference.pathLength(), 2) << " m\n";
  os << "association max-diff " << fixed(o.max_diff, 3) << " s, offset " << fixed(o.offset, 3)
     << " s; alignment " << toString(o.align) << "; RPE delta " << o.rpe.delta << " "
     << toString(o.rpe.unit) << "\n\n";

  using Row = std::pair<std::string, std::function<std::string(const EstimateEvaluation&)>>;
  std::vector<Row> rows = {
      {"kind", [](const auto& e) { return toString(e.kind); }},
      {"source", [](const auto& e) { return e.source; }},
      {"poses", [](const auto& e) { return std::to_string(e.poses); }},
      {"duration [s]", [](const auto& e) { return fixed(e.duration, 2); }},
      {"path length [m]", [](const auto& e) { return fixed(e.path_length, 3); }},
      {"alignment yaw [deg]",
       [](const auto& e) { return fixed(e.ate.alignment.yaw() * kRadToDeg, 3); }},
      {"alignment angle [deg]",
       [](const auto& e) { return fixed(e.ate.alignment.rotationAngle() * kRadToDeg, 3); }},
      {"alignment |t| [m]", [](const auto& e) { return fixed(e.ate.alignment.t.norm(), 4); }},
      {"alignment scale", [](const auto& e) { return fixed(e.ate.alignment.scale, 6); }},
      {"ATE pairs", [](const auto& e) { return std::to_string(e.ate.stats.count); }},
  };
  const std::pair<const char*, double ErrorStats::*> stat_fields[] = {
      {"rmse", &ErrorStats::rmse}, {"mean", &ErrorStats::mean}, {"median", &ErrorStats::median},
      {"std", &ErrorStats::std},   {"min", &ErrorStats::min},   {"max", &ErrorStats::max}};
  for (const auto& [name, field] : stat_fields) {
    rows.push_back({std::string("ATE ") + name + " [m]",
                    [field = field](const auto& e) { return fixed(e.ate.stats.*field, 6); }});
  }
  for (const auto& [name, field] : stat_fields) {
    rows.push_back({std::string("ATE heading ") + name + " [deg]", [field = field](const auto& e) {
                      return fixed(e.ate.heading.*field * kRadToDeg, 4);
                    }});
  }
  rows.push_back({"RPE pairs", [](const auto& e) { return std::to_string(e.rpe.trans.count); }});
  for (const auto& [name, field] : stat_fields) {
    rows.push_back({std::string("RPE trans ") + name + " [m]",
                    [field = field](const auto& e) { return fixed(e.rpe.trans.*field, 6); }});
  }
  for (const auto& [name, field] : stat_fields) {
    rows.push_back({std::string("RPE rot ") + name + " [deg]", [field = field](const auto& e) {
                      return fixed(e.rpe.rot.*field * kRadToDeg, 4);
                    }});
  }

  std::size_t label_w = 0;
  for (const auto& row : rows) label_w = std::max(label_w, row.first.size());
  std::vector<std::size_t> widths;
  for (const auto& e : r.estimates) {
    std::size_t w = e.name.size();
    for (const auto& row : rows) w = std::max(w, row.second(e).size());
    widths.push_back(w + 2);
  }
  os << std::left << std::setw(static_cast<int>(label_w + 2)) << "";
  for (std::size_t i = 0; i < r.estimates.size(); ++i) {
    os << std::right << std::setw(static_cast<int>(widths[i])) << r.estimates[i].name;
  }
  os << "\n";
  for (const auto& row : rows) {
    os << std::left << std::setw(static_cast<int>(label_w + 2)) << row.first;
    for (std::size_t i = 0; i < r.estimates.size(); ++i) {
      os << std::right << std::setw(static_cast<int>(widths[i])) << row.second(r.estimates[i]);
    }
    os << "\n";
  }
  if (!r.landmarks.empty()) os << "\nmap: " << r.landmarks.size() << " landmarks\n";
  os.flush();
}

Json toJson(const TrajectoryReport& r) {
  Json j;
  j["tool"] = "vslam-eval";
  j["mode"] = "trajectory";
  j["input"] = r.input;
  Json& parameters = j["parameters"];
  parameters["max_diff_s"] = jsonNumber(r.options.max_diff);
  parameters["offset_s"] = jsonNumber(r.options.offset);
  parameters["align"] = toString(r.options.align);
  parameters["rpe_delta"] = jsonNumber(r.options.rpe.delta);
  parameters["rpe_delta_unit"] = toString(r.options.rpe.unit);
  Json& reference = j["reference"];
  reference["name"] = r.reference.name;
  reference["source"] = r.reference_source;
  reference["poses"] = r.reference.size();
  reference["duration_s"] = jsonNumber(r.reference.duration());
  reference["path_length_m"] = jsonNumber(r.reference.pathLength());
  Json& estimates = j["estimates"] = Json::array();
  for (const auto& e : r.estimates) {
    Json est;
    est["name"] = e.name;
    est["kind"] = toString(e.kind);
    est["source"] = e.source;
    est["poses"] = e.poses;
    est["duration_s"] = jsonNumber(e.duration);
    est["path_length_m"] = jsonNumber(e.path_length);
    const auto& a = e.ate.alignment;
    Json& alignment = est["alignment"];
    alignment["mode"] = toString(r.options.align);
    alignment["scale"] = jsonNumber(a.scale);
    alignment["yaw_deg"] = jsonNumber(a.yaw() * kRadToDeg);
    alignment["angle_deg"] = jsonNumber(a.rotationAngle() * kRadToDeg);
    alignment["translation_m"] = jsonNumbers({a.t.x(), a.t.y(), a.t.z()});
    const auto& R = a.R;
    alignment["rotation_rowmajor"] = jsonNumbers(
        {R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)});
    Json& ate = est["ate"];
    ate["pairs"] = e.ate.stats.count;
    ate["translation_m"] = statsJson(e.ate.stats, 1.0);
    ate["heading_deg"] = statsJson(e.ate.heading, kRadToDeg);
    Json& rpe = est["rpe"];
    rpe["pairs"] = e.rpe.trans.count;
    rpe["reference_max_time_diff_s"] = jsonNumber(e.rpe.ref_max_time_diff);
    rpe["translation_m"] = statsJson(e.rpe.trans, 1.0);
    rpe["rotation_deg"] = statsJson(e.rpe.rot, kRadToDeg);
    estimates.push_back(std::move(est));
  }
  j["landmarks"] = r.landmarks.size();
  return j;
}

void writeJson(const std::filesystem::path& file, const TrajectoryReport& report) {
  writeJsonFile(file, toJson(report));
}

}  // namespace vslam::eval
