#include "config/robot_config.hpp"

#include <cmath>
#include <opencv2/core.hpp>
#include <ostream>
#include <set>

#include "util/angles.hpp"

namespace vslam::config {

const std::vector<ChannelNames::Field>& ChannelNames::fields() {
  using C = ChannelNames;
  static const std::vector<Field> all = {
      {"odometry", &C::odometry},
      {"ground_truth", &C::ground_truth},
      {"health", &C::health},
      {"pose_estimate", &C::pose_estimate},
      {"pose_odometry", &C::pose_odometry},
      {"visual_measurement", &C::visual_measurement},
      {"visual_measurement_filtered", &C::visual_measurement_filtered},
      {"landmark_proposal", &C::landmark_proposal},
      {"landmark_update", &C::landmark_update},
      {"landmark_summary", &C::landmark_summary},
      {"landmark_request", &C::landmark_request},
      {"map", &C::map},
      {"particles", &C::particles},
      {"appearance_hypotheses", &C::appearance_hypotheses},
      {"appearance_map", &C::appearance_map},
      {"appearance_event", &C::appearance_event},
      {"view_jump", &C::view_jump},
  };
  return all;
}
CameraIntrinsics readOpenCvCalibration(const std::filesystem::path& file) {
  const std::string name = file.string();
  auto fail = [&](const std::string& what, const std::string& problem) {
    return ConfigError(name, what, problem);
  };
  if (std::error_code ec; !std::filesystem::is_regular_file(file, ec)) {
    throw fail("", "no such calibration file");
  }
  cv::FileStorage fs;
  try {
    fs.open(name, cv::FileStorage::READ);
  } catch (const cv::Exception& e) {
    throw fail("", std::string("not an OpenCV calibration file: ") + e.what());
  }
  if (!fs.isOpened()) throw fail("", "cannot be read as an OpenCV calibration file");
  CameraIntrinsics c;
  cv::Mat k, d;
  try {
    if (fs["image_width"].empty() || fs["image_height"].empty()) {
      throw fail("image_width", "image_width/image_height missing");
    }
    c.width = static_cast<int>(fs["image_width"]);
    c.height = static_cast<int>(fs["image_height"]);
    fs["camera_matrix"] >> k;
    if (!fs["distortion_coefficients"].empty()) fs["distortion_coefficients"] >> d;
  } catch (const cv::Exception& e) {
    throw fail("", std::string("malformed calibration: ") + e.what());
  }
  if (k.rows != 3 || k.cols != 3) throw fail("camera_matrix", "must be a 3x3 matrix");
  k.convertTo(k, CV_64F);
  c.fx = k.at<double>(0, 0);
  c.fy = k.at<double>(1, 1);
  c.cx = k.at<double>(0, 2);
  c.cy = k.at<double>(1, 2);
  if (c.width <= 0 || c.height <= 0 || c.width > 8192 || c.height > 8192) {
    throw fail("image_width", "image_width/image_height must be in 1..8192");
  }
  if (!(c.fx > 0) || !(c.fy > 0)) throw fail("camera_matrix", "focal lengths must be > 0");
  if (!d.empty()) {
    d.convertTo(d, CV_64F);
    const size_t n = d.total();
    static const std::set<size_t> kValid = {4, 5, 8, 12, 14};
    if (!kValid.count(n)) {
      throw fail("distortion_coefficients",
                 "must have 4, 5, 8, 12 or 14 entries, has " + std::to_string(n));
    }
    for (size_t i = 0; i < n; ++i) c.distortion.push_back(d.at<double>(static_cast<int>(i)));
  }
  return c;
}

Eigen::Matrix3d robotRotationCamera(double yaw_rad, double pitch_rad, double roll_rad) {
  // Columns: the camera's x (right), y (down), z (optical axis) in the robot
  // frame for a forward-looking level camera.
  Eigen::Matrix3d forward;
  forward << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  const Eigen::Matrix3d r = (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()) *
                             Eigen::AngleAxisd(-pitch_rad, Eigen::Vector3d::UnitY()) *
                             Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitX()))
                                .toRotationMatrix();
  return r * forward;
}

Alternation readAlternation(const ConfigNode& node, const std::string& key, double rate_hz) {
  Alternation a;
  if (!node.has(key)) return a;
  const ConfigNode n = node.child(key);
  a.slots = static_cast<int>(n.getInt("slots", InRange{1, 1000}));
  a.slot = static_cast<int>(n.getInt("slot", InRange{0, 999}));
  n.requireAllKeysUsed();
  if (a.slot >= a.slots) {
    throw n.error("slot", "slot " + std::to_string(a.slot) + " of " + std::to_string(a.slots) +
                              " slots: slots are numbered 0.." + std::to_string(a.slots - 1));
  }
  try {
    checkAlternation(a, rate_hz);
  } catch (const std::invalid_argument& e) {
    throw n.error("slots", e.what());
  }
  return a;
}

RobotConfig RobotConfig::load(const ConfigNode& node) {
  RobotConfig robot;
  robot.file = node.file();
  robot.name = node.getString("name");

  std::set<std::string> names, channels_seen;
  for (const ConfigNode& c : node.sequence("cameras")) {
    CameraConfig cam;
    cam.name = c.getString("name");
    if (!names.insert(cam.name).second)
      throw c.error("name", "duplicate camera '" + cam.name + "'");
    cam.calibration_file = c.getPath("calibration");
    const CameraIntrinsics k = readOpenCvCalibration(cam.calibration_file);
    cam.width = k.width;
    cam.height = k.height;
    cam.fx = k.fx;
    cam.fy = k.fy;
    cam.cx = k.cx;
    cam.cy = k.cy;
    cam.distortion = k.distortion;
    cam.frame_rate_hz = c.getDouble("frame_rate_hz", InRange{0.1, 1000});
    cam.alternate = readAlternation(c, "alternate", cam.frame_rate_hz);
    const auto t = c.getDoubles("position_m", 3, InRange{-10, 10});
    const ConfigNode o = c.child("orientation_deg");
    const double yaw = degToRad(o.getDouble("yaw", InRange{-360, 360}));
    const double pitch = degToRad(o.getDouble("pitch", InRange{-90, 90}));
    const double roll = degToRad(o.getDouble("roll", InRange{-180, 180}));
    o.requireAllKeysUsed();
    cam.robot_T_camera.linear() = robotRotationCamera(yaw, pitch, roll);
    cam.robot_T_camera.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
    cam.image_channel = c.getChannel("image_channel");
    cam.calibration_channel = c.getChannel("calibration_channel");
    c.requireAllKeysUsed();
    robot.cameras.push_back(cam);
  }
  if (robot.cameras.empty()) throw node.error("cameras", "at least one camera is required");

  const ConfigNode ch = node.child("channels");
  for (const auto& f : ChannelNames::fields()) robot.channels.*f.member = ch.getChannel(f.key);
  ch.requireAllKeysUsed();

  // A channel carries one type: no two roles may share a name.
  for (const std::string& key : ch.keys()) {
    if (!channels_seen.insert(ch.getString(key)).second) {
      throw ch.error(key, "channel '" + ch.getString(key) + "' is used twice");
    }
  }
  for (const auto& cam : robot.cameras) {
    for (const auto* c : {&cam.image_channel, &cam.calibration_channel}) {
      if (!channels_seen.insert(*c).second) {
        throw node.error("cameras",
                         "channel '" + *c + "' of camera '" + cam.name + "' is used twice");
      }
    }
  }
  // Cameras taking turns must share the period and not the slot.
  const CameraConfig* first_alternating = nullptr;
  std::set<int> slots_taken;
  for (const auto& cam : robot.cameras) {
    if (!cam.alternate.active()) continue;
    if (!first_alternating) first_alternating = &cam;
    if (cam.alternate.slots != first_alternating->alternate.slots ||
        cam.frame_rate_hz != first_alternating->frame_rate_hz) {
      throw node.error("cameras", "cameras '" + first_alternating->name + "' and '" + cam.name +
                                      "' alternate with different slots or frame_rate_hz");
    }
    if (!slots_taken.insert(cam.alternate.slot).second) {
      throw node.error("cameras", "camera '" + cam.name + "' alternates in slot " +
                                      std::to_string(cam.alternate.slot) +
                                      ", which another camera has");
    }
  }
  node.requireAllKeysUsed();
  return robot;
}

RobotConfig RobotConfig::loadFile(const std::filesystem::path& file) {
  return load(ConfigNode::loadFile(file));
}

double opticalAxisHeading(const Eigen::Matrix3d& robot_R_camera) {
  return std::atan2(robot_R_camera(1, 2), robot_R_camera(0, 2));
}

const CameraConfig& RobotConfig::camera(const std::string& camera_name) const {
  for (const auto& c : cameras) {
    if (c.name == camera_name) return c;
  }
  throw std::out_of_range("no camera named '" + camera_name + "' in robot '" + name + "'");
}

void RobotConfig::print(std::ostream& os) const {
  os << "robot " << name << " (" << file.string() << ")\n";
  for (const auto& c : cameras) {
    const Eigen::Vector3d t = c.robot_T_camera.translation();
    os << "  camera " << c.name << ": " << c.width << "x" << c.height << " @ " << c.frame_rate_hz
       << " Hz, fx=" << c.fx << " fy=" << c.fy << " cx=" << c.cx << " cy=" << c.cy << ", position ["
       << t.x() << ", " << t.y() << ", " << t.z() << "] m, channels " << c.image_channel << " "
       << c.calibration_channel;
    if (c.alternate.active()) {
      os << ", alternating: slot " << c.alternate.slot << " of " << c.alternate.slots;
    }
    os << "\n";
  }
}

}  // namespace vslam::config
