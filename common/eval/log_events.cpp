#include "eval/log_events.hpp"

#include "bus/log_reader.hpp"
#include "util/log.hpp"
#include "util/progress.hpp"

namespace vslam::eval {

int64_t fingerprint(const void* data, int32_t len) {
  if (len < 8) return 0;
  const auto* b = static_cast<const uint8_t*>(data);
  uint64_t h = 0;
  for (int i = 0; i < 8; ++i) h = (h << 8) | b[i];
  return static_cast<int64_t>(h);
}

std::string channelList(const std::map<std::string, int64_t>& counts) {
  if (counts.empty()) return "none";
  std::string s;
  for (const auto& [ch, n] : counts)
    s += (s.empty() ? "" : ", ") + ch + " (" + std::to_string(n) + ")";
  return s;
}

std::map<std::string, int64_t> forEachLogEvent(
    const std::filesystem::path& log, const std::function<void(const LogEventRef&)>& visit) {
  std::map<std::string, int64_t> counts;
  try {
    bus::LogReader reader(log, bus::LogDamage::kCutTail);
    std::error_code ec;
    const auto bytes = std::filesystem::file_size(log, ec);
    ProgressMeter meter("read " + log.filename().string(), ec ? 0.0 : static_cast<double>(bytes),
                        ProgressMeter::kBytes);
    while (const lcm::LogEvent* ev = reader.next()) {
      ++counts[ev->channel];
      visit(LogEventRef{reader.name(), *ev, reader.eventOffset()});
      meter.update(static_cast<double>(reader.eventOffset()));
    }
    if (reader.stats().tail_bytes > 0) {
      vslam::log::warn(reader.name(), " ends with ", reader.stats().tail_bytes,
                       " bytes of an event cut short (a recording stopped by a power loss?): "
                       "evaluated the ",
                       reader.stats().events_read, " complete events before them");
    }
  } catch (const bus::LogError& e) {
    throw DataError(e.what());
  }
  return counts;
}

}  // namespace vslam::eval
