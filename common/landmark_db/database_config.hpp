#pragma once
// The landmark database's configuration block (no LCM): read by the
// landmark DB stage and by vslam-map.

#include "config/config_node.hpp"
#include "config/param_table.hpp"
#include "config/robot_config.hpp"
#include "landmark_db/landmark_database.hpp"

namespace vslam::landmark_db {

// The processes.<instance> keys the database itself reads (prune,
// segmentation, allow_new_landmarks), declared once (config/param_table.hpp).
const config::ParamTable<DatabaseParams>& databaseParamTable();

// The heading of each of the robot's cameras, for the duplicate test.
void setCameraHeadings(const config::RobotConfig& robot, DatabaseParams& p);

// Those keys, with the robot's camera headings.
DatabaseParams loadDatabaseParams(const config::ConfigNode& node, const config::RobotConfig& robot);

}  // namespace vslam::landmark_db
