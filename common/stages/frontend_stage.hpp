#pragma once
// vslam-frontend: the vSLAM visual front-end (paper section 4) for one
// camera: the LCM adapter of frontend::Frontend (common/frontend/frontend.hpp,
// which holds the tracking and the creation window). This stage decodes
// frames and odometry, publishes what each frame gives, and keeps the
// recognition index a replica of the landmark DB (the protocol below).
//
// Every frame (newest wins; stale frames are dropped, counted in health):
// SIFT features -> recognition of known landmarks (of every camera) -> a
// visual measurement per recognized landmark, published unfiltered on
// VISUAL_MEASUREMENT (the back-end's pre-filter judges it). Where no landmark
// gives a measurement the pre-filter would accept, the front-end collects
// three views ~creation_baseline_m apart by odometry and creates a new
// landmark from them, published on LANDMARK_PROPOSAL.
//
// Landmark ids (`landmark_db:` in the instance's block; docs/landmark-db.md):
//  - required: the landmark DB (vslam-landmark-db) owns the landmarks. A new
//    landmark is proposed on LANDMARK_PROPOSAL with a proposal_id and kept
//    "pending" (recognized, so the place is not proposed twice, but never
//    measured: measurements carry global ids only) until the DB's OP_CREATED
//    names its global id (OP_REJECTED drops it; no answer within
//    proposal_timeout_s sends it again). The recognition index is a replica
//    of the DB's in-memory set, kept current from LANDMARK_UPDATE (created,
//    loaded: added; removed, evicted: dropped); a revision gap, another
//    database_id, or a LANDMARK_SUMMARY that lists ids it lacks makes the
//    front-end ask for them on LANDMARK_REQUEST (OP_SNAPSHOT answers).
//  - none: no DB. Each front-end numbers its landmarks camera_number * 1e9 + n
//    (camera_number = 1-based position in the robot file), uses that id in its
//    measurements and proposals, and adds other front-ends' proposals to its
//    index, so every camera still recognizes every landmark (nothing persists).

#include <deque>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <vslam/image_t.hpp>
#include <vslam/landmark_summary_t.hpp>
#include <vslam/landmark_update_t.hpp>
#include <vslam/odometry_t.hpp>

#include "bus/input_watchdog.hpp"
#include "bus/latest_worker.hpp"
#include "bus/repeat_filter.hpp"
#include "bus/serial_worker.hpp"
#include "bus/stage.hpp"
#include "bus/stage_registry.hpp"
#include "frontend/frontend.hpp"

namespace vslam::stages {

struct FrontendStageParams {
  frontend::FrontendParams frontend;  // the algorithm (camera, window, SIFT, creation, ...)
  std::string camera_name;            // the robot file's camera this front-end reads
  int camera_number = 1;              // 1-based index of the camera in the robot file
  std::string odometry_channel;
  std::string measurement_channel;
  std::string view_jump_channel;
  std::string proposal_channel;
  std::string update_channel, summary_channel, request_channel;
  bool use_landmark_db = true;      // landmark_db: required (true) | none
  double proposal_timeout_s = 2.0;  // unanswered proposals are sent again after this
  double input_timeout_s = 2.0;     // quieter images or odometry: logged once, health WARN

  // The keys of the block, declared once (config/param_table.hpp).
  static const config::ParamTable<FrontendStageParams>& table();
  // The pre-filter is the stack's (loadPrefilter in stages/prefilter_config.hpp):
  // here to decide whether a place needs a landmark.
  static FrontendStageParams load(const config::ConfigNode& node, const config::RobotConfig& robot,
                                  const frontend::PrefilterParams& prefilter);
};

// Why a landmark from another front-end or the DB may not enter this
// front-end's replica ("" if it may): no SIFT points, too many points
// (landmark_db::kMaxLandmarkPoints), non-finite points.
std::string checkLandmarkMessage(const vslam::landmark_t& l);

class FrontendStage final : public bus::Stage {
 public:
  explicit FrontendStage(FrontendStageParams params);
  ~FrontendStage() override;
  void start(bus::StageContext& ctx) override;
  void drain() override;
  void stop() override;
  void collectHealth(bus::HealthReport& report) override;
  void prefetch(const std::string& channel, const void* data, size_t size) override;
  std::vector<std::string> outputChannels() const override {
    if (!params_.use_landmark_db) {
      return {params_.measurement_channel, params_.view_jump_channel, params_.proposal_channel};
    }
    return {params_.measurement_channel, params_.view_jump_channel, params_.proposal_channel,
            params_.request_channel};
  }

 private:
  struct Stats {
    int64_t frames = 0, features = 0, recognitions = 0, measurements = 0, measurement_failures = 0;
    int64_t created = 0, creation_failures = 0, foreign_landmarks = 0, no_odometry = 0;
    double sift_ms = 0, recognition_ms = 0, measurement_ms = 0, creation_ms = 0;
    int64_t acknowledged = 0, rejected = 0, resent = 0, sync_requests = 0, replica_added = 0,
            replica_removed = 0;
    int64_t prefetched = 0;              // frames whose features prefetch() extracted (replay)
    int64_t gained = 0;                  // dim frames scaled up before SIFT
    int64_t refined = 0;                 // landmarks refined from later views
    int64_t revisions_sent = 0;          // of those, revisions sent to the DB
    int64_t odometry_disagreements = 0;  // FrameResult::odometry_disagreements
  };

  void onImage(const vslam::image_t& msg);
  void onOdometry(const vslam::odometry_t& msg);
  void onProposal(const vslam::landmark_update_t& msg);
  // Landmark DB replica (landmark_db: required).
  void onUpdate(const vslam::landmark_update_t& msg);
  void onSummary(const vslam::landmark_summary_t& msg);
  void adoptDatabase(const std::string& database_id);                         // replica_mutex_ held
  void requestSync(int64_t since_revision, std::vector<int64_t> ids);         // replica_mutex_ held
  void addToReplica(const vslam::landmark_t& l, const std::string& channel);  // replica_mutex_ held
  void resendPending();
  void process(vslam::image_t& msg);
  void propose(const frontend::NewLandmark& created);
  // Sends a refined landmark's structure to the DB (OP_REVISED).
  void revise(const frontend::FrameResult::Refined& refined);
  vslam::landmark_update_t makeProposal(const frontend::NewLandmark& created, int64_t id) const;

  const config::CameraConfig& camera() const { return params_.frontend.camera; }

  FrontendStageParams params_;
  bus::StageContext* ctx_ = nullptr;
  std::unique_ptr<bus::LatestWinsWorker<vslam::image_t>> worker_;
  std::unique_ptr<bus::InputWatchdog> image_watchdog_, odometry_watchdog_;  // from start()
  bus::RepeatFilter repeated_images_{8};  // a frame delivered twice is measured once
  frontend::Frontend frontend_;
  cv::Mat gray_;
  // Lock-step replay: SIFT of the coming frames of this camera, extracted in
  // order on another thread while the events before them are handled
  // (prefetch()).
  struct PrefetchedFeatures {
    bool ok = false;  // false: the image is malformed (process() reports it)
    frontend::Features features;
    double sift_ms = 0;
  };
  frontend::FeatureExtractor prefetch_extractor_;  // used by prefetch_worker_ only
  cv::Mat prefetch_gray_;
  bus::SerialWorker prefetch_worker_;
  std::deque<std::pair<std::pair<Utime, int64_t>, std::future<PrefetchedFeatures>>>
      prefetched_;  // (utime, seq) of the frame, its features; in delivery order
  int64_t next_landmark_ = 1;
  // Replica state. Proposals and updates arrive on the LCM thread, frames on
  // the worker: replica_mutex_ keeps this state and the index's landmarks in step.
  std::mutex replica_mutex_;
  struct Pending {
    vslam::landmark_update_t proposal;
    Utime sent = 0;
    int64_t index_id = 0;  // its id in the index until the DB answers
  };
  int64_t proposal_base_ = -1;          // first frame's utime: proposal ids of this run
  std::map<int64_t, Pending> pending_;  // by proposal_id
  // Landmarks of this front-end being refined, by their first view's utime:
  // the proposal and the global id (-1 until the DB answers).
  struct Refining {
    int64_t proposal_id = -1;
    int64_t landmark_id = -1;
  };
  std::map<Utime, Refining> refining_;
  std::set<int64_t> replica_;  // global ids in the index
  std::string database_id_;    // database the replica follows ("" none yet)
  int64_t revision_ = -1;      // last revision applied (-1 unknown)
  Utime last_request_ = 0;
  int64_t measurement_seq_ = 0;
  std::mutex stats_mutex_;
  Stats stats_, last_;
};

void registerFrontend(bus::StageRegistry& registry);

}  // namespace vslam::stages
