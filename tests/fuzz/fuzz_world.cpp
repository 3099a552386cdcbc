// A world file and a scenario file as a user might break them: YAML text
// through World::loadString (docs/world-format.md) and Scenario::load. A bad
// file must be an exception with a message (ConfigError naming the key, or
// the texture loader's runtime_error naming the file); a crash, a hang or a
// sanitizer report is a finding.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "fuzz_target.hpp"
#include "sim/scenario.hpp"
#include "world/world.hpp"

namespace fs = std::filesystem;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const fs::path worlds = fs::path(VSLAM_SOURCE_DIR) / "config/worlds";
  try {
    (void)vslam::world::World::loadString(text, "fuzz-world.yaml", worlds);
  } catch (const std::exception& e) {
    if (std::string(e.what()).empty()) std::abort();
  }
  try {
    const auto node = vslam::config::ConfigNode::loadString(
        text, "fuzz-scenario.yaml", fs::path(VSLAM_SOURCE_DIR) / "config/scenarios");
    (void)vslam::sim::Scenario::load(node);
  } catch (const std::exception& e) {
    if (std::string(e.what()).empty()) std::abort();
  }
  return 0;
}

std::vector<std::string> vslam::fuzz::seeds() {
  std::vector<std::string> out;
  for (const char* dir : {"config/worlds", "config/scenarios"}) {
    for (const auto& entry : fs::directory_iterator(fs::path(VSLAM_SOURCE_DIR) / dir)) {
      if (entry.path().extension() != ".yaml") continue;
      std::ifstream in(entry.path());
      std::stringstream s;
      s << in.rdbuf();
      out.push_back(s.str());
    }
  }
  return out;
}
