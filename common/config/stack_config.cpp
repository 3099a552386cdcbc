#include "config/stack_config.hpp"

#include <algorithm>
#include <cstdlib>

#include "util/log.hpp"

namespace vslam::config {

StackConfig StackConfig::loadFile(const std::filesystem::path& file) {
  StackConfig stack{ConfigNode::loadFile(file), {}, "", 1.0};
  const ConfigNode& root = stack.root;
  stack.robot = RobotConfig::loadFile(root.getPath("robot"));
  if (root.has("lcm")) {
    const ConfigNode lcm = root.child("lcm");
    stack.lcm_url = lcm.getString("url");
    lcm.requireAllKeysUsed();
  } else {
    root.markUsed("lcm");
  }
  stack.health_period_s =
      root.getDouble("health_period_s", stack.health_period_s, InRange{0.05, 60});
  // Shared by the front-ends and the back-end, read by them
  // (stages/prefilter_config.hpp).
  root.markUsed("prefilter");
  const ConfigNode processes = root.child("processes");
  for (const auto& instance : processes.keys()) {
    if (!processes.child(instance).has("role")) {
      throw processes.error(instance, "missing key 'role' (the program that reads this block)");
    }
  }
  root.requireAllKeysUsed();
  return stack;
}

ConfigNode StackConfig::process(const std::string& instance) const {
  const ConfigNode processes = root.child("processes");
  if (!processes.has(instance)) {
    std::string known;
    for (const auto& k : processes.keys()) known += (known.empty() ? "" : ", ") + k;
    throw processes.error(instance, "no such process instance; known instances: " + known);
  }
  return processes.child(instance);
}

std::vector<std::string> StackConfig::instances() const { return root.child("processes").keys(); }

std::string StackConfig::roleOf(const std::string& instance) const {
  return process(instance).getString("role");
}

std::vector<std::string> StackConfig::absentCameras(const std::string& instance) const {
  const ConfigNode block = process(instance);
  std::vector<std::string> named;
  if (block.has("camera")) named.push_back(block.getString("camera"));
  if (block.has("cameras")) {
    for (const auto& name : block.getStrings("cameras")) named.push_back(name);
  }
  std::vector<std::string> absent;
  for (const auto& name : named) {
    const bool known = std::any_of(robot.cameras.begin(), robot.cameras.end(),
                                   [&](const CameraConfig& c) { return c.name == name; });
    if (!known) absent.push_back(name);
  }
  return absent;
}

std::string resolveStackConfig(const std::string& command_line) {
  if (!command_line.empty()) return command_line;
  const char* env = std::getenv("VSLAM_CONFIG");
  return env && *env ? env : kDefaultStackConfig;
}

std::string resolveLcmUrl(const std::string& command_line, const std::string& config_url) {
  std::string url;
  if (!command_line.empty()) {
    url = command_line;
  } else if (const char* env = std::getenv("LCM_DEFAULT_URL"); env && *env) {
    url = env;
  } else if (!config_url.empty()) {
    url = config_url;
  } else {
    url = kDefaultLcmUrl;
  }
  if (url.rfind("udpm://", 0) == 0 && url.find("recv_buf_size") == std::string::npos) {
    log::warn("LCM URL ", url,
              " sets no recv_buf_size: camera images will be dropped; add "
              "recv_buf_size=8388608");
  }
  return url;
}

}  // namespace vslam::config
