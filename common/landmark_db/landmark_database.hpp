#pragma once
// The landmark database manager of the vSLAM paper (section 8), without LCM:
// one owner of the landmarks of a robot. It assigns stable global ids to the
// front-ends' proposals, stores them durably (LandmarkStore), keeps usage
// statistics from measurements and pre-filter verdicts, prunes poor and
// duplicate landmarks by policy, and segments the map: landmarks are grouped
// into square regions by position, and only the regions nearest the robot
// are held in memory, within a memory budget (the "active set", which every
// front-end's recognition replica mirrors). Every change it makes is a
// Change with a new database revision, for the stage to publish.
//
//   LandmarkDatabase db(std::make_unique<LandmarkStore>(file, opts), params);
//   auto r = db.propose(info, structure, now);   // r.id: the global id
//   db.recordMeasurement(id, utime); db.recordVerdict(id, accepted, utime);
//   db.setRobotPose(pose); auto changes = db.updateActiveSet();
//   auto pruned = db.prune(now);  auto updated = db.flush();

#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "landmark_db/landmark_record.hpp"
#include "landmark_db/landmark_store.hpp"

namespace vslam::landmark_db {

struct PrunePolicy {
  bool enabled = true;              // the landmark DB stage runs a pass...
  double period_s = 30;             // ...every this many seconds of robot time
  double min_age_s = 120;           // only landmarks at least this old (robot time) are judged
  int min_recognitions = 3;         // fewer measurements by then: rarely recognized, pruned
  int min_verdicts = 10;            // with at least this many pre-filter verdicts...
  double min_accepted_ratio = 0.3;  // ...fewer accepted than this fraction: poor, pruned
  // Duplicates: two landmarks whose positions are this close and whose
  // cameras looked the same way, sharing this fraction of the smaller one's
  // descriptors (ratio-test matches): the one with fewer accepted
  // measurements (then the newer) is pruned.
  double duplicate_distance_m = 0.3;
  double duplicate_angle_deg = 20;
  double duplicate_min_shared = 0.3;
  double duplicate_match_ratio = 0.8;
};

struct SegmentationParams {
  double region_size_m = 4.0;          // square regions of the map plane
  double active_radius_m = 8.0;        // regions whose centre is this near the robot are wanted
  double memory_budget_mb = 64;        // replica bytes (replicaBytes) of the active set, at most
  double reevaluate_distance_m = 1.0;  // robot travel that triggers a new active set
};

struct DatabaseParams {
  bool allow_new_landmarks = true;  // false: a known map used for localization only
  PrunePolicy prune;
  SegmentationParams segmentation;
  // Heading of each camera in the robot frame (radians), for duplicates:
  // landmarks of the same place are seen in the same direction.
  std::map<std::string, double> camera_yaw;
};

enum class ChangeOp { kCreated, kUpdated, kRemoved, kEvicted, kLoaded };
const char* toString(ChangeOp op);

struct Change {
  ChangeOp op;
  int64_t id;
  int64_t revision;
  bool stats_only = false;  // kUpdated: the structure is unchanged
  const char* reason = "";  // kRemoved: the pruning rule
};

enum class ProposalOutcome { kCreated, kAlreadyKnown, kRefused, kInvalid };

struct ProposalResult {
  ProposalOutcome outcome = ProposalOutcome::kInvalid;
  int64_t id = -1;              // kCreated, kAlreadyKnown
  std::string reason;           // kRefused, kInvalid
  std::vector<Change> changes;  // kCreated: the creation, then any evictions
};

struct RegionKey {
  int64_t ix = 0, iy = 0;
  bool operator<(const RegionKey& o) const { return ix != o.ix ? ix < o.ix : iy < o.iy; }
  bool operator==(const RegionKey& o) const { return ix == o.ix && iy == o.iy; }
};

struct RegionSummary {
  RegionKey key;
  double centre_x = 0, centre_y = 0;
  int landmarks = 0;
  size_t replica_bytes = 0;
  bool active = false;
};

class LandmarkDatabase {
 public:
  LandmarkDatabase(std::unique_ptr<LandmarkStore> store, DatabaseParams params);

  const LandmarkStore& store() const { return *store_; }
  LandmarkStore& store() { return *store_; }
  const DatabaseParams& params() const { return params_; }
  const std::string& databaseId() const { return store_->databaseId(); }
  int64_t revision() const { return revision_; }

  // A front-end's new landmark: durably stored before this returns. The same
  // (camera, proposal_id) again gives kAlreadyKnown with the first id.
  // `map_T_odom`, if known, places it in the map frame until MAP does.
  ProposalResult propose(LandmarkInfo info, LandmarkStructure structure,
                         const std::optional<Pose2>& map_T_odom = std::nullopt);

  // A landmark's 3-D points refined by the front-end that proposed it (the
  // same camera and proposal_id and as many points; nothing else changes),
  // durably stored before this returns; refused in a map opened for
  // localization only. Empty `reason` and a kUpdated change
  // (with the structure) on success; otherwise why not, and nothing changed.
  struct RevisionResult {
    std::string reason;
    std::vector<Change> changes;
  };
  RevisionResult revise(int64_t id, const std::string& camera, int64_t proposal_id,
                        std::vector<float> points);

  // Statistics; false for an unknown id. Written by flush().
  bool recordMeasurement(int64_t id, Utime utime);
  bool recordVerdict(int64_t id, bool accepted, Utime utime);
  // Positions from the back-end's map; returns how many ids were known.
  int setMapPoses(const std::vector<std::pair<int64_t, Pose2>>& poses);
  // The localizer's newest estimate (and whether it believed the robot
  // kidnapped then): kept as the map file's robot pose, what a restarted
  // back-end resumes from. A kidnapped estimate clears it: the robot is
  // somewhere the estimate does not say. Written by flush().
  void noteRobotEstimate(const RobotPoseRecord& estimate, bool kidnapped);
  // Writes changed statistics and positions in one transaction; one stats-only
  // kUpdated per landmark whose statistics changed. Then the robot pose, if
  // a newer estimate came.
  std::vector<Change> flush();

  // Removes landmarks by the pruning policy (judged at robot time `now`);
  // flushes first. `dry_run`: only lists them (ids in Change, revision 0).
  std::vector<Change> prune(Utime now, bool dry_run = false);

  // Segmentation.
  void setRobotPose(const Pose2& map_pose);
  std::optional<Pose2> robotPose() const { return robot_; }
  // Recomputes the active set if the robot moved reevaluate_distance_m since
  // the last time, or `force`, or the budget is exceeded: evicts and loads.
  std::vector<Change> updateActiveSet(bool force = false) { return updateActive(force, true); }
  RegionKey regionOf(const Pose2& p) const;
  std::vector<RegionSummary> regions() const;

  // Landmarks.
  size_t numStored() const { return infos_.size(); }
  size_t numActive() const { return active_.size(); }
  const LandmarkInfo* info(int64_t id) const;
  const std::map<int64_t, LandmarkInfo>& infos() const { return infos_; }
  bool isActive(int64_t id) const { return active_.count(id) > 0; }
  // The structure of an active landmark (nullptr if not active).
  StructurePtr structure(int64_t id) const;
  // Active ids ascending, and those whose last change or load is after `revision`.
  std::vector<int64_t> activeIds() const;
  std::vector<int64_t> activeChangedSince(int64_t revision) const;
  // Replica bytes of the active set, and what this process holds.
  size_t activeReplicaBytes() const { return active_replica_bytes_; }
  size_t heldBytes() const;
  size_t budgetBytes() const;

 private:
  // publish = false (opening): landmarks enter the set without a change.
  std::vector<Change> updateActive(bool force, bool publish);
  void activate(int64_t id, StructurePtr st, int64_t revision);
  void deactivate(int64_t id);
  bool duplicates(const LandmarkInfo& a, const LandmarkInfo& b) const;

  std::unique_ptr<LandmarkStore> store_;
  DatabaseParams params_;
  int64_t revision_ = 0;
  std::map<int64_t, LandmarkInfo> infos_;
  struct Active {
    StructurePtr structure;
    int64_t revision = 0;  // last change or load
  };
  std::map<int64_t, Active> active_;
  size_t active_replica_bytes_ = 0;
  std::set<int64_t> dirty_;       // statistics changed: new version, published
  std::set<int64_t> pose_dirty_;  // only the map position changed: written, not published
  std::optional<Pose2> robot_;
  std::optional<RobotPoseRecord> robot_estimate_;  // noteRobotEstimate's newest
  bool robot_estimate_dirty_ = false;
  std::optional<Pose2> evaluated_at_;
};

// Shared descriptors between two landmarks: the fraction of the smaller one's
// descriptors with a ratio-test match in the other (brute force, L2).
double sharedDescriptorFraction(const LandmarkStructure& a, const LandmarkStructure& b,
                                double ratio);

}  // namespace vslam::landmark_db
