#include "bus/log_writer.hpp"

#include <stdexcept>

namespace vslam::bus {

LogWriter::LogWriter(const std::filesystem::path& file) : file_(file), log_(file.string(), "w") {
  if (!log_.good()) throw std::runtime_error(file_.string() + ": cannot create the log");
}

void LogWriter::write(int64_t timestamp, const std::string& channel, const void* data,
                      size_t size) {
  lcm::LogEvent ev;
  ev.eventnum = next_eventnum_;
  ev.timestamp = timestamp;
  ev.channel = channel;
  ev.datalen = static_cast<int32_t>(size);
  ev.data = const_cast<void*>(data);  // lcm::LogFile only reads it
  if (log_.writeEvent(&ev) != 0)
    throw std::runtime_error(file_.string() + ": write failed (disk full?)");
  ++next_eventnum_;
}

}  // namespace vslam::bus
