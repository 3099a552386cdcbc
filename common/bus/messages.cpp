#include "bus/messages.hpp"

#include <Eigen/Geometry>

namespace vslam::bus {

vslam::camera_calibration_t calibrationMessage(const config::CameraConfig& c, Utime utime) {
  vslam::camera_calibration_t m{};
  m.utime = utime;
  m.camera = c.name;
  m.image_channel = c.image_channel;
  m.width = c.width;
  m.height = c.height;
  m.frame_rate = c.frame_rate_hz;
  m.fx = c.fx;
  m.fy = c.fy;
  m.cx = c.cx;
  m.cy = c.cy;
  m.distortion = c.distortion;
  m.num_distortion = static_cast<int8_t>(c.distortion.size());
  const Eigen::Vector3d t = c.robot_T_camera.translation();
  const Eigen::Quaterniond q(c.robot_T_camera.linear());
  for (int i = 0; i < 3; ++i) m.robot_t_camera[i] = t[i];
  m.robot_q_camera[0] = q.w();
  m.robot_q_camera[1] = q.x();
  m.robot_q_camera[2] = q.y();
  m.robot_q_camera[3] = q.z();
  return m;
}

}  // namespace vslam::bus
