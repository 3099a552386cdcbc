#pragma once
// The landmark database's domain types (no LCM, no SQLite): what the DB knows
// of every landmark (LandmarkInfo: ids, creation, statistics, position; small,
// always in memory) and its structure (LandmarkStructure: 3-D points, the
// reference view's features and descriptors; large, in memory only while the
// landmark's region is near the robot).

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "odometry/pose2.hpp"
#include "util/time.hpp"

namespace vslam::landmark_db {

// The most points a landmark may have. The front-end keeps 20-300 (the most
// in the apartment and generated homes: 288); a proposal claiming more is
// refused by the DB and by the front-ends that would copy it into their
// replicas, so one hostile message cannot grow every process by megabytes.
inline constexpr int32_t kMaxLandmarkPoints = 2048;

// Where a landmark's position for segmentation and duplicate detection comes from.
enum class PoseSource : int {
  kOdometry = 0,     // only the creation pose in the creating run's odometry frame
  kProvisional = 1,  // creation odometry pose moved into the map frame by the pose estimate
  kMap = 2,          // the back-end's estimate (MAP)
};

struct LandmarkStats {
  int32_t num_recognitions = 0;  // measurements made (VISUAL_MEASUREMENT)
  int32_t num_accepted = 0;      // pre-filter verdicts (VISUAL_MEASUREMENT_FILTERED)
  int32_t num_rejected = 0;
  Utime last_seen_utime = 0;  // 0: never recognized
};

struct LandmarkInfo {
  int64_t id = -1;          // global id, > 0
  std::string camera;       // camera that created it
  int64_t proposal_id = 0;  // the creating front-end's id for it
  uint64_t fingerprint =
      0;                    // hash of the descriptors: (camera, proposal_id, fingerprint) is unique
  int32_t version = 0;      // +1 per change
  int64_t revision = 0;     // database revision of its last change
  Utime created_utime = 0;  // robot clock
  Pose2 created_odom;       // robot pose at creation, odometry frame of the creating run
  int32_t num_points = 0;
  LandmarkStats stats;
  PoseSource pose_source = PoseSource::kOdometry;
  Pose2 map_pose;  // valid unless pose_source == kOdometry

  // The best known position: the map pose, or the creation odometry pose.
  const Pose2& position() const {
    return pose_source == PoseSource::kOdometry ? created_odom : map_pose;
  }
};

struct LandmarkStructure {
  int32_t num_points = 0;
  int32_t descriptor_size = 128;
  std::vector<float> points;         // 3 per point, robot frame at creation, metres
  std::vector<float> keypoints;      // 2 per point, normalized image coordinates
  std::vector<float> scales;         // 1 per point, pixels
  std::vector<float> orientations;   // 1 per point, radians
  std::vector<uint8_t> descriptors;  // descriptor_size per point

  // Empty string if consistent, else what is wrong (sizes, non-finite values).
  std::string validate() const;
  // FNV-1a of the descriptors: tells two proposals with the same id apart.
  uint64_t fingerprint() const;
  size_t bytes() const {
    return sizeof(*this) +
           4 * (points.size() + keypoints.size() + scales.size() + orientations.size()) +
           descriptors.size();
  }
};
using StructurePtr = std::shared_ptr<const LandmarkStructure>;

// Memory a landmark costs where it is held for recognition (a front-end's
// replica: float descriptors, points and the index; the dominant cost, so the
// memory budget is counted in it): bytes per point and per landmark.
inline constexpr size_t kReplicaBytesPerPoint = 128 * 4 + 3 * 8 + 64;
inline constexpr size_t kReplicaBytesPerLandmark = 512;
inline size_t replicaBytes(int32_t num_points) {
  return kReplicaBytesPerLandmark + kReplicaBytesPerPoint * static_cast<size_t>(num_points);
}

}  // namespace vslam::landmark_db
