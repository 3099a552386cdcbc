// Writes an LCM log with three messages of every vslam type (filled by the
// transport tests' fill()), one channel per type, for the lcm-spy decode test.
#include <cctype>
#include <cstdio>
#include <exception>
#include <string>

#include "bus/log_writer.hpp"
#include "message_fill.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT.lcmlog\n", argv[0]);
    return 2;
  }
  try {
    vslam::bus::LogWriter log(argv[1]);
    vslam::transport_test::forEachType(vslam::transport_test::AllTypes{}, [&](auto tag) {
      using Msg = typename decltype(tag)::type;
      std::string channel = "SPY_";
      for (char c : std::string(Msg::getTypeName())) channel += static_cast<char>(std::toupper(c));
      for (int seed = 0; seed < 3; ++seed) {
        Msg msg;
        vslam::transport_test::fill(msg, seed);
        log.writeMessage(1700000000000000 + log.eventsWritten() * 1000, channel, msg);
      }
    });
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}
