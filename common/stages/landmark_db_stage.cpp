#include "stages/landmark_db_stage.hpp"

#include <sys/statvfs.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <vslam/landmark_summary_t.hpp>

#include "landmark_db/database_config.hpp"
#include "util/log.hpp"

namespace vslam::stages {
namespace {

using landmark_db::ChangeOp;
using vslam::landmark_update_t;

Utime periodUs(double seconds) { return std::max<Utime>(1, fromSeconds(seconds)); }

std::string hex(uint64_t v) {
  std::ostringstream os;
  os << std::hex << v;
  return os.str();
}

// FNV-1a: a deterministic id for a new map created in lock-step replay.
uint64_t fnv1a(const std::string& s) {
  uint64_t h = 1469598103934665603ULL;
  for (unsigned char c : s) {
    h ^= c;
    h *= 1099511628211ULL;
  }
  return h;
}

int8_t opOf(ChangeOp op) {
  switch (op) {
    case ChangeOp::kCreated:
      return landmark_update_t::OP_CREATED;
    case ChangeOp::kUpdated:
      return landmark_update_t::OP_UPDATED;
    case ChangeOp::kRemoved:
      return landmark_update_t::OP_REMOVED;
    case ChangeOp::kEvicted:
      return landmark_update_t::OP_EVICTED;
    case ChangeOp::kLoaded:
      return landmark_update_t::OP_LOADED;
  }
  return landmark_update_t::OP_UPDATED;
}

// The proposal's structure; "" or what is wrong.
std::string toStructure(const vslam::landmark_t& l, landmark_db::LandmarkStructure* s) {
  if (l.num_points <= 0) return "no points";
  const size_t n = static_cast<size_t>(l.num_points);
  if (l.descriptor_size != 128) {
    return "descriptor_size " + std::to_string(l.descriptor_size) + ", not 128 (SIFT)";
  }
  s->num_points = l.num_points;
  s->descriptor_size = l.descriptor_size;
  s->points.reserve(3 * n);
  s->keypoints.reserve(2 * n);
  s->descriptors.reserve(128 * n);
  for (size_t i = 0; i < n; ++i) {
    s->points.insert(s->points.end(), l.points[i].begin(), l.points[i].end());
    s->keypoints.insert(s->keypoints.end(), l.keypoints[i].begin(), l.keypoints[i].end());
    s->descriptors.insert(s->descriptors.end(), l.descriptors[i].begin(), l.descriptors[i].end());
  }
  s->scales = l.scales;
  s->orientations = l.orientations;
  return s->validate();
}

}  // namespace

const config::ParamTable<LandmarkDbParams>& LandmarkDbParams::table() {
  using P = LandmarkDbParams;
  using config::InRange;
  static const config::ParamTable<P> declared = [] {
    config::ParamTable<P> t;
    t.path("map_file", &P::map_file, false,
           "the map file, relative to the config file or under `$XDG_DATA_HOME/` or `~/` "
           "(`\"\"`: in memory, nothing persists); created if missing; a foreign or damaged file "
           "stops the process (exit 1) and is left untouched; `vslam-replay` uses a fresh map in "
           "memory unless `--map FILE`")
        .required()
        .add("summary_period_s", &P::summary_period_s, InRange{0.05, 3600}, "s",
             "LANDMARK_SUMMARY period")
        .required()
        .add("flush_period_s", &P::flush_period_s, InRange{0.05, 3600}, "s",
             "statistics are written (and OP_UPDATED published) at most this often")
        .required()
        .add("max_map_file_mb", &P::max_map_file_mb, InRange{0, 1e7}, "MiB",
             "the map file stops growing at this size (0: no limit); a proposal that no longer "
             "fits is answered OP_REJECTED, as on a full disk, and health is ERROR")
        .add("min_free_disk_mb", &P::min_free_disk_mb, InRange{0, 1e7}, "MiB",
             "less free space than this on the map file's filesystem warns in health "
             "(`disk_free_mb`), also right after a restart on a full disk")
        .merge(&P::db, landmark_db::databaseParamTable());
    return t;
  }();
  return declared;
}

LandmarkDbParams LandmarkDbParams::load(const config::ConfigNode& node,
                                        const config::RobotConfig& robot) {
  LandmarkDbParams p;
  table().load(node, p);
  landmark_db::setCameraHeadings(robot, p.db);
  const auto& ch = robot.channels;
  p.proposal_channel = ch.landmark_proposal;
  p.update_channel = ch.landmark_update;
  p.summary_channel = ch.landmark_summary;
  p.request_channel = ch.landmark_request;
  p.measurement_channel = ch.visual_measurement;
  p.filtered_channel = ch.visual_measurement_filtered;
  p.map_channel = ch.map;
  p.pose_channel = ch.pose_estimate;
  return p;
}

LandmarkDbStage::LandmarkDbStage(LandmarkDbParams params, std::string instance)
    : params_(std::move(params)), instance_(std::move(instance)) {
  std::error_code ec;
  if (!params_.map_file.empty() && std::filesystem::exists(params_.map_file, ec)) {
    open(bus::ExecutionMode::kLive);  // the id of an existing file is stored in it
  }
}

LandmarkDbStage::~LandmarkDbStage() { stop(); }

void LandmarkDbStage::open(bus::ExecutionMode mode) {
  landmark_db::StoreOptions so;
  so.create_if_missing = true;
  const std::string name = params_.map_file.empty() ? ":memory:" : params_.map_file.string();
  if (mode == bus::ExecutionMode::kLockstep || params_.map_file.empty()) {
    so.new_database_id = "lmdb-" + hex(fnv1a(instance_ + "|" + name));  // reproducible
  } else {
    std::random_device rd;
    so.new_database_id = "lmdb-" + hex((static_cast<uint64_t>(rd()) << 32) ^ rd() ^
                                       static_cast<uint64_t>(wallUtime()));
  }
  so.now = mode == bus::ExecutionMode::kLive ? wallUtime() : 0;
  so.max_file_bytes = static_cast<uint64_t>(params_.max_map_file_mb * 1024 * 1024);
  auto store = std::make_unique<landmark_db::LandmarkStore>(name, so);
  db_ = std::make_unique<landmark_db::LandmarkDatabase>(std::move(store), params_.db);
  log::info("landmark map ", name, ": database ", db_->databaseId(), ", revision ", db_->revision(),
            ", ", db_->numStored(), " landmarks stored, ", db_->numActive(), " in memory",
            params_.db.allow_new_landmarks ? "" : " (localization only)");
}

void LandmarkDbStage::start(bus::StageContext& ctx) {
  ctx_ = &ctx;
  if (!db_) open(ctx.mode);
  auto& bus = ctx.bus;
  bus.subscribe<landmark_update_t>(
      params_.proposal_channel, [this](const landmark_update_t& m) { onProposal(m); }, 100);
  bus.subscribe<vslam::visual_measurement_t>(
      params_.measurement_channel,
      [this](const vslam::visual_measurement_t& m) { onMeasurement(m, false); }, 200);
  bus.subscribe<vslam::visual_measurement_t>(
      params_.filtered_channel,
      [this](const vslam::visual_measurement_t& m) { onMeasurement(m, true); }, 200);
  bus.subscribe<vslam::map_t>(
      params_.map_channel, [this](const vslam::map_t& m) { onMap(m); }, 5);
  bus.subscribe<vslam::pose_estimate_t>(
      params_.pose_channel, [this](const vslam::pose_estimate_t& m) { onPose(m); }, 30);
  bus.subscribe<vslam::landmark_request_t>(
      params_.request_channel, [this](const vslam::landmark_request_t& m) { onRequest(m); }, 30);
}

template <class... Args>
void LandmarkDbStage::logLimited(LogReason reason, const Args&... args) {
  warnings_.warn(reason, ctx_->clock.now(), args...);
}

void LandmarkDbStage::fillLandmark(const landmark_db::LandmarkInfo& info,
                                   const landmark_db::LandmarkStructure* st, vslam::landmark_t* l) {
  l->landmark_id = info.id;
  l->proposal_id = info.proposal_id;
  l->version = info.version;
  l->camera = info.camera;
  l->created_utime = info.created_utime;
  l->created_odom_x = info.created_odom.x;
  l->created_odom_y = info.created_odom.y;
  l->created_odom_theta = info.created_odom.theta;
  l->num_recognitions = info.stats.num_recognitions;
  l->num_accepted = info.stats.num_accepted;
  l->num_rejected = info.stats.num_rejected;
  l->last_seen_utime = info.stats.last_seen_utime;
  l->descriptor_size = 128;
  l->num_points = 0;
  l->points.clear();
  l->keypoints.clear();
  l->scales.clear();
  l->orientations.clear();
  l->descriptors.clear();
  if (st == nullptr) return;
  const size_t n = static_cast<size_t>(st->num_points);
  const size_t d = static_cast<size_t>(st->descriptor_size);
  l->num_points = st->num_points;
  l->descriptor_size = static_cast<int16_t>(st->descriptor_size);
  l->points.resize(n);
  l->keypoints.resize(n);
  l->descriptors.resize(n);
  for (size_t i = 0; i < n; ++i) {
    l->points[i].assign(st->points.begin() + static_cast<ptrdiff_t>(3 * i),
                        st->points.begin() + static_cast<ptrdiff_t>(3 * i + 3));
    l->keypoints[i].assign(st->keypoints.begin() + static_cast<ptrdiff_t>(2 * i),
                           st->keypoints.begin() + static_cast<ptrdiff_t>(2 * i + 2));
    l->descriptors[i].assign(st->descriptors.begin() + static_cast<ptrdiff_t>(d * i),
                             st->descriptors.begin() + static_cast<ptrdiff_t>(d * i + d));
  }
  l->scales = st->scales;
  l->orientations = st->orientations;
}

void LandmarkDbStage::publish(const std::vector<landmark_db::Change>& changes, Utime now) {
  for (const auto& c : changes) {
    landmark_update_t m{};
    m.utime = now;
    m.database_id = db_->databaseId();
    m.revision = c.revision;
    m.op = opOf(c.op);
    const landmark_db::LandmarkInfo* info = db_->info(c.id);
    if (info != nullptr) {
      const bool full = c.op == ChangeOp::kCreated || c.op == ChangeOp::kLoaded ||
                        (c.op == ChangeOp::kUpdated && !c.stats_only);
      const auto st = full ? db_->structure(c.id) : nullptr;
      fillLandmark(*info, st.get(), &m.landmark);
    } else {  // removed: only the id
      m.landmark.landmark_id = c.id;
      m.landmark.descriptor_size = 128;
    }
    ctx_->bus.publish(params_.update_channel, m);
    switch (c.op) {
      case ChangeOp::kCreated:
        ++stats_.created;
        break;
      case ChangeOp::kUpdated:
        ++stats_.updates;
        break;
      case ChangeOp::kRemoved:
        ++stats_.pruned;
        log::info("pruned landmark ", c.id, " (", c.reason, ")");
        break;
      case ChangeOp::kEvicted:
        ++stats_.evicted;
        break;
      case ChangeOp::kLoaded:
        ++stats_.loaded;
        break;
    }
  }
}

void LandmarkDbStage::publishReply(int8_t op, const landmark_update_t& proposal, int64_t id,
                                   Utime now) {
  landmark_update_t m{};
  m.utime = now;
  m.database_id = db_->databaseId();
  m.revision = db_->revision();
  m.op = op;
  const landmark_db::LandmarkInfo* info = id > 0 ? db_->info(id) : nullptr;
  if (info != nullptr) {
    const auto st = db_->structure(id);
    fillLandmark(*info, st.get(), &m.landmark);
  } else {
    m.landmark.landmark_id = -1;
    m.landmark.descriptor_size = 128;
  }
  // The proposer recognizes its answer by these two.
  m.landmark.camera = proposal.landmark.camera;
  m.landmark.proposal_id = proposal.landmark.proposal_id;
  ctx_->bus.publish(params_.update_channel, m);
}

void LandmarkDbStage::onRevision(const landmark_update_t& msg) {
  const vslam::landmark_t& l = msg.landmark;
  landmark_db::LandmarkStructure st;
  const std::string malformed = toStructure(l, &st);
  if (!malformed.empty()) {
    ++stats_.revisions_refused;
    ctx_->bus.reportMalformed(params_.proposal_channel, "revision of landmark " +
                                                            std::to_string(l.landmark_id) +
                                                            " of '" + l.camera + "': " + malformed);
    return;
  }
  landmark_db::LandmarkDatabase::RevisionResult r;
  try {
    r = db_->revise(l.landmark_id, l.camera, l.proposal_id, std::move(st.points));
  } catch (const std::exception& e) {
    ++stats_.store_errors;
    last_store_error_ = e.what();
    logLimited(kLogStore, "cannot store the revision of landmark ", l.landmark_id, ": ", e.what(),
               "; kept as it was");
    return;
  }
  if (!r.reason.empty()) {
    // Not the sender's fault when the landmark was pruned or merged since.
    ++stats_.revisions_refused;
    logLimited(kLogProposal, "revision of landmark ", l.landmark_id, " from ", l.camera,
               " refused: ", r.reason);
    return;
  }
  ++stats_.revisions;
  publish(r.changes, ctx_->clock.now());
}

void LandmarkDbStage::onProposal(const landmark_update_t& msg) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (msg.op == landmark_update_t::OP_REVISED) {
    onRevision(msg);
    return;
  }
  if (msg.op != landmark_update_t::OP_PROPOSED) {
    ctx_->bus.reportMalformed(params_.proposal_channel,
                              "op " + std::to_string(msg.op) + " on the proposal channel");
    return;
  }
  ++stats_.proposals;
  const Utime now = ctx_->clock.now();
  last_time_ = std::max(last_time_, msg.landmark.created_utime);
  const vslam::landmark_t& l = msg.landmark;
  landmark_db::LandmarkInfo info;
  info.camera = l.camera;
  info.proposal_id = l.proposal_id;
  info.created_utime = l.created_utime;
  info.created_odom = {l.created_odom_x, l.created_odom_y, l.created_odom_theta};
  landmark_db::LandmarkStructure st;
  std::string why = toStructure(l, &st);
  if (why.empty() && l.camera.empty()) why = "no camera name";
  if (why.empty() && !info.created_odom.isFinite()) why = "non-finite creation pose";
  if (!why.empty()) {
    ++stats_.invalid;
    ctx_->bus.reportMalformed(
        params_.proposal_channel,
        "proposal " + std::to_string(l.proposal_id) + " of '" + l.camera + "': " + why);
    publishReply(landmark_update_t::OP_REJECTED, msg, -1, now);
    return;
  }
  landmark_db::ProposalResult r;
  try {
    r = db_->propose(std::move(info), std::move(st), map_T_odom_);
  } catch (const std::exception& e) {
    // Nothing changed (the database writes first); the front-end is told, so
    // it does not wait for an answer or send it again forever (a full disk).
    ++stats_.store_errors;
    ++stats_.store_rejected;
    last_store_error_ = e.what();
    logLimited(kLogStore, "cannot store proposal ", l.proposal_id, " of ", l.camera, ": ", e.what(),
               "; rejected");
    publishReply(landmark_update_t::OP_REJECTED, msg, -1, now);
    return;
  }
  switch (r.outcome) {
    case landmark_db::ProposalOutcome::kCreated:
      publish(r.changes, now);
      break;
    case landmark_db::ProposalOutcome::kAlreadyKnown:
      // A proposal sent again (its answer was lost, or the DB restarted):
      // answer again without a change.
      ++stats_.already_known;
      publishReply(landmark_update_t::OP_SNAPSHOT, msg, r.id, now);
      break;
    case landmark_db::ProposalOutcome::kRefused:
      ++stats_.refused;
      logLimited(kLogProposal, "proposal ", l.proposal_id, " of ", l.camera,
                 " refused: ", r.reason);
      publishReply(landmark_update_t::OP_REJECTED, msg, -1, now);
      break;
    case landmark_db::ProposalOutcome::kInvalid:
      ++stats_.invalid;
      ctx_->bus.reportMalformed(params_.proposal_channel,
                                "proposal " + std::to_string(l.proposal_id) + ": " + r.reason);
      publishReply(landmark_update_t::OP_REJECTED, msg, -1, now);
      break;
  }
}

void LandmarkDbStage::onMeasurement(const vslam::visual_measurement_t& msg, bool filtered) {
  std::lock_guard<std::mutex> lock(mutex_);
  last_time_ = std::max(last_time_, msg.utime);
  if (filtered && msg.status == vslam::visual_measurement_t::STATUS_UNFILTERED) return;
  const bool known =
      filtered ? db_->recordVerdict(msg.landmark_id,
                                    msg.status == vslam::visual_measurement_t::STATUS_ACCEPTED,
                                    msg.utime)
               : db_->recordMeasurement(msg.landmark_id, msg.utime);
  if (!known) {
    ++stats_.unknown_ids;
    logLimited(kLogUnknown, "measurement of unknown landmark ", msg.landmark_id, " from ",
               msg.camera, " (not in database ", db_->databaseId(), ")");
  }
}

void LandmarkDbStage::onMap(const vslam::map_t& msg) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!msg.database_id.empty() && msg.database_id != db_->databaseId()) {
    logLimited(kLogMap, "MAP from ", msg.estimator, " is for database ", msg.database_id,
               ", this is ", db_->databaseId(), "; used by landmark id anyway");
  }
  std::vector<std::pair<int64_t, Pose2>> poses;
  poses.reserve(msg.landmarks.size());
  for (const auto& l : msg.landmarks) poses.push_back({l.landmark_id, Pose2{l.x, l.y, l.theta}});
  db_->setMapPoses(poses);
}

void LandmarkDbStage::onPose(const vslam::pose_estimate_t& msg) {
  std::lock_guard<std::mutex> lock(mutex_);
  const Pose2 map_pose{msg.x, msg.y, msg.theta};
  const Pose2 odom_pose{msg.odom_x, msg.odom_y, msg.odom_theta};
  if (!map_pose.isFinite() || !odom_pose.isFinite()) {
    ctx_->bus.reportMalformed(params_.pose_channel, "non-finite pose estimate");
    return;
  }
  last_time_ = std::max(last_time_, msg.utime);
  map_T_odom_ = map_pose.compose(odom_pose.inverse());
  db_->setRobotPose(map_pose);
  landmark_db::RobotPoseRecord estimate{msg.utime, map_pose, odom_pose, {}};
  std::copy(std::begin(msg.covariance), std::end(msg.covariance), estimate.covariance.begin());
  if (std::all_of(estimate.covariance.begin(), estimate.covariance.end(),
                  [](double c) { return std::isfinite(c); })) {
    db_->noteRobotEstimate(estimate, msg.kidnapped);
  }
  try {
    publish(db_->updateActiveSet(), ctx_->clock.now());
  } catch (const std::exception& e) {
    ++stats_.store_errors;
    last_store_error_ = e.what();
    logLimited(kLogStore, "segmentation: ", e.what());
  }
}

void LandmarkDbStage::onRequest(const vslam::landmark_request_t& msg) {
  std::lock_guard<std::mutex> lock(mutex_);
  const Utime t0 = monotonicUtime();
  ++stats_.requests;
  std::vector<int64_t> ids;
  if (msg.num_ids > 0) {
    for (int64_t id : msg.landmark_ids) {
      if (db_->isActive(id)) ids.push_back(id);
    }
  } else if (msg.database_id == db_->databaseId()) {
    ids = db_->activeChangedSince(msg.since_revision);
  } else {
    ids = db_->activeIds();  // another (or no) database: everything in memory
  }
  const Utime now = ctx_->clock.now();
  for (int64_t id : ids) {
    landmark_update_t m{};
    m.utime = now;
    m.database_id = db_->databaseId();
    m.revision = db_->revision();
    m.op = landmark_update_t::OP_SNAPSHOT;
    m.requester = msg.requester;
    const auto st = db_->structure(id);
    fillLandmark(*db_->info(id), st.get(), &m.landmark);
    ctx_->bus.publish(params_.update_channel, m);
  }
  stats_.snapshots += static_cast<int64_t>(ids.size());
  stats_.request_ms += 1e-3 * static_cast<double>(monotonicUtime() - t0);
  log::debug("request from ", msg.requester, " (since ", msg.since_revision, ", ", msg.num_ids,
             " ids): ", ids.size(), " landmarks sent");
}

void LandmarkDbStage::publishSummary(Utime now) {
  vslam::landmark_summary_t s{};
  s.utime = now;
  s.database_id = db_->databaseId();
  s.revision = db_->revision();
  s.num_stored = static_cast<int32_t>(db_->numStored());
  s.landmark_ids = db_->activeIds();
  s.num_landmarks = static_cast<int32_t>(s.landmark_ids.size());
  s.versions.reserve(s.landmark_ids.size());
  for (int64_t id : s.landmark_ids) s.versions.push_back(db_->info(id)->version);
  ctx_->bus.publish(params_.summary_channel, s);
}

void LandmarkDbStage::onTimer(Utime now) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!db_ || ctx_ == nullptr) return;
  try {
    if (now >= next_flush_) {
      publish(db_->flush(), now);
      next_flush_ = now + periodUs(params_.flush_period_s);
    }
    if (params_.db.prune.enabled && now >= next_prune_) {
      if (next_prune_ != 0) {
        // Ages in robot time: the newest time seen on the bus (replay: the log's).
        publish(db_->prune(std::max(last_time_, now)), now);
      }
      next_prune_ = now + periodUs(params_.db.prune.period_s);
    }
  } catch (const std::exception& e) {
    ++stats_.store_errors;
    last_store_error_ = e.what();
    logLimited(kLogStore, "cannot write the map: ", e.what());
  }
  if (now >= next_summary_) {
    publishSummary(now);
    next_summary_ = now + periodUs(params_.summary_period_s);
  }
}

void LandmarkDbStage::stop() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!db_) return;
  try {
    db_->flush();  // statistics; published or not, they are stored
  } catch (const std::exception& e) {
    log::error("cannot write the last statistics: ", e.what());
  }
}

void LandmarkDbStage::checkDiskSpace(bus::HealthReport& report) {
  if (params_.map_file.empty()) return;
  constexpr double kMiB = 1024.0 * 1024.0;
  struct statvfs fs {};
  const std::filesystem::path dir =
      params_.map_file.has_parent_path() ? params_.map_file.parent_path() : ".";
  if (statvfs(dir.c_str(), &fs) == 0) {
    const double free_mb =
        static_cast<double>(fs.f_bavail) * static_cast<double>(fs.f_frsize) / kMiB;
    report.add("disk_free_mb", free_mb, "MiB");
    if (free_mb < params_.min_free_disk_mb) {
      report.warn("only " + std::to_string(static_cast<int>(free_mb)) + " MiB free for " +
                  params_.map_file.string() + ": new landmarks will not be stored");
    }
  }
  if (params_.max_map_file_mb > 0 &&
      static_cast<double>(db_->store().fileBytes()) >= 0.95 * params_.max_map_file_mb * kMiB) {
    report.warn("the map file is at its size limit (max_map_file_mb " +
                std::to_string(params_.max_map_file_mb) + "): new landmarks will not be stored");
  }
}

void LandmarkDbStage::collectHealth(bus::HealthReport& report) {
  std::lock_guard<std::mutex> lock(mutex_);
  if (!db_) return;
  const Stats& s = stats_;
  const Stats d{s.proposals - last_.proposals,
                s.created - last_.created,
                s.already_known - last_.already_known,
                s.refused - last_.refused,
                s.invalid - last_.invalid,
                s.store_errors - last_.store_errors,
                s.unknown_ids - last_.unknown_ids,
                s.requests - last_.requests,
                s.snapshots - last_.snapshots,
                s.pruned - last_.pruned,
                s.evicted - last_.evicted,
                s.loaded - last_.loaded,
                s.updates - last_.updates,
                s.store_rejected - last_.store_rejected,
                s.request_ms - last_.request_ms};
  last_ = stats_;
  int64_t commits = 0;
  const double commit_ms = db_->store().takeMeanCommitMs(&commits);
  constexpr double kMiB = 1024.0 * 1024.0;
  report.add("landmarks_stored", static_cast<double>(db_->numStored()), "count");
  report.add("landmarks_in_memory", static_cast<double>(db_->numActive()), "count");
  report.add("replica_mb", static_cast<double>(db_->activeReplicaBytes()) / kMiB, "MiB");
  report.add("memory_budget_mb", static_cast<double>(db_->budgetBytes()) / kMiB, "MiB");
  report.add("held_mb", static_cast<double>(db_->heldBytes()) / kMiB, "MiB");
  report.add("file_mb", static_cast<double>(db_->store().fileBytes()) / kMiB, "MiB");
  report.add("revision", static_cast<double>(db_->revision()), "");
  report.add("commits", static_cast<double>(commits), "count");
  report.add("commit_ms", commit_ms, "ms");
  report.add("proposals", static_cast<double>(d.proposals), "count");
  report.add("landmarks_revised", static_cast<double>(stats_.revisions), "count");
  report.add("revisions_refused", static_cast<double>(stats_.revisions_refused), "count");
  report.add("created", static_cast<double>(d.created), "count");
  report.add("proposals_repeated", static_cast<double>(d.already_known), "count");
  report.add("proposals_refused", static_cast<double>(d.refused), "count");
  report.add("proposals_invalid", static_cast<double>(d.invalid), "count");
  report.add("pruned", static_cast<double>(d.pruned), "count");
  report.add("pruned_total", static_cast<double>(s.pruned), "count");
  report.add("evicted", static_cast<double>(d.evicted), "count");
  report.add("loaded", static_cast<double>(d.loaded), "count");
  report.add("requests", static_cast<double>(d.requests), "count");
  report.add("snapshots_sent", static_cast<double>(d.snapshots), "count");
  report.add("request_ms", d.requests > 0 ? d.request_ms / static_cast<double>(d.requests) : 0,
             "ms");
  report.add("measurements_unknown_landmark", static_cast<double>(d.unknown_ids), "count");
  report.add("proposals_store_failed", static_cast<double>(d.store_rejected), "count");
  if (d.store_errors > 0) {
    report.fail("map file writes failed (" + last_store_error_ +
                "); new landmarks are rejected, stored ones are kept");
  }
  checkDiskSpace(report);
  if (d.unknown_ids > 0) report.warn("measurements of landmarks this database does not have");
}

void registerLandmarkDb(bus::StageRegistry& registry) {
  registry.add(
      "landmark_db",
      [](const bus::StageSetup& setup) {
        return std::make_unique<LandmarkDbStage>(
            LandmarkDbParams::load(setup.params, setup.stack.robot), setup.instance);
      },
      bus::describeWith(LandmarkDbParams::table()));
}

}  // namespace vslam::stages
