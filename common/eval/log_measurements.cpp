#include "eval/log_measurements.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <vslam/camera_calibration_t.hpp>
#include <vslam/ground_truth_pose_t.hpp>
#include <vslam/landmark_update_t.hpp>
#include <vslam/visual_measurement_t.hpp>

#include "config/robot_config.hpp"
#include "eval/errors.hpp"
#include "eval/log_events.hpp"
#include "util/log.hpp"

namespace vslam::eval {

// A message's status is cast to the verdict; the codes must stay equal.
static_assert(static_cast<int>(MeasurementVerdict::kAccepted) ==
                  vslam::visual_measurement_t::STATUS_ACCEPTED &&
              static_cast<int>(MeasurementVerdict::kRejectedInvalid) ==
                  vslam::visual_measurement_t::STATUS_REJECTED_INVALID);

MeasurementLog readMeasurementLog(const std::filesystem::path& log,
                                  const MeasurementLogOptions& options) {
  MeasurementLog out;
  const auto& landmark_channels = options.landmark_channels;
  const auto counts = forEachLogEvent(log, [&](const LogEventRef& ref) {
    const std::string& channel = ref.event.channel;
    if (channel == options.ref_channel) {
      const auto m = decodeEvent<vslam::ground_truth_pose_t>(ref, "vslam.ground_truth_pose_t");
      out.reference.poses.push_back(planarPose(m.utime * 1e-6, m.x, m.y, m.z, m.theta));
    } else if (channel == options.measurement_channel) {
      const auto m = decodeEvent<vslam::visual_measurement_t>(ref, "vslam.visual_measurement_t");
      MeasurementSample s;
      s.t = m.utime * 1e-6;
      s.camera = m.camera;
      s.landmark_id = m.landmark_id;
      s.dx = m.dx;
      s.dy = m.dy;
      s.dtheta = m.dtheta;
      s.proj_err_rms = m.proj_err_rms;
      s.num_points = m.num_points;
      s.slope = m.slope;
      if (m.status == vslam::visual_measurement_t::STATUS_UNFILTERED || options.rejudge) {
        frontend::PoseMeasurement pm;
        pm.relative = {m.dx, m.dy, m.dtheta};
        pm.proj_err_rms_px = m.proj_err_rms;
        pm.num_points = m.num_points;
        pm.slope = m.slope;
        s.verdict = frontend::prefilter(pm, options.prefilter);
      } else if (m.status >= vslam::visual_measurement_t::STATUS_ACCEPTED &&
                 m.status <= vslam::visual_measurement_t::STATUS_REJECTED_INVALID) {
        s.verdict = static_cast<MeasurementVerdict>(m.status);
      } else {
        s.verdict = MeasurementVerdict::kRejectedInvalid;
      }
      out.samples.push_back(std::move(s));
    } else if (std::find(landmark_channels.begin(), landmark_channels.end(), channel) !=
               landmark_channels.end()) {
      const auto u = decodeEvent<vslam::landmark_update_t>(ref, "vslam.landmark_update_t");
      if (u.op == vslam::landmark_update_t::OP_REMOVED || u.landmark.landmark_id < 0) return;
      // The first record of a landmark wins: its creation never changes.
      out.creations.emplace(
          u.landmark.landmark_id,
          LandmarkCreationTime{u.landmark.created_utime * 1e-6, u.landmark.camera});
    } else if (isEventOf<vslam::camera_calibration_t>(ref)) {
      // Only for the view changes: a damaged one is named and skipped.
      try {
        const auto c = decodeEvent<vslam::camera_calibration_t>(ref, "vslam.camera_calibration_t");
        const Eigen::Quaterniond q(c.robot_q_camera[0], c.robot_q_camera[1], c.robot_q_camera[2],
                                   c.robot_q_camera[3]);
        const Eigen::Matrix3d robot_R_camera = q.normalized().toRotationMatrix();
        // A camera looking straight up or down has no heading.
        if (robot_R_camera.allFinite() &&
            std::hypot(robot_R_camera(0, 2), robot_R_camera(1, 2)) > 1e-6)
          out.camera_heading_rad[c.camera] = config::opticalAxisHeading(robot_R_camera);
      } catch (const DataError& err) {
        log::warn(err.what(), ": skipped");
      }
    }
  });
  const std::string name = log.string();
  if (out.reference.empty()) {
    throw DataError(name + ": no ground truth on " + options.ref_channel +
                    " (choose it with --ref-channel); channels in the log: " + channelList(counts));
  }
  if (!counts.count(options.measurement_channel)) {
    throw DataError(
        name + ": no visual measurements on " + options.measurement_channel +
        " (choose it with --measurement-channel); channels in the log: " + channelList(counts));
  }
  return out;
}

}  // namespace vslam::eval
