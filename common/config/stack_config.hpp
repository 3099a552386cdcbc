#pragma once
// The configuration of a whole stack: one file (config/vslam.yaml) that names
// the robot file, the LCM URL, health settings, blocks shared by several
// stages (`prefilter:`, read by stages/prefilter_config.hpp) and one block
// per process instance under `processes:`. Each block has a `role` (which program/stage
// reads it) and that stage's parameters.

#include <filesystem>
#include <string>
#include <vector>

#include "config/config_node.hpp"
#include "config/robot_config.hpp"

namespace vslam::config {

// Lossless for camera images on loopback with LCM 1.3.1: the kernel's default
// socket buffer (208 KiB) loses 90-99% of 300 KB frames.
inline constexpr const char* kDefaultLcmUrl =
    "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";

struct StackConfig {
  ConfigNode root;
  RobotConfig robot;
  std::string lcm_url;         // "" when the file does not set one
  double health_period_s = 1;  // seconds between health messages

  static StackConfig loadFile(const std::filesystem::path& file);

  // The `processes.<instance>` block; ConfigError if absent.
  ConfigNode process(const std::string& instance) const;
  std::vector<std::string> instances() const;
  // The `role` of an instance (marks the key as read).
  std::string roleOf(const std::string& instance) const;
  // The cameras an instance's block names (its `camera:` or `cameras:`) that
  // the robot file does not have: such an instance cannot run with this
  // robot (a two-camera config with a one-camera robot file).
  std::vector<std::string> absentCameras(const std::string& instance) const;
};

// The stack config file to read: `command_line` if given, else
// $VSLAM_CONFIG, else kDefaultStackConfig (relative to the working directory).
inline constexpr const char* kDefaultStackConfig = "config/vslam.yaml";
std::string resolveStackConfig(const std::string& command_line);

// Precedence: command line, then LCM_DEFAULT_URL, then the config file, then
// kDefaultLcmUrl. A udpm URL without recv_buf_size gets a warning: it will
// drop most camera frames.
std::string resolveLcmUrl(const std::string& command_line, const std::string& config_url);

}  // namespace vslam::config
