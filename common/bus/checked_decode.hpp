#pragma once
// Decoding an LCM message that came from outside the process (the network, a
// log file): the only way the stack decodes one.
//
// The decoder lcm-gen 1.3.1 writes trusts the counts in the message: it
// resizes a vector to the claimed count before it looks for the bytes, and
// checks count * sizeof(element) in int, which overflows. One 39-byte
// landmark_request_t claiming 5e8 ids made it zero-fill gigabytes and read
// past the buffer. So the bytes are walked first by the wire check generated
// from the .lcm files (cmake/lcm_wire_check.py): every count and string
// length against the bytes actually there, in 64 bits, before anything is
// allocated. Only a message that passes is handed to the decoder.

#include <climits>
#include <cstddef>
#include <string>
#include <vslam_lcmtypes/wire_check.hpp>

namespace vslam::bus {

// Decodes data[0, size) into msg if it is exactly one well-formed Msg.
// Otherwise returns false, leaves msg in an unspecified but valid state, and
// sets *why (if not null) to the reason, naming the type and the field, e.g.
// "vslam.landmark_request_t: landmark_ids: 500000000 elements of >= 8 bytes
// need >= 4000000000 bytes, 0 left".
template <class Msg>
bool checkedDecode(Msg& msg, const void* data, size_t size, std::string* why) {
  const std::string type = wire::Walker<Msg>::kName;
  if (size > static_cast<size_t>(INT_MAX)) {
    if (why) *why = type + ": " + std::to_string(size) + " bytes, more than LCM can decode";
    return false;
  }
  std::string reason;
  if (!wire::check<Msg>(data, size, &reason)) {
    if (why) *why = type + ": " + reason;
    return false;
  }
  // The check walked exactly what the decoder reads; a disagreement would be
  // a bug in the generator, reported rather than trusted.
  const int used = msg.decode(data, 0, static_cast<int>(size));
  if (used != static_cast<int>(size)) {
    if (why) {
      *why = type + ": passed the wire check but the decoder " +
             (used < 0 ? std::string("refused it") : "read " + std::to_string(used) + " bytes");
    }
    return false;
  }
  return true;
}

}  // namespace vslam::bus
