#include "sim/scenario.hpp"

#include <cctype>
#include <optional>
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

// An optional block: nothing if the key is absent (which then counts as read).
std::optional<ConfigNode> optionalChild(const ConfigNode& node, const std::string& key) {
  if (node.has(key)) return node.child(key);
  node.markUsed(key);
  return std::nullopt;
}

// An optional list: empty if the key is absent (which then counts as read).
std::vector<ConfigNode> optionalSequence(const ConfigNode& node, const std::string& key) {
  if (node.has(key)) return node.sequence(key);
  node.markUsed(key);
  return {};
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

namespace {

// Fallbacks are the structs' defaults, but for the turn rates: the file gives
// degrees and the structs radians.

// motion: mode waypoints: a list of waypoints or a route of the world file.
// A key written in degrees into a value held in radians, left at its
// default (the struct's) when absent.
void readDegrees(const ConfigNode& m, const std::string& key, InRange range, double* radians) {
  if (m.has(key)) *radians = degToRad(m.getDouble(key, range));
}

void readWaypoints(const ConfigNode& m, MotionParams& mp) {
  mp.mode = MotionMode::kWaypoints;
  if (m.has("route") == m.has("waypoints")) {
    throw m.error("waypoints",
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
  mp.laps = static_cast<int>(m.getInt("laps", mp.laps, InRange{1, 1000}));
}

// motion: mode actions: a string of F, L and R moves of fixed size.
void readActions(const ConfigNode& m, MotionParams& mp) {
  mp.mode = MotionMode::kActions;
  mp.actions = m.getString("actions");
  try {
    parseActions(mp.actions);
  } catch (const std::invalid_argument& e) {
    throw m.error("actions", e.what());
  }
  mp.laps = static_cast<int>(m.getInt("laps", mp.laps, InRange{1, 1000}));
  mp.action_length_m = m.getDouble("action_length_m", mp.action_length_m, InRange{0.01, 100});
  readDegrees(m, "action_turn_deg", InRange{1, 180}, &mp.action_turn_rad);
  mp.action_error = m.getDouble("action_error", mp.action_error, InRange{0, 0.5});
  mp.action_pause_s = m.getDouble("action_pause_s", mp.action_pause_s, InRange{0, 60});
}

// The scenario's `motion` block (random motion needs the scenario's duration).
MotionParams readMotion(const ConfigNode& node) {
  const ConfigNode m = node.child("motion");
  const std::string mode = m.getEnum("mode", {"waypoints", "random", "actions", "trajectory"});
  MotionParams mp;
  mp.speed_mps = m.getDouble("speed_mps", mp.speed_mps, InRange{0.01, 2.0});
  readDegrees(m, "turn_rate_dps", InRange{1, 360}, &mp.turn_rate_rps);
  mp.robot_radius_m = m.getDouble("robot_radius_m", mp.robot_radius_m, InRange{0.05, 1.0});
  if (mode != "trajectory" && m.has("start")) {
    mp.start = readPose(m, "start");
    mp.has_start = true;
  } else {
    m.markUsed("start");
  }
  if (mode == "waypoints") {
    readWaypoints(m, mp);
  } else if (mode == "random") {
    mp.mode = MotionMode::kRandom;
    mp.lookahead_m = m.getDouble("lookahead_m", mp.lookahead_m, InRange{0.05, 5});
    if (!node.has("duration_s")) {
      throw node.error("duration_s", "random motion needs a duration_s > 0");
    }
  } else if (mode == "actions") {
    readActions(m, mp);
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
  return mp;
}

// The scenario's `odometry` block: noise, biases and wheel slips.
OdometryParams readOdometry(const ConfigNode& node) {
  const ConfigNode o = node.child("odometry");
  OdometryParams op;
  op.rate_hz = o.getDouble("rate_hz", op.rate_hz, InRange{1, 1000});
  op.sigma_translation = o.getDouble("sigma_translation", config::nonNegative());
  op.sigma_rotation = o.getDouble("sigma_rotation", config::nonNegative());
  op.scale_bias = o.getDouble("scale_bias", op.scale_bias, InRange{-0.5, 0.5});
  op.heading_bias = o.getDouble("heading_bias", op.heading_bias, InRange{-1, 1});
  for (const ConfigNode& e : optionalSequence(o, "slips")) {
    SlipEvent slip;
    slip.at_s = e.getDouble("at_s", config::nonNegative());
    slip.duration_s = e.getDouble("duration_s", config::positive());
    slip.translation_factor =
        e.getDouble("translation_factor", slip.translation_factor, InRange{0, 10});
    slip.rotation_factor = e.getDouble("rotation_factor", slip.rotation_factor, InRange{0, 10});
    e.requireAllKeysUsed();
    op.slips.push_back(slip);
  }
  o.requireAllKeysUsed();
  return op;
}

// The scenario's optional `cameras` block: image encoding and noise.
CameraParams readCameras(const ConfigNode& node) {
  CameraParams cp;
  const std::optional<ConfigNode> block = optionalChild(node, "cameras");
  if (!block) return cp;
  const ConfigNode& c = *block;
  cp.encoding = c.getString("encoding", cp.encoding);
  if (cp.encoding != "gray8" && cp.encoding != "bgr8" && cp.encoding != "jpeg") {
    c.getEnum("encoding", {"gray8", "bgr8", "jpeg"});
  }
  cp.jpeg_quality = static_cast<int>(c.getInt("jpeg_quality", cp.jpeg_quality, InRange{10, 100}));
  cp.noise_sigma = c.getDouble("noise_sigma", cp.noise_sigma, InRange{0, 50});
  cp.motion_blur = c.getBool("motion_blur", cp.motion_blur);
  cp.blur_samples = static_cast<int>(c.getInt("blur_samples", cp.blur_samples, InRange{2, 16}));
  cp.exposure_time_s = c.getDouble("exposure_time_s", cp.exposure_time_s, InRange{0.0001, 0.2});
  c.requireAllKeysUsed();
  return cp;
}

// disturbances: people walking about.
PeopleParams readPeople(const ConfigNode& d) {
  PeopleParams pp;
  const std::optional<ConfigNode> block = optionalChild(d, "people");
  if (!block) return pp;
  const ConfigNode& p = *block;
  pp.count = static_cast<int>(p.getInt("count", InRange{0, 50}));
  pp.speed_mps = p.getDouble("speed_mps", pp.speed_mps, InRange{0.05, 3});
  pp.height_m = p.getDouble("height_m", pp.height_m, InRange{0.3, 2.5});
  pp.width_m = p.getDouble("width_m", pp.width_m, InRange{0.1, 2});
  pp.depth_m = p.getDouble("depth_m", pp.depth_m, InRange{0.1, 2});
  pp.texture = p.getString("texture", pp.texture);
  p.requireAllKeysUsed();
  return pp;
}

// The scenario's optional `disturbances` block: kidnappings, lights, people.
void readDisturbances(const ConfigNode& node, Scenario& s) {
  const std::optional<ConfigNode> block = optionalChild(node, "disturbances");
  if (!block) return;
  const ConfigNode& d = *block;
  for (const ConfigNode& e : optionalSequence(d, "kidnap")) {
    s.kidnaps.push_back({e.getDouble("at_s", config::nonNegative()), readPose(e, "to")});
    e.requireAllKeysUsed();
  }
  for (const ConfigNode& e : optionalSequence(d, "lights")) {
    LightEvent l;
    l.at_s = e.getDouble("at_s", config::nonNegative());
    l.duration_s = e.getDouble("duration_s", l.duration_s, config::nonNegative());
    l.exposure = e.getDouble("exposure", InRange{0.01, 10});
    e.requireAllKeysUsed();
    s.lights.push_back(l);
  }
  s.people = readPeople(d);
  d.requireAllKeysUsed();
}

}  // namespace

Scenario Scenario::load(const ConfigNode& node) {
  Scenario s;
  s.file = node.file();
  s.name = node.getString("name");
  s.world_file = node.getPath("world");
  s.seed =
      static_cast<uint64_t>(node.getInt("seed", static_cast<int64_t>(s.seed), InRange{0, 1e15}));
  s.duration_s = node.getDouble("duration_s", s.duration_s, InRange{0, 86400});
  s.max_duration_s = node.getDouble("max_duration_s", s.max_duration_s, InRange{1, 86400});
  s.motion = readMotion(node);
  s.odometry = readOdometry(node);
  s.cameras = readCameras(node);
  readDisturbances(node, s);
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
