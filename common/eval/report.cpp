#include "eval/report.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iomanip>
#include <ostream>
#include <sstream>

#include "eval/errors.hpp"

namespace vslam::eval {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;

std::string fixed(double v, int decimals) {
  if (!std::isfinite(v)) return "n/a";
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

// Minimal pretty-printing JSON writer: objects and arrays of numbers and
// strings. Non-finite numbers are written as null.
class Json {
 public:
  void beginObject(const std::string& key = "") { open(key, '{'); }
  void endObject() { close('}'); }
  void beginArray(const std::string& key = "") { open(key, '['); }
  void endArray() { close(']'); }
  void number(const std::string& key, double v) {
    item(key);
    if (std::isfinite(v)) {
      char buf[64];
      std::snprintf(buf, sizeof(buf), "%.10g", v);
      os_ << buf;
    } else {
      os_ << "null";
    }
  }
  void integer(const std::string& key, long long v) {
    item(key);
    os_ << v;
  }
  void string(const std::string& key, const std::string& v) {
    item(key);
    quoted(v);
  }
  void boolean(const std::string& key, bool v) {
    item(key);
    os_ << (v ? "true" : "false");
  }
  void numbers(const std::string& key, const std::vector<double>& v) {
    item(key);
    os_ << "[";
    for (std::size_t i = 0; i < v.size(); ++i) {
      char buf[64];
      std::snprintf(buf, sizeof(buf), "%.10g", v[i]);
      os_ << (i ? ", " : "") << (std::isfinite(v[i]) ? buf : "null");
    }
    os_ << "]";
  }
  std::string str() const { return os_.str() + "\n"; }

 private:
  void quoted(const std::string& s) {
    os_ << '"';
    for (const char c : s) {
      switch (c) {
        case '"':
          os_ << "\\\"";
          break;
        case '\\':
          os_ << "\\\\";
          break;
        case '\n':
          os_ << "\\n";
          break;
        case '\t':
          os_ << "\\t";
          break;
        default:
          if (static_cast<unsigned char>(c) < 0x20) {
            char buf[8];
            std::snprintf(buf, sizeof(buf), "\\u%04x", c);
            os_ << buf;
          } else {
            os_ << c;
          }
      }
    }
    os_ << '"';
  }
  void item(const std::string& key) {
    if (!first_.empty()) {
      if (!first_.back()) os_ << ",";
      first_.back() = false;
      os_ << "\n" << std::string(2 * first_.size(), ' ');
    }
    if (!key.empty()) {
      quoted(key);
      os_ << ": ";
    }
  }
  void open(const std::string& key, char bracket) {
    item(key);
    os_ << bracket;
    first_.push_back(true);
  }
  void close(char bracket) {
    const bool empty = first_.back();
    first_.pop_back();
    if (!empty) os_ << "\n" << std::string(2 * first_.size(), ' ');
    os_ << bracket;
  }

  std::ostringstream os_;
  std::vector<bool> first_;
};

void statsJson(Json& j, const std::string& key, const ErrorStats& s, double factor) {
  j.beginObject(key);
  j.integer("count", static_cast<long long>(s.count));
  j.number("rmse", s.rmse * factor);
  j.number("mean", s.mean * factor);
  j.number("median", s.median * factor);
  j.number("std", s.std * factor);
  j.number("min", s.min * factor);
  j.number("max", s.max * factor);
  j.endObject();
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

std::string toJson(const TrajectoryReport& r) {
  Json j;
  j.beginObject();
  j.string("tool", "vslam-eval");
  j.string("mode", "trajectory");
  j.string("input", r.input);
  j.beginObject("parameters");
  j.number("max_diff_s", r.options.max_diff);
  j.number("offset_s", r.options.offset);
  j.string("align", toString(r.options.align));
  j.number("rpe_delta", r.options.rpe.delta);
  j.string("rpe_delta_unit", toString(r.options.rpe.unit));
  j.endObject();
  j.beginObject("reference");
  j.string("name", r.reference.name);
  j.string("source", r.reference_source);
  j.integer("poses", static_cast<long long>(r.reference.size()));
  j.number("duration_s", r.reference.duration());
  j.number("path_length_m", r.reference.pathLength());
  j.endObject();
  j.beginArray("estimates");
  for (const auto& e : r.estimates) {
    j.beginObject();
    j.string("name", e.name);
    j.string("kind", toString(e.kind));
    j.string("source", e.source);
    j.integer("poses", static_cast<long long>(e.poses));
    j.number("duration_s", e.duration);
    j.number("path_length_m", e.path_length);
    j.beginObject("alignment");
    j.string("mode", toString(r.options.align));
    j.number("scale", e.ate.alignment.scale);
    j.number("yaw_deg", e.ate.alignment.yaw() * kRadToDeg);
    j.number("angle_deg", e.ate.alignment.rotationAngle() * kRadToDeg);
    j.numbers("translation_m",
              {e.ate.alignment.t.x(), e.ate.alignment.t.y(), e.ate.alignment.t.z()});
    const auto& R = e.ate.alignment.R;
    j.numbers("rotation_rowmajor",
              {R(0, 0), R(0, 1), R(0, 2), R(1, 0), R(1, 1), R(1, 2), R(2, 0), R(2, 1), R(2, 2)});
    j.endObject();
    j.beginObject("ate");
    j.integer("pairs", static_cast<long long>(e.ate.stats.count));
    statsJson(j, "translation_m", e.ate.stats, 1.0);
    statsJson(j, "heading_deg", e.ate.heading, kRadToDeg);
    j.endObject();
    j.beginObject("rpe");
    j.integer("pairs", static_cast<long long>(e.rpe.trans.count));
    j.number("reference_max_time_diff_s", e.rpe.ref_max_time_diff);
    statsJson(j, "translation_m", e.rpe.trans, 1.0);
    statsJson(j, "rotation_deg", e.rpe.rot, kRadToDeg);
    j.endObject();
    j.endObject();
  }
  j.endArray();
  j.integer("landmarks", static_cast<long long>(r.landmarks.size()));
  j.endObject();
  return j.str();
}

void writeJson(const std::filesystem::path& file, const TrajectoryReport& report) {
  std::ofstream out(file);
  if (!out) throw DataError(file.string() + ": cannot open for writing");
  out << toJson(report);
  out.close();
  if (!out) throw DataError(file.string() + ": write failed");
}

}  // namespace vslam::eval
