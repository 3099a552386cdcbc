#pragma once
// The vslam-map command line (no LCM).
//
//   vslam-map info FILE                  counts, ids, size, regions, revision
//   vslam-map list FILE                  one CSV line per landmark (statistics, poses)
//   vslam-map regions FILE               the segmentation's regions
//   vslam-map check FILE                 SQLite integrity check (exit 1 if damaged)
//   vslam-map prune FILE [--dry-run]     remove landmarks by the configured policy
//   vslam-map plot FILE --out DIR        landmarks.png (paper Fig. 6),
//                                        measurements_histogram.png (Fig. 10)
// Options (a value follows its option, or --key=value): --config FILE
// (default $VSLAM_CONFIG, else config/vslam.yaml) --instance NAME (default
// landmark_db) give the prune policy and region size; --now-utime T judges
// ages at T (default: the newest time in the file).
// Exit codes: 0 ok, 1 damaged or failing file, 2 usage or configuration error.

#include <filesystem>
#include <string>
#include <vector>

#include "landmark_db/database_config.hpp"

namespace vslam::landmark_db {

int runMapTool(const std::vector<std::string>& args);

}  // namespace vslam::landmark_db
