// An LCM log file as it may be found (cut short by a crash, damaged on
// disk, not a log at all) through the one log reader (bus::LogReader): the
// strict reading of the evaluation tools must refuse damage with a LogError
// naming the byte, the replay's skipping reading must get through any file
// without an exception, and neither may crash, hang or read past the file.

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "bus/log_reader.hpp"
#include "bus/log_writer.hpp"
#include "fuzz_target.hpp"
#include "transport/message_fill.hpp"

namespace fs = std::filesystem;

namespace {

fs::path scratchFile() {
  static const fs::path file = vslam::fuzz::scratchDir("log") / "log";
  return file;
}

int64_t readAll(vslam::bus::LogDamage mode) {
  vslam::bus::LogReader reader(scratchFile(), mode);
  int64_t n = 0;
  while (const lcm::LogEvent* e = reader.next()) {
    if (e->datalen < 0) std::abort();  // the reader hands out only whole events
    ++n;
  }
  return n;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::ofstream(scratchFile(), std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  for (const auto mode : {vslam::bus::LogDamage::kThrow, vslam::bus::LogDamage::kCutTail}) {
    try {
      (void)readAll(mode);
    } catch (const vslam::bus::LogError& e) {
      if (std::string(e.what()).empty()) std::abort();
    }
  }
  (void)readAll(vslam::bus::LogDamage::kSkip);  // must not throw: damage is skipped
  return 0;
}

std::vector<std::string> vslam::fuzz::seeds() {
  {
    vslam::bus::LogWriter writer(scratchFile());
    int64_t t = 1700000000000000;
    using namespace vslam::transport_test;
    forEachType(AllTypes{}, [&](auto tag) {
      typename decltype(tag)::type m;
      fill(m, 1);
      writer.writeMessage(t += 1000, "CHANNEL_" + std::to_string(writer.eventsWritten()), m);
    });
  }
  std::ifstream in(scratchFile(), std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return {s.str(), ""};
}
