#include "stages/frontend_stage.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <vslam/landmark_request_t.hpp>
#include <vslam/view_jump_t.hpp>
#include <vslam/visual_measurement_t.hpp>

#include "bus/checked_decode.hpp"
#include "landmark_db/landmark_record.hpp"
#include "stages/image_gray.hpp"
#include "stages/prefilter_config.hpp"
#include "util/log.hpp"

namespace vslam::stages {
namespace {

constexpr int64_t kIdsPerCamera = 1000000000;
constexpr Utime kMinRequestInterval = kMicrosPerSecond;  // between two replica sync requests

frontend::LandmarkModel modelFromMessage(const vslam::landmark_t& l, int64_t id) {
  frontend::LandmarkModel model;
  model.id = id;
  model.created_utime = l.created_utime;
  model.created_odometry = Pose2{l.created_odom_x, l.created_odom_y, l.created_odom_theta};
  model.descriptors.create(l.num_points, 128, CV_32F);
  for (int i = 0; i < l.num_points; ++i) {
    const size_t k = static_cast<size_t>(i);
    model.points_robot.emplace_back(l.points[k][0], l.points[k][1], l.points[k][2]);
    for (int c = 0; c < 128; ++c) {
      model.descriptors.at<float>(i, c) =
          static_cast<float>(l.descriptors[k][static_cast<size_t>(c)]);
    }
  }
  return model;
}

double msSince(Utime start) { return 1e-3 * static_cast<double>(monotonicUtime() - start); }

}  // namespace

std::string checkLandmarkMessage(const vslam::landmark_t& l) {
  if (l.num_points <= 0 || l.descriptor_size != 128) return "without SIFT points";
  if (l.num_points > landmark_db::kMaxLandmarkPoints) {
    return "with " + std::to_string(l.num_points) + " points (at most " +
           std::to_string(landmark_db::kMaxLandmarkPoints) + ")";
  }
  for (const auto& p : l.points) {
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
      return "with non-finite points";
    }
  }
  return "";
}

const config::ParamTable<FrontendStageParams>& FrontendStageParams::table() {
  using P = FrontendStageParams;
  using config::InRange;
  static const config::ParamTable<P> declared = [] {
    config::ParamTable<P> t;
    t.add("camera", &P::camera_name,
          "camera name in the robot file; its image channel, intrinsics and extrinsics are used")
        .required()
        .add(
            "creation_baseline_m", [](auto& p) -> auto& { return p.frontend.creation_baseline_m; },
            InRange{0.02, 2.0}, "m", "odometry travel between the three views of a new landmark")
        .add(
            "coverage_radius_m", [](auto& p) -> auto& { return p.frontend.coverage_radius_m; },
            InRange{0, 100}, "m",
            "a landmark covers its place (no new one is made there) only when measured within "
            "this distance of its creation pose; 0: at any distance")
        .add(
            "coverage_gate_sigmas",
            [](auto& p) -> auto& { return p.frontend.coverage_gate.sigmas; }, InRange{0, 100}, "",
            "a landmark covers its place only when measured where the odometry since its "
            "creation puts the robot, within this many standard deviations of the odometry's "
            "drift (coverage_odometry_sigma_*) plus the measurement's error: a repeated pattern "
            "recognized a period away is a look-alike and its place gets a landmark of its own "
            "(only for landmarks made in view of this front-end's odometry since the last view "
            "jump); 0: any measurement the pre-filter accepts covers")
        .add(
            "coverage_odometry_sigma_translation",
            [](auto& p) -> auto& { return p.frontend.coverage_gate.sigma_translation; },
            InRange{0, 1}, "m/sqrt(m)",
            "the odometry's translation drift assumed by coverage_gate_sigmas: the worst the "
            "robot's wheels are expected to have, not the typical")
        .add(
            "coverage_odometry_sigma_rotation",
            [](auto& p) -> auto& { return p.frontend.coverage_gate.sigma_rotation; }, InRange{0, 1},
            "rad/sqrt(m+rad)", "its heading drift, likewise")
        .add(
            "refine_distance_m", [](auto& p) -> auto& { return p.frontend.refine_distance_m; },
            InRange{0, 5}, "m",
            "a new landmark is refined with the frames that see it until the robot has driven "
            "this far from its first view (longer baselines than its three views), and its "
            "refined points sent to the landmark DB (OP_REVISED); 0: not refined")
        .add(
            "view_jump_max_matched_share",
            [](auto& p) -> auto& { return p.frontend.view_jump_max_matched_share; }, InRange{0, 1},
            "",
            "the view jumped (carried, kidnapped) when a frame finds again fewer than this share "
            "of the previous frame's strongest features although odometry says the robot barely "
            "moved; published on the view-jump channel for the back-end's kidnap test; 0: not "
            "tested")
        .add(
            "view_jump_min_thumbnail_similarity",
            [](auto& p) -> auto& { return p.frontend.view_jump_min_thumbnail_similarity; },
            InRange{0, 1}, "",
            "the view jumped (carried, kidnapped) when the frame reduced ten times correlates "
            "less than this with the previous one so reduced (over the shifts the odometry's "
            "turn allows), odometry as above; where both have contrast this decides (with the "
            "features where it is unsure: view_jump_features_below_similarity), needing no "
            "features (a dark room) and not fooled by a repeated pattern's, else "
            "view_jump_max_matched_share does; 0: not tested")
        .add(
            "view_jump_features_below_similarity",
            [](auto& p) -> auto& { return p.frontend.view_jump_features_below_similarity; },
            InRange{0, 1}, "",
            "thumbnails alike at least view_jump_min_thumbnail_similarity but less than this are "
            "not sure: the features are tested as well (view_jump_max_matched_share), and the "
            "view jumped if they say so (a carry between two views of one repeated pattern); 0: "
            "the thumbnails alone")
        .add(
            "max_measurements_per_frame",
            [](auto& p) -> auto& { return p.frontend.max_measurements_per_frame; }, InRange{1, 100},
            "", "recognized landmarks measured per frame, most matches first")
        .add(
            "sift_max_features", [](auto& p) -> auto& { return p.frontend.sift.nfeatures; },
            InRange{0, 100000}, "", "keep the N strongest SIFT features (0 = all)")
        .add(
            "sift_contrast_threshold",
            [](auto& p) -> auto& { return p.frontend.sift.contrast_threshold; },
            InRange{0.001, 1.0}, "",
            "OpenCV's contrastThreshold: weaker extrema are not keypoints (divided by the "
            "layers per octave)")
        .add(
            "sift_double_first_octave",
            [](auto& p) -> auto& { return p.frontend.sift.double_first_octave; },
            "SIFT's first octave at twice the image's resolution (OpenCV's, Lowe's); false: at "
            "its own, about a third of the time, fewer small features")
        .add(
            "dim_frame_gain_target",
            [](auto& p) -> auto& { return p.frontend.sift.gain_target_level; }, InRange{0, 255},
            "grey level",
            "a frame whose 99th-percentile level is below this is scaled up to it before SIFT "
            "(0: off)")
        .add(
            "dim_frame_max_gain", [](auto& p) -> auto& { return p.frontend.sift.max_gain; },
            InRange{1, 64}, "", "at most this gain")
        .add(
            "match_ratio", [](auto& p) -> auto& { return p.frontend.recognition.ratio; },
            InRange{0.1, 1.0}, "", "Lowe's ratio test, for recognition and landmark creation")
        .add(
            "min_matches", [](auto& p) -> auto& { return p.frontend.recognition.min_matches; },
            InRange{4, 1000}, "", "matches for a landmark to be measured")
        .choice("landmark_db", &P::use_landmark_db,
                std::vector<std::pair<std::string, bool>>{{"required", true}, {"none", false}},
                "`required`: the landmark DB owns the landmarks (proposals, global ids, a replica "
                "for recognition); `none`: no DB, each front-end numbers its own landmarks "
                "camera_number x 10^9 + n and adds the other front-ends' proposals (nothing "
                "persists)")
        .required()
        .add("input_timeout_s", &P::input_timeout_s, InRange{0.05, 3600}, "s",
             "images or odometry quieter than this (the stage's clock) are logged once and raise "
             "health to WARN until they resume")
        .add("proposal_timeout_s", &P::proposal_timeout_s, InRange{0.1, 600}, "s",
             "an unanswered proposal is sent again after this (the DB restarted, or a message was "
             "lost)");
    return t;
  }();
  return declared;
}

FrontendStageParams FrontendStageParams::load(const config::ConfigNode& node,
                                              const config::RobotConfig& robot,
                                              const frontend::PrefilterParams& prefilter) {
  rejectInstancePrefilter(node);
  FrontendStageParams p;
  table().load(node, p);
  frontend::FrontendParams& f = p.frontend;
  f.prefilter = prefilter;
  f.creation.match.ratio = f.recognition.ratio;
  bool found = false;
  for (size_t i = 0; i < robot.cameras.size(); ++i) {
    if (robot.cameras[i].name == p.camera_name) {
      f.camera = robot.cameras[i];
      p.camera_number = static_cast<int>(i) + 1;
      found = true;
    }
  }
  if (!found) {
    throw node.error("camera", "no camera '" + p.camera_name + "' in " + robot.file.string());
  }
  p.odometry_channel = robot.channels.odometry;
  p.measurement_channel = robot.channels.visual_measurement;
  p.view_jump_channel = robot.channels.view_jump;
  p.proposal_channel = robot.channels.landmark_proposal;
  p.update_channel = robot.channels.landmark_update;
  p.summary_channel = robot.channels.landmark_summary;
  p.request_channel = robot.channels.landmark_request;
  return p;
}

FrontendStage::FrontendStage(FrontendStageParams params)
    : params_(std::move(params)),
      frontend_(params_.frontend),
      prefetch_extractor_(params_.frontend.camera, params_.frontend.sift) {}

FrontendStage::~FrontendStage() { stop(); }

void FrontendStage::start(bus::StageContext& ctx) {
  ctx_ = &ctx;
  worker_ = std::make_unique<bus::LatestWinsWorker<vslam::image_t>>(
      ctx.mode, [this](vslam::image_t& img) { process(img); });
  image_watchdog_ = std::make_unique<bus::InputWatchdog>("images on " + camera().image_channel,
                                                         "image_age_s", params_.input_timeout_s,
                                                         ": nothing is measured or created");
  odometry_watchdog_ = std::make_unique<bus::InputWatchdog>(
      "odometry on " + params_.odometry_channel, "odometry_age_s", params_.input_timeout_s,
      ": no landmarks can be created");
  image_watchdog_->begin(ctx.clock.now());
  odometry_watchdog_->begin(ctx.clock.now());
  ctx.bus.subscribe<vslam::odometry_t>(params_.odometry_channel,
                                       [this](const vslam::odometry_t& m) { onOdometry(m); });
  if (params_.use_landmark_db) {
    // A snapshot answer can be every landmark in memory at once.
    ctx.bus.subscribe<vslam::landmark_update_t>(
        params_.update_channel, [this](const vslam::landmark_update_t& m) { onUpdate(m); }, 2000);
    ctx.bus.subscribe<vslam::landmark_summary_t>(
        params_.summary_channel, [this](const vslam::landmark_summary_t& m) { onSummary(m); }, 5);
  } else {
    ctx.bus.subscribe<vslam::landmark_update_t>(
        params_.proposal_channel, [this](const vslam::landmark_update_t& m) { onProposal(m); });
  }
  // A small queue: frames wait in the worker's one-slot mailbox, not in LCM.
  ctx.bus.subscribe<vslam::image_t>(
      camera().image_channel, [this](const vslam::image_t& m) { onImage(m); }, 2);
}

void FrontendStage::drain() {
  if (worker_) worker_->drain();
}

void FrontendStage::stop() {
  if (worker_) worker_->stop();
  prefetch_worker_.stop();
  prefetched_.clear();
}

void FrontendStage::onOdometry(const vslam::odometry_t& m) {
  odometry_watchdog_->arrived(ctx_->clock.now(), m.utime);
  if (frontend_.addOdometry(m.utime, Pose2{m.x, m.y, m.theta}) ==
      frontend::Frontend::OdometryVerdict::kNotFinite) {
    ctx_->bus.reportMalformed(params_.odometry_channel, "non-finite odometry pose");
  }
}

void FrontendStage::onImage(const vslam::image_t& msg) {
  image_watchdog_->arrived(ctx_->clock.now(), msg.utime);
  if (repeated_images_.repeated("", msg.seq, msg.utime)) return;
  if (!worker_->post(msg)) ctx_->bus.countDropped();
}

void FrontendStage::onProposal(const vslam::landmark_update_t& m) {
  const vslam::landmark_t& l = m.landmark;
  if (m.op != vslam::landmark_update_t::OP_PROPOSED || l.camera == camera().name) return;
  const std::string why = checkLandmarkMessage(l);
  if (!why.empty()) {
    ctx_->bus.reportMalformed(params_.proposal_channel,
                              "landmark " + std::to_string(l.landmark_id) + " " + why);
    return;
  }
  frontend_.addLandmark(modelFromMessage(l, l.landmark_id));
  std::lock_guard<std::mutex> stats_lock(stats_mutex_);
  ++stats_.foreign_landmarks;
}

void FrontendStage::addToReplica(const vslam::landmark_t& l, const std::string& channel) {
  const std::string why = checkLandmarkMessage(l);
  if (l.landmark_id <= 0 || !why.empty()) {
    ctx_->bus.reportMalformed(channel, "landmark " + std::to_string(l.landmark_id) + " " +
                                           (why.empty() ? "without a global id" : why));
    return;
  }
  frontend_.addLandmark(modelFromMessage(l, l.landmark_id));
  replica_.insert(l.landmark_id);
  std::lock_guard<std::mutex> stats_lock(stats_mutex_);
  ++stats_.replica_added;
}

void FrontendStage::adoptDatabase(const std::string& database_id) {
  if (database_id == database_id_) return;
  if (!database_id_.empty()) {
    log::warn("landmark database changed from ", database_id_, " to ", database_id, ": replica of ",
              replica_.size(), " landmarks dropped");
  }
  for (int64_t id : replica_) frontend_.removeLandmark(id);
  std::lock_guard<std::mutex> stats_lock(stats_mutex_);
  stats_.replica_removed += static_cast<int64_t>(replica_.size());
  replica_.clear();
  database_id_ = database_id;
  revision_ = -1;
}

void FrontendStage::requestSync(int64_t since_revision, std::vector<int64_t> ids) {
  const Utime now = ctx_->clock.now();
  if (last_request_ != 0 && now - last_request_ < kMinRequestInterval) return;
  last_request_ = now;
  vslam::landmark_request_t r{};
  r.utime = now;
  r.requester = ctx_->instance;
  r.database_id = database_id_;
  r.since_revision = since_revision;
  r.landmark_ids = std::move(ids);
  r.num_ids = static_cast<int32_t>(r.landmark_ids.size());
  ctx_->bus.publish(params_.request_channel, r);
  std::lock_guard<std::mutex> stats_lock(stats_mutex_);
  ++stats_.sync_requests;
}

void FrontendStage::onUpdate(const vslam::landmark_update_t& m) {
  using U = vslam::landmark_update_t;
  const vslam::landmark_t& l = m.landmark;
  std::lock_guard<std::mutex> lock(replica_mutex_);
  if (m.database_id.empty()) {
    ctx_->bus.reportMalformed(params_.update_channel, "update without a database_id");
    return;
  }
  adoptDatabase(m.database_id);
  // The answer to one of this front-end's proposals.
  const bool mine = l.camera == camera().name && pending_.count(l.proposal_id) > 0;
  if (mine && (m.op == U::OP_CREATED || m.op == U::OP_SNAPSHOT || m.op == U::OP_REJECTED)) {
    for (auto& [first_view, refining] : refining_) {
      if (refining.proposal_id == l.proposal_id) refining.landmark_id = l.landmark_id;
    }
    frontend_.removeLandmark(pending_[l.proposal_id].index_id);
    pending_.erase(l.proposal_id);
    std::lock_guard<std::mutex> stats_lock(stats_mutex_);
    ++(m.op == U::OP_REJECTED ? stats_.rejected : stats_.acknowledged);
  }
  if (m.op == U::OP_REJECTED) return;
  if (m.op == U::OP_SNAPSHOT) {
    // Answers to other requesters are ignored (unless they acknowledged a proposal of ours).
    if (!mine && !m.requester.empty() && m.requester != ctx_->instance) return;
    addToReplica(l, params_.update_channel);
    revision_ = std::max(revision_, m.revision);
    return;
  }
  if (revision_ >= 0 && m.revision > revision_ + 1) {
    log::info("landmark updates ", revision_ + 1, "..", m.revision - 1, " of ", database_id_,
              " missed: asking for them");
    requestSync(revision_, {});
  }
  revision_ = std::max(revision_, m.revision);
  switch (m.op) {
    case U::OP_CREATED:
    case U::OP_LOADED:
      addToReplica(l, params_.update_channel);
      break;
    case U::OP_UPDATED:
      if (l.num_points > 0) addToReplica(l, params_.update_channel);  // structure changed
      break;
    case U::OP_REMOVED:
    case U::OP_EVICTED:
      if (replica_.erase(l.landmark_id) > 0) {
        frontend_.removeLandmark(l.landmark_id);
        std::lock_guard<std::mutex> stats_lock(stats_mutex_);
        ++stats_.replica_removed;
      }
      break;
    default:
      ctx_->bus.reportMalformed(params_.update_channel, "op " + std::to_string(m.op));
  }
}

void FrontendStage::onSummary(const vslam::landmark_summary_t& s) {
  if (s.landmark_ids.size() != s.versions.size() || s.database_id.empty()) {
    ctx_->bus.reportMalformed(params_.summary_channel, "summary without a database_id or sizes");
    return;
  }
  std::lock_guard<std::mutex> lock(replica_mutex_);
  adoptDatabase(s.database_id);
  // The summary lists what the DB holds in memory as of its revision; updates
  // published before it have arrived before it.
  const std::set<int64_t> listed(s.landmark_ids.begin(), s.landmark_ids.end());
  std::vector<int64_t> extra, missing;
  for (int64_t id : replica_) {
    if (listed.count(id) == 0) extra.push_back(id);
  }
  for (int64_t id : listed) {
    if (replica_.count(id) == 0) missing.push_back(id);
  }
  for (int64_t id : extra) {
    replica_.erase(id);
    frontend_.removeLandmark(id);
  }
  if (!extra.empty()) {
    std::lock_guard<std::mutex> stats_lock(stats_mutex_);
    stats_.replica_removed += static_cast<int64_t>(extra.size());
  }
  revision_ = std::max(revision_, s.revision);
  if (!missing.empty()) requestSync(-1, std::move(missing));
}

void FrontendStage::resendPending() {
  std::lock_guard<std::mutex> lock(replica_mutex_);
  const Utime now = ctx_->clock.now();
  const Utime timeout = fromSeconds(params_.proposal_timeout_s);
  for (auto& [id, p] : pending_) {
    if (now - p.sent < timeout) continue;
    p.sent = now;
    ctx_->bus.publish(params_.proposal_channel, p.proposal);
    std::lock_guard<std::mutex> stats_lock(stats_mutex_);
    ++stats_.resent;
  }
}

void FrontendStage::prefetch(const std::string& channel, const void* data, size_t size) {
  // Frames of this camera a few events ahead, extracted in order on one
  // thread (one extractor, reused buffers). Features do not depend on the
  // thread that extracts them, so the replay's output does not either.
  // (The replay's look-ahead bounds how many are queued.)
  if (channel != camera().image_channel) return;
  auto msg = std::make_shared<vslam::image_t>();
  // Malformed: the bus's subscription reports it when the frame is delivered.
  if (!bus::checkedDecode(*msg, data, size, nullptr)) return;
  const std::pair<Utime, int64_t> frame{msg->utime, msg->seq};
  prefetched_.emplace_back(frame, prefetch_worker_.submit([this, msg] {
    PrefetchedFeatures out;
    if (checkImage(camera(), *msg) || imageToGray(*msg, &prefetch_gray_)) {
      return out;  // malformed: process() reports it
    }
    const Utime t0 = monotonicUtime();
    prefetch_extractor_.extract(prefetch_gray_, &out.features);
    out.sift_ms = msSince(t0);
    out.ok = true;
    return out;
  }));
}

void FrontendStage::process(vslam::image_t& msg) {
  // Features prefetched for this very frame, if any; prefetches of earlier
  // frames (ones that never came) are discarded.
  std::optional<PrefetchedFeatures> prefetched;
  const std::pair<Utime, int64_t> frame{msg.utime, msg.seq};
  while (!prefetched_.empty() && prefetched_.front().first <= frame) {
    if (prefetched_.front().first == frame)
      prefetched = prefetched_.front().second.get();
    else
      prefetched_.front().second.wait();
    prefetched_.pop_front();
  }
  const bool have_features = prefetched && prefetched->ok;
  if (!have_features) {
    auto error = checkImage(camera(), msg);
    if (!error) error = imageToGray(msg, &gray_);
    if (error) {
      ctx_->bus.reportMalformed(camera().image_channel, *error);
      return;
    }
  }
  if (params_.use_landmark_db) resendPending();
  frontend::Features features;
  double sift_ms = 0;
  if (have_features) {
    features = std::move(prefetched->features);
    sift_ms = prefetched->sift_ms;
  } else {
    const Utime t0 = monotonicUtime();
    frontend_.extract(gray_, &features);
    sift_ms = msSince(t0);
  }
  const size_t num_features = features.size();
  const bool gained = features.gain > 1.0;

  const frontend::FrameResult result = frontend_.track(msg.utime, std::move(features));
  if (result.view_jumped) {
    // Before the frame's measurements: the back-end knows of the jump when they come.
    vslam::view_jump_t jump{};
    jump.utime = msg.utime;
    jump.previous_utime = result.previous_utime;
    jump.camera = camera().name;
    jump.matched_share = result.matched_share;
    jump.max_matched_share = params_.frontend.view_jump_max_matched_share;
    jump.thumbnail_similarity = result.thumbnail_similarity;
    jump.min_thumbnail_similarity = params_.frontend.view_jump_min_thumbnail_similarity;
    ctx_->bus.publish(params_.view_jump_channel, jump);
    log::info("view jumped at ", msg.utime, ": thumbnails' similarity ",
              result.thumbnail_similarity, ", share of features found again ", result.matched_share,
              " (nan, -1: not tested)");
  }
  for (const auto& [landmark_id, pm] : result.measurements) {
    vslam::visual_measurement_t out{};
    out.utime = msg.utime;
    out.seq = measurement_seq_++;
    out.camera = camera().name;
    out.image_seq = msg.seq;
    out.landmark_id = landmark_id;
    out.dx = pm.relative.x;
    out.dy = pm.relative.y;
    out.dtheta = pm.relative.theta;
    out.proj_err_rms = pm.proj_err_rms_px;
    out.num_points = pm.num_points;
    out.slope = pm.slope;
    out.status = vslam::visual_measurement_t::STATUS_UNFILTERED;
    ctx_->bus.publish(params_.measurement_channel, out);
  }
  if (result.created) propose(*result.created);
  if (result.refined) revise(*result.refined);

  std::lock_guard<std::mutex> lock(stats_mutex_);
  ++stats_.frames;
  stats_.features += static_cast<int64_t>(num_features);
  stats_.recognitions += result.recognitions;
  stats_.measurements += static_cast<int64_t>(result.measurements.size());
  stats_.measurement_failures += result.measurement_failures;
  stats_.odometry_disagreements += result.odometry_disagreements;
  stats_.no_odometry += result.have_odometry ? 0 : 1;
  stats_.prefetched += have_features ? 1 : 0;
  stats_.gained += gained ? 1 : 0;
  stats_.created += result.created ? 1 : 0;
  stats_.creation_failures += result.creation_failure ? 1 : 0;
  stats_.sift_ms += sift_ms;
  stats_.recognition_ms += result.recognition_ms;
  stats_.measurement_ms += result.measurement_ms;
  stats_.creation_ms += result.creation_ms;
}

void FrontendStage::propose(const frontend::NewLandmark& created) {
  // With a DB: a proposal id unique to this run (the first frame's time plus
  // a counter), in the index as kFirstPendingId + n until the DB names the global id.
  if (proposal_base_ < 0) proposal_base_ = created.first_view.utime;
  const int64_t id = params_.use_landmark_db
                         ? proposal_base_ + next_landmark_++
                         : params_.camera_number * kIdsPerCamera + next_landmark_++;
  const int64_t index_id =
      params_.use_landmark_db ? frontend::kFirstPendingId + next_landmark_ : id;
  vslam::landmark_update_t proposal = makeProposal(created, id);
  {
    std::lock_guard<std::mutex> lock(replica_mutex_);
    frontend_.addLandmark(created.model(index_id));
    if (params_.use_landmark_db) pending_[id] = {proposal, ctx_->clock.now(), index_id};
    if (params_.frontend.refine_distance_m > 0) {
      refining_[created.first_view.utime] = {id, params_.use_landmark_db ? int64_t{-1} : id};
    }
  }
  ctx_->bus.publish(params_.proposal_channel, proposal);
}

void FrontendStage::revise(const frontend::FrameResult::Refined& refined) {
  int64_t proposal_id = -1, landmark_id = -1;
  {
    std::lock_guard<std::mutex> lock(replica_mutex_);
    const auto it = refining_.find(refined.landmark.first_view.utime);
    if (it == refining_.end()) return;
    proposal_id = it->second.proposal_id;
    landmark_id = it->second.landmark_id;
    refining_.erase(it);
    if (!refined.report.refined) return;
    {
      std::lock_guard<std::mutex> stats_lock(stats_mutex_);
      ++stats_.refined;
    }
    if (!params_.use_landmark_db) {
      // No DB to tell: this front-end's own copy is refined.
      frontend_.addLandmark(refined.landmark.model(landmark_id));
      return;
    }
  }
  if (landmark_id <= 0) {
    log::info("landmark proposal ", proposal_id,
              " refined before the landmark DB answered it: its structure stays as proposed");
    return;
  }
  // The DB stores the refined points and publishes them (OP_UPDATED with the
  // structure), which updates every replica, this one's too.
  vslam::landmark_update_t revision = makeProposal(refined.landmark, proposal_id);
  revision.op = vslam::landmark_update_t::OP_REVISED;
  revision.landmark.landmark_id = landmark_id;
  ctx_->bus.publish(params_.proposal_channel, revision);
  std::lock_guard<std::mutex> stats_lock(stats_mutex_);
  ++stats_.revisions_sent;
}

vslam::landmark_update_t FrontendStage::makeProposal(const frontend::NewLandmark& created,
                                                     int64_t id) const {
  const frontend::View& v1 = created.first_view;
  const frontend::CreatedLandmark& lm = created.landmark;
  vslam::landmark_update_t m{};
  m.utime = v1.utime;
  m.database_id = "";
  m.revision = 0;
  m.op = vslam::landmark_update_t::OP_PROPOSED;
  vslam::landmark_t& l = m.landmark;
  l.landmark_id = params_.use_landmark_db ? -1 : id;
  l.proposal_id = id;
  l.version = 0;
  l.camera = camera().name;
  l.created_utime = v1.utime;
  l.created_odom_x = v1.odometry.x;
  l.created_odom_y = v1.odometry.y;
  l.created_odom_theta = v1.odometry.theta;
  const size_t n = lm.points_robot.size();
  l.num_points = static_cast<int32_t>(n);
  l.descriptor_size = 128;
  l.points.assign(n, std::vector<float>(3));
  l.keypoints.assign(n, std::vector<float>(2));
  l.scales.resize(n);
  l.orientations.resize(n);
  l.descriptors.assign(n, std::vector<uint8_t>(128));
  for (size_t i = 0; i < n; ++i) {
    const int f = lm.feature_index[i];
    for (int k = 0; k < 3; ++k) l.points[i][k] = static_cast<float>(lm.points_robot[i][k]);
    l.keypoints[i][0] = static_cast<float>(v1.features.normalized[static_cast<size_t>(f)].x());
    l.keypoints[i][1] = static_cast<float>(v1.features.normalized[static_cast<size_t>(f)].y());
    l.scales[i] = v1.features.keypoints[static_cast<size_t>(f)].size;
    l.orientations[i] =
        static_cast<float>(v1.features.keypoints[static_cast<size_t>(f)].angle * M_PI / 180.0);
    const float* d = v1.features.descriptors.ptr<float>(f);
    for (int c = 0; c < 128; ++c) {
      l.descriptors[i][static_cast<size_t>(c)] =
          static_cast<uint8_t>(std::clamp(std::lround(d[c]), 0L, 255L));
    }
  }
  return m;
}

void FrontendStage::collectHealth(bus::HealthReport& report) {
  if (image_watchdog_) {
    image_watchdog_->report(ctx_->clock.now(), report);
    odometry_watchdog_->report(ctx_->clock.now(), report);
  }
  // The replica's state first, under its own lock alone: the LCM thread
  // takes replica_mutex_ before stats_mutex_, so this must not nest them the
  // other way round.
  size_t pending = 0, replica = 0;
  int64_t revision = -1;
  bool database_heard = false;
  {
    std::lock_guard<std::mutex> replica_lock(replica_mutex_);
    pending = pending_.size();
    replica = replica_.size();
    revision = revision_;
    database_heard = !database_id_.empty();
  }
  std::lock_guard<std::mutex> lock(stats_mutex_);
  const Stats d{stats_.frames - last_.frames,
                stats_.features - last_.features,
                stats_.recognitions - last_.recognitions,
                stats_.measurements - last_.measurements,
                stats_.measurement_failures - last_.measurement_failures,
                stats_.created - last_.created,
                stats_.creation_failures - last_.creation_failures,
                stats_.foreign_landmarks - last_.foreign_landmarks,
                stats_.no_odometry - last_.no_odometry,
                stats_.sift_ms - last_.sift_ms,
                stats_.recognition_ms - last_.recognition_ms,
                stats_.measurement_ms - last_.measurement_ms,
                stats_.creation_ms - last_.creation_ms,
                stats_.acknowledged - last_.acknowledged,
                stats_.rejected - last_.rejected,
                stats_.resent - last_.resent,
                stats_.sync_requests - last_.sync_requests,
                stats_.replica_added - last_.replica_added,
                stats_.replica_removed - last_.replica_removed};
  last_ = stats_;
  const double frames = std::max<double>(1.0, static_cast<double>(d.frames));
  report.add("frames_processed", static_cast<double>(d.frames), "count");
  report.add("features_per_frame", static_cast<double>(d.features) / frames, "");
  report.add("recognitions", static_cast<double>(d.recognitions), "count");
  report.add("measurements", static_cast<double>(d.measurements), "count");
  report.add("measurement_failures", static_cast<double>(d.measurement_failures), "count");
  report.add("landmarks_created", static_cast<double>(stats_.created), "count");
  report.add("landmarks_refined", static_cast<double>(stats_.refined), "count");
  report.add("measurements_against_odometry", static_cast<double>(stats_.odometry_disagreements),
             "count");
  report.add("landmark_revisions_sent", static_cast<double>(stats_.revisions_sent), "count");
  report.add("creation_failures", static_cast<double>(d.creation_failures), "count");
  report.add("sift_ms", d.sift_ms / frames, "ms");
  report.add("recognition_ms", d.recognition_ms / frames, "ms");
  report.add("measurement_ms", d.measurement_ms / frames, "ms");
  report.add("creation_ms", d.creation_ms / frames, "ms");
  report.add("landmarks_known", static_cast<double>(frontend_.numLandmarks()), "count");
  if (params_.use_landmark_db) {
    report.add("landmarks_pending", static_cast<double>(pending), "count");
    report.add("replica_landmarks", static_cast<double>(replica), "count");
    report.add("replica_revision", static_cast<double>(revision), "");
    if (!database_heard) report.warn("no landmark database heard yet");
  }
  if (params_.use_landmark_db) {
    report.add("proposals_acknowledged", static_cast<double>(stats_.acknowledged), "count");
    report.add("proposals_rejected", static_cast<double>(stats_.rejected), "count");
    report.add("proposals_resent", static_cast<double>(stats_.resent), "count");
    report.add("sync_requests", static_cast<double>(stats_.sync_requests), "count");
    report.add("replica_added", static_cast<double>(stats_.replica_added), "count");
    report.add("replica_removed", static_cast<double>(stats_.replica_removed), "count");
  }
  report.add("frames_dropped", static_cast<double>(worker_ ? worker_->dropped() : 0), "count");
  report.add("frames_repeated", static_cast<double>(repeated_images_.repeats()), "count");
  report.add("frames_prefetched", static_cast<double>(stats_.prefetched), "count");
  report.add("frames_gained", static_cast<double>(stats_.gained), "count");
  if (d.no_odometry > 0) report.warn("frames without odometry: no landmarks can be created");
}

void registerFrontend(bus::StageRegistry& registry) {
  registry.add(
      "frontend",
      [](const bus::StageSetup& setup) {
        return std::make_unique<FrontendStage>(
            FrontendStageParams::load(setup.params, setup.stack.robot, loadPrefilter(setup.stack)));
      },
      bus::describeWith(FrontendStageParams::table()));
}

}  // namespace vslam::stages
