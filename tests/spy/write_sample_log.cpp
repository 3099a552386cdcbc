// Writes an LCM log with three messages of every vslam type (filled by the
// transport tests' fill()), one channel per type, for the lcm-spy decode test.
#include <cctype>
#include <cstdio>
#include <lcm/lcm-cpp.hpp>
#include <string>
#include <vector>

#include "message_fill.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT.lcmlog\n", argv[0]);
    return 2;
  }
  lcm::LogFile log(argv[1], "w");
  if (!log.good()) return 1;
  int64_t eventnum = 0;
  bool ok = true;
  vslam::transport_test::forEachType(vslam::transport_test::AllTypes{}, [&](auto tag) {
    using Msg = typename decltype(tag)::type;
    std::string channel = "SPY_";
    for (char c : std::string(Msg::getTypeName())) channel += static_cast<char>(std::toupper(c));
    for (int seed = 0; seed < 3; ++seed) {
      Msg msg;
      vslam::transport_test::fill(msg, seed);
      std::vector<uint8_t> buf(static_cast<size_t>(msg.getEncodedSize()));
      msg.encode(buf.data(), 0, static_cast<int>(buf.size()));
      lcm::LogEvent ev;
      ev.eventnum = eventnum;
      ev.timestamp = 1700000000000000 + eventnum * 1000;
      ++eventnum;
      ev.channel = channel;
      ev.datalen = static_cast<int32_t>(buf.size());
      ev.data = buf.data();
      ok = ok && log.writeEvent(&ev) == 0;
    }
  });
  return ok ? 0 : 1;
}
