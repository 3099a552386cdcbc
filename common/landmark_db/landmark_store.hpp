#pragma once
// The landmark map file: one SQLite database in WAL mode (docs/landmark-db.md,
// "Map file"). Every write is one transaction with synchronous=FULL, so a
// landmark whose insert returned survives kill -9 (and power loss). A file
// that is not a landmark map (another application's database, not SQLite at
// all, a newer schema, a damaged file) is refused with MapFileError before
// anything is written to it.
//
//   PRAGMA application_id = 0x764C4D44 ('vLMD'), PRAGMA user_version = 1
//   meta(key TEXT PRIMARY KEY, value TEXT)
//     format = "vslam-landmark-map", schema = "1", database_id, revision,
//     next_id, created_utime; robot_pose (optional, RobotPoseRecord: where the
//     robot last was, "utime x y theta odom_x odom_y odom_theta" and the 9
//     covariance entries, space-separated)
//   landmarks(landmark_id INTEGER PRIMARY KEY, camera, proposal_id, version,
//     revision, created_utime, odom_x, odom_y, odom_theta, num_points,
//     descriptor_size, points BLOB, keypoints BLOB, scales BLOB,
//     orientations BLOB, descriptors BLOB, num_recognitions, num_accepted,
//     num_rejected, last_seen_utime, pose_source, map_x, map_y, map_theta,
//     fingerprint, UNIQUE(camera, proposal_id, fingerprint))
//   Blobs are little-endian float32 (points 3 per point, keypoints 2, scales
//   and orientations 1) and uint8 descriptors (descriptor_size per point).
//
// ":memory:" (or an empty path) is a private in-memory database: nothing persists.

#include <array>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "landmark_db/landmark_record.hpp"

namespace vslam::sqlite {
template <class Error>
class Database;
}  // namespace vslam::sqlite

namespace vslam::landmark_db {

class MapFileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

inline constexpr int32_t kApplicationId = 0x764C4D44;
inline constexpr int kSchemaVersion = 1;

struct StoreOptions {
  bool create_if_missing = true;
  bool read_only = false;  // vslam-map inspect/plot: never writes
  // A new file's database_id (the caller makes it unique; replay makes it
  // deterministic).
  std::string new_database_id;
  Utime now = 0;            // a new file's created_utime
  bool quick_check = true;  // PRAGMA quick_check on open
  // synchronous=FULL: a commit survives power loss. NORMAL (false) still
  // survives kill -9 of the process (WAL), and is faster.
  bool power_safe = true;
  // The map file stops growing at this size (0: no limit): a write beyond it
  // fails as on a full disk (SQLite's max_page_count).
  uint64_t max_file_bytes = 0;
};

// Where the robot last was in this map, as its localizer estimated it: what a
// restarted back-end resumes from (docs/landmark-db.md, "Map file").
struct RobotPoseRecord {
  Utime utime = 0;                     // the estimate's robot time
  Pose2 map_pose;                      // the estimate, map frame
  Pose2 odom_pose;                     // the odometry reading it was made at, odometry frame
  std::array<double, 9> covariance{};  // of map_pose, row-major (m^2, m rad, rad^2)
};

class LandmarkStore {
 public:
  // Throws MapFileError naming the file and what is wrong.
  LandmarkStore(const std::filesystem::path& file, const StoreOptions& options);
  ~LandmarkStore();
  LandmarkStore(const LandmarkStore&) = delete;
  LandmarkStore& operator=(const LandmarkStore&) = delete;

  const std::string& file() const { return file_; }
  bool inMemory() const { return in_memory_; }
  const std::string& databaseId() const { return database_id_; }
  int64_t revision() const { return revision_; }
  int64_t nextId() const { return next_id_; }
  Utime createdUtime() const { return created_utime_; }

  std::vector<LandmarkInfo> loadAllInfo();
  // The structure of a stored landmark; nullopt if there is no such landmark.
  std::optional<LandmarkStructure> loadStructure(int64_t id);
  // The landmark stored from this proposal (same camera, id and descriptors).
  std::optional<int64_t> findProposal(const std::string& camera, int64_t proposal_id,
                                      uint64_t fingerprint);

  // One durable transaction each; `revision` becomes the stored revision.
  // insert assigns info.id = nextId() if info.id <= 0 and returns the id.
  int64_t insert(LandmarkInfo info, const LandmarkStructure& structure, int64_t revision);
  void updateInfos(const std::vector<LandmarkInfo>& infos, int64_t revision);
  // A landmark's 3-D points replaced (a refinement), with its new version.
  void updatePoints(int64_t id, const std::vector<float>& points, int32_t version,
                    int64_t revision);
  void remove(const std::vector<int64_t>& ids, int64_t revision);
  void setRevision(int64_t revision);
  // The robot's last pose: one durable write, no new revision (no landmark
  // changes). nullopt clears it.
  void saveRobotPose(const std::optional<RobotPoseRecord>& pose);
  // As read when the file was opened, or last saved; nullopt if none (or
  // unreadable: a damaged value is not worth refusing the map for).
  const std::optional<RobotPoseRecord>& robotPose() const { return robot_pose_; }

  // "ok", or SQLite's list of problems.
  std::string integrityCheck();
  int64_t fileBytes() const;  // main file + WAL; 0 in memory
  // Mean milliseconds of the commits since the last call (0 if none), and their number.
  double takeMeanCommitMs(int64_t* count = nullptr);

 private:
  void checkIdentity();
  void createSchema(const StoreOptions& options);
  void readMeta();
  void writeMetaValue(const char* key, const std::string& value);
  // Runs body and sets the map's revision in one transaction, rolled back
  // if anything throws; counts its time for takeMeanCommitMs.
  void writeTransaction(int64_t revision, const std::function<void()>& body);

  std::string file_;
  bool in_memory_ = false;
  bool read_only_ = false;
  std::unique_ptr<sqlite::Database<MapFileError>> db_;
  std::string database_id_;
  int64_t revision_ = 0;
  int64_t next_id_ = 1;
  Utime created_utime_ = 0;
  std::optional<RobotPoseRecord> robot_pose_;
  double commit_ms_sum_ = 0;
  int64_t commit_count_ = 0;
};

}  // namespace vslam::landmark_db
