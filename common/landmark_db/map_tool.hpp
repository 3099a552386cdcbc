#pragma once
// The landmark DB's configuration block and the vslam-map command line (no LCM).
//
//   vslam-map info FILE                  counts, ids, size, regions, revision
//   vslam-map list FILE                  one CSV line per landmark (statistics, poses)
//   vslam-map regions FILE               the segmentation's regions
//   vslam-map check FILE                 SQLite integrity check (exit 1 if damaged)
//   vslam-map prune FILE [--dry-run]     remove landmarks by the configured policy
//   vslam-map plot FILE --out DIR        landmarks.png (paper Fig. 6),
//                                        measurements_histogram.png (Fig. 10)
// Options: --config FILE (default config/vslam.yaml) --instance NAME (default
// landmark_db) give the prune policy and region size; --now-utime T judges
// ages at T (default: the newest time in the file).
// Exit codes: 0 ok, 1 damaged or failing file, 2 usage or configuration error.

#include <filesystem>
#include <string>
#include <vector>

#include "config/config_node.hpp"
#include "config/robot_config.hpp"
#include "landmark_db/landmark_database.hpp"

namespace vslam::landmark_db {

// The processes.<instance> keys the database itself reads (prune,
// segmentation, allow_new_landmarks), with the robot's camera headings.
DatabaseParams loadDatabaseParams(const config::ConfigNode& node, const config::RobotConfig& robot);

int runMapTool(const std::vector<std::string>& args);

}  // namespace vslam::landmark_db
