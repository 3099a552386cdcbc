#include "landmark_db/database_config.hpp"

#include <cmath>

namespace vslam::landmark_db {

DatabaseParams loadDatabaseParams(const config::ConfigNode& node,
                                  const config::RobotConfig& robot) {
  using config::InRange;
  DatabaseParams p;
  p.allow_new_landmarks = node.getBool("allow_new_landmarks");
  const config::ConfigNode pr = node.child("prune");
  p.prune.min_age_s = pr.getDouble("min_age_s", InRange{0, 1e9});
  p.prune.min_recognitions = static_cast<int>(pr.getInt("min_recognitions", InRange{0, 1e6}));
  p.prune.min_verdicts = static_cast<int>(pr.getInt("min_verdicts", InRange{1, 1e6}));
  p.prune.min_accepted_ratio = pr.getDouble("min_accepted_ratio", InRange{0, 1});
  p.prune.duplicate_distance_m = pr.getDouble("duplicate_distance_m", InRange{0, 100});
  p.prune.duplicate_angle_deg = pr.getDouble("duplicate_angle_deg", InRange{0, 180});
  p.prune.duplicate_min_shared = pr.getDouble("duplicate_min_shared", InRange{0, 1});
  p.prune.duplicate_match_ratio = pr.getDouble("duplicate_match_ratio", 0.8, InRange{0.1, 1});
  const config::ConfigNode seg = node.child("segmentation");
  p.segmentation.region_size_m = seg.getDouble("region_size_m", InRange{0.1, 1e4});
  p.segmentation.active_radius_m = seg.getDouble("active_radius_m", InRange{0, 1e6});
  p.segmentation.memory_budget_mb = seg.getDouble("memory_budget_mb", InRange{0.01, 1e6});
  p.segmentation.reevaluate_distance_m = seg.getDouble("reevaluate_distance_m", InRange{0.01, 1e4});
  for (const auto& c : robot.cameras) {
    const Eigen::Vector3d axis = c.robot_T_camera.linear().col(2);
    p.camera_yaw[c.name] = std::atan2(axis.y(), axis.x());
  }
  return p;
}

}  // namespace vslam::landmark_db
