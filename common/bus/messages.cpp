#include "bus/messages.hpp"

#include <unistd.h>

#include <Eigen/Geometry>

#include "util/process.hpp"

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

vslam::health_t healthMessage(const std::string& process, const std::string& instance, Utime utime,
                              Utime started_monotonic, const HealthReport& report) {
  vslam::health_t msg{};
  msg.utime = utime;
  msg.process = process;
  msg.instance = instance;
  msg.host = hostName();
  msg.pid = static_cast<int32_t>(getpid());
  msg.uptime = toSeconds(monotonicUtime() - started_monotonic);
  msg.level = static_cast<int8_t>(report.level);
  msg.message = report.message;
  const ResourceUsage usage = currentResourceUsage();
  msg.cpu_seconds = usage.cpu_seconds;
  msg.rss_bytes = usage.rss_bytes;
  for (const auto& m : report.metrics) {
    vslam::health_metric_t hm;
    hm.name = m.name;
    hm.value = m.value;
    hm.unit = m.unit;
    msg.metrics.push_back(hm);
  }
  msg.num_metrics = static_cast<int32_t>(msg.metrics.size());
  return msg;
}

}  // namespace vslam::bus
