#include "eval/log_reader.hpp"

#include <cstdio>

namespace vslam::eval {
namespace {

// Bytes of an event's framing: sync word, event number, timestamp, channel
// length, data length (lcm_eventlog format).
constexpr long kEventHeaderBytes = 4 + 8 + 8 + 4 + 4;

}  // namespace

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
  const std::string name = log.string();
  std::error_code ec;
  if (!std::filesystem::exists(log, ec)) throw DataError(name + ": no such file");
  if (std::filesystem::is_directory(log, ec)) throw DataError(name + ": is a directory, not a log");

  lcm::LogFile in(name, "r");
  if (!in.good()) throw DataError(name + ": cannot open the log for reading");
  FILE* file = in.getFilePtr();
  std::fseek(file, 0, SEEK_END);
  const long file_size = std::ftell(file);
  std::fseek(file, 0, SEEK_SET);

  std::map<std::string, int64_t> counts;
  long pos = 0;
  int64_t events = 0;
  while (const lcm::LogEvent* ev = in.readNextEvent()) {
    const long end = std::ftell(file);
    const long expected = kEventHeaderBytes + static_cast<long>(ev->channel.size()) + ev->datalen;
    if (end - pos != expected) {
      std::ostringstream os;
      os << name << " is damaged: " << (end - pos - expected) << " bytes at byte " << pos
         << " are not an LCM event (before event " << ev->eventnum << " on " << ev->channel << ")";
      throw DataError(os.str());
    }
    const long event_offset = pos;
    pos = end;
    ++events;
    ++counts[ev->channel];
    visit(LogEventRef{name, *ev, event_offset});
  }
  if (pos < file_size) {
    std::ostringstream os;
    if (events == 0) {
      os << name << ": not an LCM log (no complete event in its " << file_size << " bytes)";
    } else {
      os << name << " is damaged: the last " << (file_size - pos) << " bytes (from byte " << pos
         << ", after " << events << " events) are not a complete LCM event (cut or corrupt)";
    }
    throw DataError(os.str());
  }
  return counts;
}

}  // namespace vslam::eval
