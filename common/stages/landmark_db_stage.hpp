#pragma once
// vslam-landmark-db: the one owner of a robot's landmarks (vSLAM paper
// section 8; docs/landmark-db.md), over the library of common/landmark_db.
//
//   LANDMARK_PROPOSAL (OP_PROPOSED)  -> stored durably, global id assigned ->
//   LANDMARK_UPDATE OP_CREATED (with the proposer's camera and proposal_id),
//     or OP_REJECTED (map for localization only, invalid proposal);
//   VISUAL_MEASUREMENT / _FILTERED   -> statistics (recognitions, pre-filter
//     verdicts), written every flush period, OP_UPDATED (statistics only);
//   MAP                              -> landmark positions (segmentation, duplicates);
//   POSE_ESTIMATE                    -> the active set: regions near the robot
//     within the memory budget; OP_EVICTED / OP_LOADED as it changes;
//   pruning policy every prune period -> OP_REMOVED;
//   LANDMARK_REQUEST                 -> OP_SNAPSHOT to the requester;
//   LANDMARK_SUMMARY                 every summary period: revision, active ids.
// Every change carries the next database revision, so replicas (front-ends)
// detect a gap and ask for what they missed.

#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <vslam/landmark_request_t.hpp>
#include <vslam/landmark_update_t.hpp>
#include <vslam/map_t.hpp>
#include <vslam/pose_estimate_t.hpp>
#include <vslam/visual_measurement_t.hpp>

#include "bus/stage.hpp"
#include "bus/stage_registry.hpp"
#include "landmark_db/landmark_database.hpp"
#include "util/log.hpp"

namespace vslam::stages {

struct LandmarkDbParams {
  std::filesystem::path map_file;  // empty: in memory, nothing persists
  landmark_db::DatabaseParams db;
  double summary_period_s = 1.0;
  double flush_period_s = 1.0;
  double max_map_file_mb = 0;  // the map file stops growing here (0: no limit)
  // Less free space than this on the map file's filesystem warns in health:
  // new landmarks will soon not be stored.
  double min_free_disk_mb = 16;
  std::string proposal_channel, update_channel, summary_channel, request_channel;
  std::string measurement_channel, filtered_channel, map_channel, pose_channel;

  // The keys of the block, declared once (config/param_table.hpp).
  static const config::ParamTable<LandmarkDbParams>& table();
  static LandmarkDbParams load(const config::ConfigNode& node, const config::RobotConfig& robot);
};

class LandmarkDbStage final : public bus::Stage {
 public:
  // Opens an existing map file here (a foreign or damaged file fails before
  // the process starts); a new file is created in start().
  explicit LandmarkDbStage(LandmarkDbParams params, std::string instance = "landmark_db");
  ~LandmarkDbStage() override;
  void start(bus::StageContext& ctx) override;
  void onTimer(Utime now) override;
  void stop() override;
  void collectHealth(bus::HealthReport& report) override;
  std::vector<std::string> outputChannels() const override {
    return {params_.update_channel, params_.summary_channel};
  }
  // For tests: the database (null before start() for a new file).
  const landmark_db::LandmarkDatabase* database() const { return db_.get(); }

  // The landmark's content in the message (structure only if `structure`).
  static void fillLandmark(const landmark_db::LandmarkInfo& info,
                           const landmark_db::LandmarkStructure* structure, vslam::landmark_t* out);

 private:
  struct Stats {
    int64_t proposals = 0, created = 0, already_known = 0, refused = 0, invalid = 0;
    int64_t store_errors = 0, unknown_ids = 0, requests = 0, snapshots = 0, pruned = 0;
    int64_t evicted = 0, loaded = 0, updates = 0;
    int64_t store_rejected = 0;  // proposals rejected because the map file could not be written
    double request_ms = 0;
    int64_t revisions = 0, revisions_refused = 0;  // refined points from front-ends (OP_REVISED)
  };
  std::string last_store_error_;                   // the newest map file write failure, for health
  void checkDiskSpace(bus::HealthReport& report);  // mutex_ held
  enum LogReason { kLogProposal, kLogUnknown, kLogStore, kLogRequest, kLogMap, kNumLogReasons };
  template <class... Args>
  void logLimited(LogReason reason, const Args&... args);

  void open(bus::ExecutionMode mode);
  void onProposal(const vslam::landmark_update_t& msg);
  void onRevision(const vslam::landmark_update_t& msg);  // mutex_ held
  void onMeasurement(const vslam::visual_measurement_t& msg, bool filtered);
  void onMap(const vslam::map_t& msg);
  void onPose(const vslam::pose_estimate_t& msg);
  void onRequest(const vslam::landmark_request_t& msg);
  void publish(const std::vector<landmark_db::Change>& changes, Utime now);
  void publishReply(int8_t op, const vslam::landmark_update_t& proposal, int64_t id, Utime now);
  void publishSummary(Utime now);

  LandmarkDbParams params_;
  std::string instance_;
  bus::StageContext* ctx_ = nullptr;
  std::mutex mutex_;  // handlers, timer and health
  std::unique_ptr<landmark_db::LandmarkDatabase> db_;
  std::optional<Pose2> map_T_odom_;
  Utime next_summary_ = 0, next_flush_ = 0, next_prune_ = 0;
  Utime last_time_ = 0;  // newest robot time seen
  Stats stats_, last_;
  log::RateLimitedWarnings<kNumLogReasons> warnings_{5 * kMicrosPerSecond};
};

void registerLandmarkDb(bus::StageRegistry& registry);

}  // namespace vslam::stages
