// A configuration file as an operator might break it: YAML text parsed by
// ConfigNode and read as the block of every role that declares its keys
// (config/param_table.hpp) and as the top-level pre-filter. Anything wrong
// must be a ConfigError naming the key; any other exception or a crash is a
// finding.
#include <cstdlib>
#include <filesystem>

#include "config/config_node.hpp"
#include "fuzz_target.hpp"
#include "stages/builtin_stages.hpp"
#include "stages/prefilter_config.hpp"

namespace fs = std::filesystem;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const auto root = vslam::config::ConfigNode::loadString(text, "fuzz.yaml",
                                                            fs::path(VSLAM_SOURCE_DIR) / "config");
    for (const auto* registry : {&vslam::stages::builtinStages(), &vslam::stages::driverStages()}) {
      for (const auto& role : registry->roles()) {
        try {
          (void)registry->describeParams(role, &root);
        } catch (const vslam::config::ConfigError&) {
        }
      }
    }
    vslam::backend::PrefilterParams prefilter;
    vslam::stages::prefilterParamTable().load(root, prefilter);
  } catch (const vslam::config::ConfigError&) {
  }
  return 0;
}

std::vector<std::string> vslam::fuzz::seeds() {
  // Every process block of the shipped configs, as the roles read them, and
  // the pre-filter block.
  std::vector<std::string> out;
  for (const char* file :
       {"config/vslam.yaml", "config/vslam-one-camera.yaml", "config/vslam-video-robot.yaml"}) {
    const YAML::Node root = YAML::LoadFile((fs::path(VSLAM_SOURCE_DIR) / file).string());
    for (const auto& kv : root["processes"]) out.push_back(YAML::Dump(kv.second));
    if (root["prefilter"]) out.push_back(YAML::Dump(root["prefilter"]));
  }
  return out;
}
