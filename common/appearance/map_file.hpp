#pragma once
// The appearance map on disk: one SQLite file (docs/appearance.md, "Map
// file"), so that a later run starts in a known map. Written to FILE.tmp and
// renamed over FILE, so a crash never leaves half a map.
//
// Tables:
//   meta(key TEXT PRIMARY KEY, value TEXT)
//     format = "vslam-appearance-map", version = "1", bins = k,
//     cameras = camera names joined by ","
//   states(state_id INTEGER PRIMARY KEY, utime INTEGER, odom_x REAL,
//          odom_y REAL, odom_theta REAL)
//   histograms(state_id INTEGER, camera INTEGER, bins BLOB,
//              PRIMARY KEY (state_id, camera))
//     bins: k float32 in little-endian order, normalised to sum 1; an
//     empty blob marks a camera that gave no image for that snapshot
//   path(seq INTEGER PRIMARY KEY, state_id INTEGER, known INTEGER,
//        dx REAL, dy REAL, dtheta REAL, relative_translation REAL,
//        relative_rotation REAL, odometry_translation REAL,
//        odometry_rotation REAL, covariance BLOB)
//     the visits of the saved path in time order; row seq describes the
//     link from visit seq-1 (known = 0: no link, the first visit or a
//     restart), covariance = 9 float64 little-endian, row-major (dx, dy, dtheta)

#include <filesystem>
#include <stdexcept>

#include "appearance/path_hypotheses.hpp"

namespace vslam::appearance {

class MapFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

void saveMap(const std::filesystem::path& file, const SavedMap& map);
// Throws MapFileError naming the file and what is wrong.
SavedMap loadMap(const std::filesystem::path& file);

}  // namespace vslam::appearance
