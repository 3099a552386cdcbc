#pragma once
// The events of an LCM log for the evaluation tools, which need it intact:
// read through bus::LogReader in its strict mode (every byte belongs to an
// event, the tail is complete), with its errors as DataError, and each
// message decoded as the type its fingerprint says.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <sstream>
#include <string>

#include "bus/checked_decode.hpp"
#include "eval/errors.hpp"

namespace vslam::eval {

// The LCM type fingerprint: the first 8 bytes of an encoded message, big-endian.
int64_t fingerprint(const void* data, int32_t len);

// Where an event sits in the log, for error messages.
struct LogEventRef {
  const std::string& log;
  const lcm::LogEvent& event;
  long offset;  // byte offset of the event in the file
};

// Whether an event's fingerprint is Msg's: a type found on any channel.
template <class Msg>
bool isEventOf(const LogEventRef& ref) {
  return fingerprint(ref.event.data, ref.event.datalen) == Msg::getHash();
}

// Calls visit(ref) for every event of the log, in order. Throws DataError if
// the file is missing, a directory, not a log, or damaged anywhere. Returns
// the number of events per channel.
std::map<std::string, int64_t> forEachLogEvent(
    const std::filesystem::path& log, const std::function<void(const LogEventRef&)>& visit);

// "A (3), B (7)" for error messages naming the channels of a log.
std::string channelList(const std::map<std::string, int64_t>& counts);

// Decodes an event as Msg (through bus::checkedDecode: a log is as untrusted
// as the network); DataError naming the event and the field at fault if the
// type, a count or the length does not match.
template <class Msg>
Msg decodeEvent(const LogEventRef& ref, const std::string& type_name) {
  Msg msg;
  std::string why;
  if (ref.event.datalen < 0 ||
      !bus::checkedDecode(msg, ref.event.data, static_cast<size_t>(ref.event.datalen), &why)) {
    std::ostringstream os;
    os << ref.log << ": event " << ref.event.eventnum << " on channel " << ref.event.channel
       << " (byte " << ref.offset << ") does not decode as " << type_name;
    if (!why.empty()) os << " (" << why << ")";
    throw DataError(os.str());
  }
  return msg;
}

}  // namespace vslam::eval
