#include "landmark_db/database_config.hpp"

#include <cmath>

namespace vslam::landmark_db {

const config::ParamTable<DatabaseParams>& databaseParamTable() {
  using config::InRange;
  using config::ParamTable;
  static const ParamTable<DatabaseParams> declared = [] {
    using P = PrunePolicy;
    ParamTable<P> prune;
    prune.add("enabled", &P::enabled, "pruning passes")
        .required()
        .add("period_s", &P::period_s, InRange{1, 1e6}, "s", "robot time between them")
        .required()
        .add("min_age_s", &P::min_age_s, InRange{0, 1e9}, "s", "younger landmarks are not judged")
        .required()
        .add("min_recognitions", &P::min_recognitions, InRange{0, 1e6}, "",
             "fewer measurements by then: pruned as rarely recognized")
        .required()
        .add("min_verdicts", &P::min_verdicts, InRange{1, 1e6}, "",
             "with this many pre-filter verdicts...")
        .required()
        .add("min_accepted_ratio", &P::min_accepted_ratio, InRange{0, 1}, "",
             "...fewer accepted than this fraction: pruned as poor")
        .required()
        .add("duplicate_distance_m", &P::duplicate_distance_m, InRange{0, 100}, "m",
             "two landmarks this close...")
        .required()
        .add("duplicate_angle_deg", &P::duplicate_angle_deg, InRange{0, 180}, "deg",
             "...seen in the same direction within this (camera yaw included)...")
        .required()
        .add("duplicate_min_shared", &P::duplicate_min_shared, InRange{0, 1}, "",
             "...sharing this fraction of the smaller one's descriptors: the less used one is "
             "pruned")
        .required()
        .add("duplicate_match_ratio", &P::duplicate_match_ratio, InRange{0.1, 1}, "",
             "Lowe's ratio test of that descriptor matching");
    using G = SegmentationParams;
    ParamTable<G> segmentation;
    segmentation
        .add("region_size_m", &G::region_size_m, InRange{0.1, 1e4}, "m",
             "square regions of the map plane")
        .required()
        .add("active_radius_m", &G::active_radius_m, InRange{0, 1e6}, "m",
             "regions whose centre is this near the robot are held in memory...")
        .required()
        .add("memory_budget_mb", &G::memory_budget_mb, InRange{0.01, 1e6}, "MiB",
             "...within this budget, counted as a front-end replica's bytes")
        .required()
        .add("reevaluate_distance_m", &G::reevaluate_distance_m, InRange{0.01, 1e4}, "m",
             "robot travel between re-evaluations of the in-memory set")
        .required();
    ParamTable<DatabaseParams> t;
    t.add("allow_new_landmarks", &DatabaseParams::allow_new_landmarks,
          "`false`: localization in a known map; proposals are refused (OP_REJECTED)")
        .required()
        .block("prune", &DatabaseParams::prune, prune)
        .required()
        .block("segmentation", &DatabaseParams::segmentation, segmentation)
        .required();
    return t;
  }();
  return declared;
}

void setCameraHeadings(const config::RobotConfig& robot, DatabaseParams& p) {
  for (const auto& c : robot.cameras)
    p.camera_yaw[c.name] = config::opticalAxisHeading(c.robot_T_camera.linear());
}

DatabaseParams loadDatabaseParams(const config::ConfigNode& node,
                                  const config::RobotConfig& robot) {
  DatabaseParams p;
  databaseParamTable().load(node, p);
  setCameraHeadings(robot, p);
  return p;
}

}  // namespace vslam::landmark_db
