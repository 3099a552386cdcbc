#include "sim/scenario.hpp"

#include <cctype>
#include <sstream>
#include <stdexcept>

#include "util/angles.hpp"

namespace vslam::sim {
namespace {

using config::ConfigNode;
using config::InRange;

Pose2 readPose(const ConfigNode& node, const std::string& key) {
  const auto v = node.getDoubles(key, 3, InRange{-1000, 1000});
  return {v[0], v[1], wrapAngle(degToRad(v[2]))};
}

}  // namespace

std::vector<char> parseActions(const std::string& text) {
  std::vector<char> out;
  std::istringstream in(text);
  std::string token;
  while (in >> token) {
    const char kind = static_cast<char>(std::toupper(static_cast<unsigned char>(token[0])));
    if (kind != 'F' && kind != 'L' && kind != 'R') {
      throw std::invalid_argument("action '" + token +
                                  "': expected F, L or R with an optional count");
    }
    int count = 1;
    if (token.size() > 1) {
      const std::string digits = token.substr(1);
      for (char c : digits) {
        if (!std::isdigit(static_cast<unsigned char>(c))) {
          throw std::invalid_argument("action '" + token + "': the count must be a whole number");
        }
      }
      count = std::stoi(digits);
      if (count < 1 || count > 1000) {
        throw std::invalid_argument("action '" + token + "': count out of 1..1000");
      }
    }
    out.insert(out.end(), static_cast<size_t>(count), kind);
  }
  return out;
}

Scenario Scenario::load(const ConfigNode& node) {
  Scenario s;
  s.file = node.file();
  s.name = node.getString("name");
  s.world_file = node.getPath("world");
  s.seed = static_cast<uint64_t>(node.getInt("seed", 1, InRange{0, 1e15}));
  s.duration_s = node.getDouble("duration_s", 0.0, InRange{0, 86400});
  s.max_duration_s = node.getDouble("max_duration_s", 3600.0, InRange{1, 86400});

  const ConfigNode m = node.child("motion");
  const std::string mode = m.getEnum("mode", {"waypoints", "random", "actions", "trajectory"});
  MotionParams& mp = s.motion;
  mp.speed_mps = m.getDouble("speed_mps", 0.3, InRange{0.01, 2.0});
  mp.turn_rate_rps = degToRad(m.getDouble("turn_rate_dps", 45.0, InRange{1, 360}));
  mp.robot_radius_m = m.getDouble("robot_radius_m", 0.2, InRange{0.05, 1.0});
  if (mode != "trajectory" && m.has("start")) {
    mp.start = readPose(m, "start");
    mp.has_start = true;
  } else {
    m.markUsed("start");
  }
  if (mode == "waypoints") {
    mp.mode = MotionMode::kWaypoints;
    if (m.has("route") == m.has("waypoints")) {
      throw m.error(
          "waypoints",
          "give either `waypoints` ([[x, y], ...]) or `route` (a route of the world file)");
    }
    if (m.has("route")) {
      mp.route = m.getString("route");
    } else {
      for (const auto& row : m.getDoubleRows("waypoints", 2, InRange{-1000, 1000})) {
        mp.waypoints.emplace_back(row[0], row[1]);
      }
      if (mp.waypoints.size() < 2) throw m.error("waypoints", "at least two waypoints are needed");
    }
    m.markUsed("route");
    m.markUsed("waypoints");
    mp.laps = static_cast<int>(m.getInt("laps", 1, InRange{1, 1000}));
  } else if (mode == "random") {
    mp.mode = MotionMode::kRandom;
    mp.lookahead_m = m.getDouble("lookahead_m", 0.5, InRange{0.05, 5});
    if (!node.has("duration_s")) {
      throw node.error("duration_s", "random motion needs a duration_s > 0");
    }
  } else if (mode == "actions") {
    mp.mode = MotionMode::kActions;
    mp.actions = m.getString("actions");
    try {
      parseActions(mp.actions);
    } catch (const std::invalid_argument& e) {
      throw m.error("actions", e.what());
    }
    mp.laps = static_cast<int>(m.getInt("laps", 1, InRange{1, 1000}));
    mp.action_length_m = m.getDouble("action_length_m", 1.0, InRange{0.01, 100});
    mp.action_turn_rad = degToRad(m.getDouble("action_turn_deg", 90.0, InRange{1, 180}));
    mp.action_error = m.getDouble("action_error", 0.03, InRange{0, 0.5});
    mp.action_pause_s = m.getDouble("action_pause_s", 0.5, InRange{0, 60});
  } else {
    mp.mode = MotionMode::kTrajectory;
    mp.trajectory_file = m.getPath("trajectory_file");
    if (m.has("odometry_file")) {
      mp.odometry_file = m.getPath("odometry_file");
    } else {
      m.markUsed("odometry_file");
    }
  }
  m.requireAllKeysUsed();

  const ConfigNode o = node.child("odometry");
  s.odometry.rate_hz = o.getDouble("rate_hz", 50.0, InRange{1, 1000});
  s.odometry.sigma_translation = o.getDouble("sigma_translation", config::nonNegative());
  s.odometry.sigma_rotation = o.getDouble("sigma_rotation", config::nonNegative());
  s.odometry.scale_bias = o.getDouble("scale_bias", 0.0, InRange{-0.5, 0.5});
  s.odometry.heading_bias = o.getDouble("heading_bias", 0.0, InRange{-1, 1});
  if (o.has("slips")) {
    for (const ConfigNode& e : o.sequence("slips")) {
      SlipEvent slip;
      slip.at_s = e.getDouble("at_s", config::nonNegative());
      slip.duration_s = e.getDouble("duration_s", config::positive());
      slip.translation_factor = e.getDouble("translation_factor", 1.0, InRange{0, 10});
      slip.rotation_factor = e.getDouble("rotation_factor", 1.0, InRange{0, 10});
      e.requireAllKeysUsed();
      s.odometry.slips.push_back(slip);
    }
  } else {
    o.markUsed("slips");
  }
  o.requireAllKeysUsed();

  if (node.has("cameras")) {
    const ConfigNode c = node.child("cameras");
    s.cameras.encoding = c.getString("encoding", "gray8");
    if (s.cameras.encoding != "gray8" && s.cameras.encoding != "bgr8" &&
        s.cameras.encoding != "jpeg") {
      c.getEnum("encoding", {"gray8", "bgr8", "jpeg"});
    }
    s.cameras.jpeg_quality = static_cast<int>(c.getInt("jpeg_quality", 90, InRange{10, 100}));
    s.cameras.noise_sigma = c.getDouble("noise_sigma", 1.5, InRange{0, 50});
    s.cameras.motion_blur = c.getBool("motion_blur", true);
    s.cameras.blur_samples = static_cast<int>(c.getInt("blur_samples", 3, InRange{2, 16}));
    s.cameras.exposure_time_s = c.getDouble("exposure_time_s", 0.012, InRange{0.0001, 0.2});
    c.requireAllKeysUsed();
  } else {
    node.markUsed("cameras");
  }

  if (node.has("disturbances")) {
    const ConfigNode d = node.child("disturbances");
    if (d.has("kidnap")) {
      for (const ConfigNode& e : d.sequence("kidnap")) {
        s.kidnaps.push_back({e.getDouble("at_s", config::nonNegative()), readPose(e, "to")});
        e.requireAllKeysUsed();
      }
    } else {
      d.markUsed("kidnap");
    }
    if (d.has("lights")) {
      for (const ConfigNode& e : d.sequence("lights")) {
        LightEvent l;
        l.at_s = e.getDouble("at_s", config::nonNegative());
        l.duration_s = e.getDouble("duration_s", 0.0, config::nonNegative());
        l.exposure = e.getDouble("exposure", InRange{0.01, 10});
        e.requireAllKeysUsed();
        s.lights.push_back(l);
      }
    } else {
      d.markUsed("lights");
    }
    if (d.has("people")) {
      const ConfigNode p = d.child("people");
      s.people.count = static_cast<int>(p.getInt("count", InRange{0, 50}));
      s.people.speed_mps = p.getDouble("speed_mps", 0.6, InRange{0.05, 3});
      s.people.height_m = p.getDouble("height_m", 1.7, InRange{0.3, 2.5});
      s.people.width_m = p.getDouble("width_m", 0.45, InRange{0.1, 2});
      s.people.depth_m = p.getDouble("depth_m", 0.3, InRange{0.1, 2});
      s.people.texture = p.getString("texture", s.people.texture);
      p.requireAllKeysUsed();
    } else {
      d.markUsed("people");
    }
    d.requireAllKeysUsed();
  } else {
    node.markUsed("disturbances");
  }
  node.requireAllKeysUsed();
  return s;
}

Scenario Scenario::loadByName(const std::string& name_or_path,
                              const std::filesystem::path& scenario_dir) {
  std::filesystem::path file(name_or_path);
  if (file.extension() != ".yaml" && file.extension() != ".yml") {
    file = scenario_dir / (name_or_path + ".yaml");
  }
  return load(ConfigNode::loadFile(file));
}

}  // namespace vslam::sim
