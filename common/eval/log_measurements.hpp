#pragma once
// Reads what `vslam-eval --measurements` scores from an LCM log: the visual
// measurements (vslam.visual_measurement_t), the landmarks' creation times
// (vslam.landmark_update_t on the proposal and update channels), ground
// truth (vslam.ground_truth_pose_t) and the cameras' mounting
// (vslam.camera_calibration_t).

#include <filesystem>
#include <string>
#include <vector>

#include "eval/measurement_eval.hpp"
#include "frontend/pose_measurement.hpp"

namespace vslam::eval {

struct MeasurementLogOptions {
  std::string ref_channel = "GROUND_TRUTH";
  std::string measurement_channel = "VISUAL_MEASUREMENT";
  // Channels of vslam.landmark_update_t whose landmarks give creation times.
  std::vector<std::string> landmark_channels = {"LANDMARK_PROPOSAL", "LANDMARK_UPDATE"};
  // The acceptance region applied to measurements that carry no verdict
  // (STATUS_UNFILTERED, as the front-ends publish them). A measurement that
  // a pre-filter already judged (e.g. VISUAL_MEASUREMENT_FILTERED) keeps its
  // verdict unless rejudge is set.
  frontend::PrefilterParams prefilter;
  bool rejudge = false;
};

struct MeasurementLog {
  Trajectory reference;
  std::vector<MeasurementSample> samples;
  std::map<int64_t, LandmarkCreationTime> creations;
  // Each camera's optical axis heading on the robot, from its
  // vslam.camera_calibration_t (any channel; the newest wins).
  std::map<std::string, double> camera_heading_rad;
};

// Throws DataError for an unreadable or damaged log, or when the reference or
// measurement channel is missing.
MeasurementLog readMeasurementLog(const std::filesystem::path& log,
                                  const MeasurementLogOptions& options);

}  // namespace vslam::eval
