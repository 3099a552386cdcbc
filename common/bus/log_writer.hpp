#pragma once
// Writing LCM logs (the lcm_eventlog format lcm-logger and lcm-logplayer
// use): one writer for every program and test that records events.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <lcm/lcm-cpp.hpp>
#include <string>
#include <vector>

namespace vslam::bus {

class LogWriter {
 public:
  // Creates (truncates) `file`; throws std::runtime_error if it cannot.
  explicit LogWriter(const std::filesystem::path& file);
  LogWriter(const LogWriter&) = delete;
  LogWriter& operator=(const LogWriter&) = delete;

  // Appends one event, numbered in order; throws std::runtime_error naming
  // the file if the write fails (a full disk).
  void write(int64_t timestamp, const std::string& channel, const void* data, size_t size);
  void write(int64_t timestamp, const std::string& channel, const std::vector<uint8_t>& data) {
    write(timestamp, channel, data.data(), data.size());
  }
  // An LCM message, encoded.
  template <class Msg>
  void writeMessage(int64_t timestamp, const std::string& channel, const Msg& msg) {
    std::vector<uint8_t> buf(static_cast<size_t>(msg.getEncodedSize()));
    msg.encode(buf.data(), 0, static_cast<int>(buf.size()));
    write(timestamp, channel, buf);
  }

  int64_t eventsWritten() const { return next_eventnum_; }
  const std::filesystem::path& file() const { return file_; }

 private:
  std::filesystem::path file_;
  lcm::LogFile log_;
  int64_t next_eventnum_ = 0;
};

}  // namespace vslam::bus
