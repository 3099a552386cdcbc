#include "status/status_board.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

namespace vslam::status {
namespace {

constexpr const char* kInputRatePrefix = "rx_hz_";

// The figures shown per program: health metric name and its label.
struct Figure {
  const char* metric;
  const char* label;
};
const std::map<std::string, std::vector<Figure>>& figuresByProcess() {
  static const std::map<std::string, std::vector<Figure>> table = {
      {"vslam-frontend",
       {{"frames_processed", "frames"},
        {"measurements", "measurements"},
        {"landmarks_created", "created"},
        {"sift_ms", "sift ms"}}},
      {"vslam-backend",
       {{"effective_sample_size", "ESS"},
        {"kidnapped", "kidnapped"},
        {"landmarks", "landmarks"},
        {"position_sigma", "sigma m"}}},
      {"vslam-landmark-db",
       {{"landmarks_in_memory", "in memory"}, {"landmarks_stored", "on disk"}, {"file_mb", "MiB"}}},
      {"vslam-appearance",
       {{"states", "states"}, {"hypotheses", "hypotheses"}, {"relocalizations", "relocalized"}}},
      {"vslam-camera", {{"frames", "frames"}, {"source_open", "open"}, {"sources_lost", "lost"}}},
      {"vslam-odometry-bridge",
       {{"lines_accepted", "lines"}, {"lines_rejected", "rejected"}, {"source_open", "open"}}},
      {"vslam-deadreckon", {{"steps", "steps"}, {"distance", "m driven"}}},
      {"vslam-sim", {{"sim_time", "sim s"}, {"frames_per_second", "frames/s"}, {"lag", "lag ms"}}},
  };
  return table;
}

const Metric* findMetric(const HealthSample& s, const std::string& name) {
  for (const auto& m : s.metrics) {
    if (m.name == name) return &m;
  }
  return nullptr;
}

// Per second between two messages of one pid, or -1 when not measurable
// (no time passed, a counter went back).
double perSecond(double now, double before, double dt_s) {
  if (!(dt_s > 0) || !(now >= before)) return -1;
  return (now - before) / dt_s;
}

std::string number(double v, int decimals) {
  if (!std::isfinite(v) || v < 0) return "-";
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

std::string duration(double s) {
  if (!std::isfinite(s) || s < 0) return "-";
  char buf[32];
  const long t = std::lround(std::min(s, 1e9));
  if (t >= 86400) {
    std::snprintf(buf, sizeof(buf), "%ldd%02ldh", t / 86400, t / 3600 % 24);
  } else if (t >= 3600) {
    std::snprintf(buf, sizeof(buf), "%ldh%02ldm", t / 3600, t / 60 % 60);
  } else {
    std::snprintf(buf, sizeof(buf), "%ldm%02lds", t / 60, t % 60);
  }
  return buf;
}

// Text from the network, printable and at most `width` characters.
std::string cut(const std::string& text, size_t width) {
  std::string s;
  for (char c : text) {
    if (s.size() >= width) break;
    const auto u = static_cast<unsigned char>(c);
    s += u >= 0x20 && u < 0x7f ? c : '?';
  }
  if (text.size() > width && width > 0) s.back() = '~';
  return s;
}

std::string pad(const std::string& s, size_t width, bool right = false) {
  const std::string c = cut(s, width);
  const std::string fill(width - c.size(), ' ');
  return right ? fill + c : c + fill;
}

const char* levelName(int level) {
  switch (level) {
    case 0:
      return "OK";
    case 1:
      return "WARN";
    case 2:
      return "ERROR";
    default:
      return "?";
  }
}

std::string figureText(const Metric& m) {
  const double v = m.value;
  if (!std::isfinite(v)) return m.name + " -";
  char buf[48];
  const bool whole = std::abs(v) < 1e15 && v == std::floor(v);
  std::snprintf(buf, sizeof(buf), whole ? "%.0f" : std::abs(v) < 10 ? "%.2f" : "%.1f", v);
  return m.name + " " + buf + m.unit;
}

}  // namespace

std::vector<Metric> StatusBoard::keyFigures(const HealthSample& sample) {
  std::vector<Metric> out;
  const auto& table = figuresByProcess();
  const auto it = table.find(sample.process);
  if (it == table.end()) return out;
  for (const Figure& f : it->second) {
    if (const Metric* m = findMetric(sample, f.metric)) out.push_back({f.label, m->value, ""});
  }
  if (sample.process == "vslam-backend") {
    // The paper's pre-filter: the share of the measurements it rejected.
    double accepted = 0, rejected = 0;
    for (const auto& m : sample.metrics) {
      if (!std::isfinite(m.value) || m.value < 0) continue;
      if (m.name == "measurements_accepted") accepted += m.value;
      if (m.name.rfind("measurements_rejected_", 0) == 0) rejected += m.value;
    }
    if (accepted + rejected > 0) {
      out.push_back({"rejected", 100.0 * rejected / (accepted + rejected), "%"});
    }
  }
  return out;
}

void StatusBoard::add(const HealthSample& sample) {
  const auto key = std::make_pair(sample.host, sample.instance);
  auto it = entries_.find(key);
  if (it == entries_.end()) {
    if (entries_.size() >= options_.max_rows) {
      // Make way: the row silent for longest goes.
      auto oldest = std::min_element(entries_.begin(), entries_.end(), [](auto& a, auto& b) {
        return a.second.last.received_s < b.second.last.received_s;
      });
      if (oldest != entries_.end()) entries_.erase(oldest);
    }
    it = entries_.emplace(key, Entry{}).first;
    it->second.last = sample;
  } else {
    Entry& e = it->second;
    if (e.last.pid != sample.pid) {
      ++e.restarts;
      e.has_previous = false;
      e.inputs.clear();
    } else {
      e.previous = std::move(e.last);
      e.has_previous = true;
    }
    e.last = sample;
  }
  Entry& e = it->second;
  std::map<std::string, bool> busy;  // this report's inputs: any messages?
  for (const auto& m : sample.metrics) {
    if (m.name.rfind(kInputRatePrefix, 0) != 0) continue;
    busy[m.name.substr(std::char_traits<char>::length(kInputRatePrefix))] =
        std::isfinite(m.value) && m.value > 0;
  }
  for (auto& [channel, input] : e.inputs) busy.emplace(channel, false);  // absent: none
  for (const auto& [channel, any] : busy) {
    if (e.inputs.size() >= options_.max_rows && !e.inputs.count(channel)) continue;
    Entry::Input& input = e.inputs[channel];
    input.busy_run = any ? input.busy_run + 1 : 0;
    input.idle_run = any ? 0 : input.idle_run + 1;
    if (input.busy_run >= options_.steady_reports) input.steady = true;
  }
}

std::vector<Row> StatusBoard::rows(double now_s) const {
  std::vector<Row> out;
  for (const auto& [key, e] : entries_) {
    const HealthSample& s = e.last;
    Row r;
    r.host = key.first;
    r.instance = key.second;
    r.process = s.process;
    r.pid = s.pid;
    r.restarts = e.restarts;
    r.uptime_s = s.uptime_s;
    r.level = s.level;
    r.message = s.message;
    r.silent_s = std::max(0.0, now_s - s.received_s);
    r.stale = r.silent_s >= options_.stale_after_s;
    r.rss_bytes = s.rss_bytes;
    r.dropped = s.dropped;
    r.malformed = s.malformed;
    r.handler_latency_ms = s.handler_latency_ms;
    if (e.has_previous) {
      const double dt = s.uptime_s - e.previous.uptime_s;
      const double cpu = perSecond(s.cpu_seconds, e.previous.cpu_seconds, dt);
      r.cpu_percent = cpu < 0 ? -1 : 100.0 * cpu;
      r.rx_per_s =
          perSecond(static_cast<double>(s.received), static_cast<double>(e.previous.received), dt);
      r.tx_per_s = perSecond(static_cast<double>(s.published),
                             static_cast<double>(e.previous.published), dt);
    }
    for (const auto& [channel, input] : e.inputs) {
      if (input.steady && input.idle_run >= options_.quiet_reports) {
        r.quiet_inputs.push_back(channel);
      }
    }
    r.key_figures = keyFigures(s);
    out.push_back(std::move(r));
  }
  return out;
}

bool StatusBoard::anyStale(double now_s) const {
  for (const auto& [key, e] : entries_) {
    if (now_s - e.last.received_s >= options_.stale_after_s) return true;
  }
  return false;
}

std::string renderBoard(const std::vector<Row>& rows, int width) {
  const size_t w = static_cast<size_t>(std::max(width, 80));
  std::string out;
  const auto line = [&](std::string l) {
    out += cut(l, w);
    out += '\n';
  };
  line(pad("INSTANCE", 20) + " " + pad("HOST", 12) + " " + pad("PID", 7, true) + " " +
       pad("UP", 7, true) + " " + pad("LEVEL", 5) + " " + pad("CPU%", 5, true) + " " +
       pad("RSS MB", 6, true) + " " + pad("RX/s", 6, true) + " " + pad("TX/s", 6, true) + " " +
       pad("DROP", 6, true) + " " + pad("LAT ms", 6, true) + "  KEY FIGURES");
  std::vector<std::string> notes;
  for (const Row& r : rows) {
    std::string figures;
    for (const auto& m : r.key_figures) figures += (figures.empty() ? "" : ", ") + figureText(m);
    const std::string level = r.stale ? "STALE" : levelName(r.level);
    line(
        pad(r.instance, 20) + " " + pad(r.host, 12) + " " + pad(std::to_string(r.pid), 7, true) +
        " " + pad(duration(r.uptime_s), 7, true) + " " + pad(level, 5) + " " +
        pad(number(r.cpu_percent, 0), 5, true) + " " +
        pad(number(static_cast<double>(r.rss_bytes) / (1 << 20), 0), 6, true) + " " +
        pad(number(r.rx_per_s, 1), 6, true) + " " + pad(number(r.tx_per_s, 1), 6, true) + " " +
        pad(number(static_cast<double>(r.dropped) + static_cast<double>(r.malformed), 0), 6, true) +
        " " + pad(number(r.handler_latency_ms, 1), 6, true) + "  " + figures);
    const std::string who = cut(r.instance, 40) + (r.host.empty() ? "" : "@" + cut(r.host, 40));
    if (r.stale) notes.push_back(who + ": STALE, silent for " + duration(r.silent_s));
    if (r.level != 0 && !r.message.empty()) {
      notes.push_back(who + ": " + levelName(r.level) + " " + cut(r.message, 200));
    }
    if (!r.quiet_inputs.empty()) {
      std::string channels;
      for (const auto& c : r.quiet_inputs) channels += (channels.empty() ? "" : ", ") + cut(c, 40);
      notes.push_back(who + ": input gone quiet: " + channels);
    }
    if (r.restarts > 0) {
      notes.push_back(who + ": restarted " + std::to_string(r.restarts) + " time" +
                      (r.restarts > 1 ? "s" : ""));
    }
  }
  for (const auto& n : notes) line("  " + n);
  return out;
}

}  // namespace vslam::status
