#include "stages/backend_stage.hpp"

#include <vslam/landmark_update_t.hpp>
#include <vslam/map_t.hpp>
#include <vslam/particle_set_t.hpp>
#include <vslam/pose_estimate_t.hpp>

#include "landmark_db/landmark_store.hpp"
#include "stages/prefilter_config.hpp"
#include "util/log.hpp"

namespace vslam::stages {
namespace {

using backend::MeasurementStatus;
using backend::MeasurementUse;
using vslam::visual_measurement_t;

static_assert(static_cast<int>(MeasurementStatus::kUnfiltered) ==
              visual_measurement_t::STATUS_UNFILTERED);
static_assert(static_cast<int>(MeasurementStatus::kAccepted) ==
              visual_measurement_t::STATUS_ACCEPTED);
static_assert(static_cast<int>(MeasurementStatus::kRejectedProjErr) ==
              visual_measurement_t::STATUS_REJECTED_PROJ_ERR);
static_assert(static_cast<int>(MeasurementStatus::kRejectedNumPoints) ==
              visual_measurement_t::STATUS_REJECTED_NUM_POINTS);
static_assert(static_cast<int>(MeasurementStatus::kRejectedSlope) ==
              visual_measurement_t::STATUS_REJECTED_SLOPE);
static_assert(static_cast<int>(MeasurementStatus::kRejectedInvalid) ==
              visual_measurement_t::STATUS_REJECTED_INVALID);

Utime periodUs(double rate_hz) { return rate_hz > 0 ? static_cast<Utime>(1e6 / rate_hz) : 0; }

void copyCovariance(const Eigen::Matrix3d& c, double* out) {
  for (int r = 0; r < 3; ++r) {
    for (int k = 0; k < 3; ++k) out[r * 3 + k] = c(r, k);
  }
}

void loadMixture(const config::ConfigNode& mx, backend::MixtureParams& m) {
  using config::InRange;
  m.dual_ratio_min = mx.getDouble("dual_ratio_min", m.dual_ratio_min, InRange{0, 1});
  m.dual_ratio_max = mx.getDouble("dual_ratio_max", m.dual_ratio_max, InRange{0, 1});
  if (m.dual_ratio_max < m.dual_ratio_min)
    throw mx.error("dual_ratio_max", "must be at least dual_ratio_min");
  m.agreement_smoothing =
      mx.getDouble("agreement_smoothing", m.agreement_smoothing, InRange{1e-3, 1});
  m.motion_min_sigma_xy_m =
      mx.getDouble("motion_min_sigma_xy_m", m.motion_min_sigma_xy_m, InRange{1e-4, 100});
  m.motion_min_sigma_theta_rad = degToRad(mx.getDouble(
      "motion_min_sigma_theta_deg", radToDeg(m.motion_min_sigma_theta_rad), InRange{1e-3, 180}));
  mx.requireAllKeysUsed();
}

void loadOutlier(const config::ConfigNode& ol, backend::OutlierParams& o) {
  using config::InRange;
  o.probability = ol.getDouble("probability", o.probability, InRange{0, 0.999});
  o.area_m2 = ol.getDouble("area_m2", o.area_m2, InRange{1e-3, 1e9});
  o.gate_mahalanobis_sq =
      ol.getDouble("gate_mahalanobis_sq", o.gate_mahalanobis_sq, InRange{1e-3, 1e9});
  ol.requireAllKeysUsed();
}

void loadKidnap(const config::ConfigNode& kd, backend::KidnapParams& k) {
  using config::InRange;
  k.detect_agreement = kd.getDouble("detect_agreement", k.detect_agreement, InRange{0, 1});
  k.detect_count = static_cast<int>(kd.getInt("detect_count", k.detect_count, InRange{1, 1000}));
  k.recover_agreement = kd.getDouble("recover_agreement", k.recover_agreement, InRange{0, 1});
  k.recover_count = static_cast<int>(kd.getInt("recover_count", k.recover_count, InRange{1, 1000}));
  k.detect_landmarks =
      static_cast<int>(kd.getInt("detect_landmarks", k.detect_landmarks, InRange{1, 1000}));
  // The defaults are the struct's (backend/particle_filter.hpp).
  k.detect_min_span_s = kd.getDouble("detect_min_span_s", k.detect_min_span_s, InRange{0, 600});
  k.cluster_xy_m = kd.getDouble("cluster_xy_m", k.cluster_xy_m, InRange{1e-3, 100});
  k.cluster_theta_rad =
      degToRad(kd.getDouble("cluster_deg", radToDeg(k.cluster_theta_rad), InRange{1e-3, 180}));
  k.suspect_after = static_cast<int>(kd.getInt("suspect_after", k.suspect_after, InRange{0, 1000}));
  k.recover_landmarks =
      static_cast<int>(kd.getInt("recover_landmarks", k.recover_landmarks, InRange{1, 1000}));
  k.recover_window_s = kd.getDouble("recover_window_s", k.recover_window_s, InRange{0, 600});
  k.drift_gate_mahalanobis_sq =
      kd.getDouble("drift_gate_mahalanobis_sq", k.drift_gate_mahalanobis_sq, InRange{0, 1e6});
  k.drift_sigma_scale = kd.getDouble("drift_sigma_scale", k.drift_sigma_scale, InRange{1e-3, 1000});
  kd.requireAllKeysUsed();
}

void loadOdometryCalibration(const config::ConfigNode& oc, backend::OdometryCalibrationParams& c) {
  using config::InRange;
  // The defaults are the struct's (backend/odometry_calibration.hpp).
  c.enabled = oc.getBool("enabled", c.enabled);
  c.adopt = oc.getBool("adopt", c.adopt);
  c.min_travel = oc.getDouble("min_travel", c.min_travel, InRange{1e-3, 100});
  c.max_travel = oc.getDouble("max_travel", c.max_travel, InRange{1e-3, 1000});
  c.max_span_s = oc.getDouble("max_span_s", c.max_span_s, InRange{1e-3, 3600});
  c.max_residual_m = oc.getDouble("max_residual_m", c.max_residual_m, InRange{1e-3, 100});
  c.max_residual_rad =
      degToRad(oc.getDouble("max_residual_deg", radToDeg(c.max_residual_rad), InRange{1e-3, 180}));
  c.min_pairs = static_cast<int>(oc.getInt("min_pairs", c.min_pairs, InRange{3, 1e6}));
  c.max_pairs = static_cast<int>(oc.getInt("max_pairs", c.max_pairs, InRange{3, 1e7}));
  if (c.max_pairs < c.min_pairs) throw oc.error("max_pairs", "must be at least min_pairs");
  if (c.max_travel <= c.min_travel) throw oc.error("max_travel", "must exceed min_travel");
  oc.requireAllKeysUsed();
}

void loadMapCorrection(const config::ConfigNode& mc, backend::MapCorrectionParams& m,
                       const MotionNoise& motion) {
  using config::InRange;
  m.enabled = mc.getBool("enabled", m.enabled);
  m.solve_interval_s = mc.getDouble("solve_interval_s", m.solve_interval_s, InRange{0, 3600});
  m.max_outlier_fraction =
      mc.getDouble("max_outlier_fraction", m.max_outlier_fraction, InRange{0, 1});
  m.measurement_min_interval_s =
      mc.getDouble("measurement_min_interval_s", m.measurement_min_interval_s, InRange{0, 3600});
  m.creation_max_age_s =
      mc.getDouble("creation_max_age_s", m.creation_max_age_s, InRange{0.01, 3600});
  m.kidnap_jump_m = mc.getDouble("kidnap_jump_m", m.kidnap_jump_m, InRange{1e-3, 1000});
  m.kidnap_jump_rad =
      degToRad(mc.getDouble("kidnap_jump_deg", radToDeg(m.kidnap_jump_rad), InRange{1e-3, 180}));
  m.landmark_sigma_xy_m =
      mc.getDouble("landmark_sigma_xy_m", m.landmark_sigma_xy_m, InRange{1e-4, 10});
  m.landmark_sigma_theta_rad = degToRad(mc.getDouble(
      "landmark_sigma_theta_deg", radToDeg(m.landmark_sigma_theta_rad), InRange{1e-3, 90}));
  backend::PoseGraphParams& g = m.graph;
  // The odometry noise is the motion model's.
  g.sigma_translation = std::max(motion.sigma_translation, 1e-4);
  g.sigma_rotation = std::max(motion.sigma_rotation, 1e-4);
  g.measurement_sigma_xy_m =
      mc.getDouble("measurement_sigma_xy_m", g.measurement_sigma_xy_m, InRange{1e-4, 10});
  g.measurement_sigma_xy_per_m =
      mc.getDouble("measurement_sigma_xy_per_m", g.measurement_sigma_xy_per_m, InRange{0, 10});
  g.measurement_sigma_theta_rad = degToRad(mc.getDouble(
      "measurement_sigma_theta_deg", radToDeg(g.measurement_sigma_theta_rad), InRange{1e-3, 90}));
  g.measurement_sigma_theta_rad_per_m =
      degToRad(mc.getDouble("measurement_sigma_theta_deg_per_m",
                            radToDeg(g.measurement_sigma_theta_rad_per_m), InRange{0, 90}));
  g.max_measurement_distance_m =
      mc.getDouble("max_measurement_distance_m", g.max_measurement_distance_m, InRange{1e-3, 100});
  // The defaults of the robust loss are the struct's (backend/pose_graph.hpp).
  if (mc.has("robust_loss")) {
    g.robust_loss = mc.getEnum("robust_loss", {"huber", "cauchy"}) == "huber"
                        ? backend::PoseGraphParams::RobustLoss::kHuber
                        : backend::PoseGraphParams::RobustLoss::kCauchy;
  }
  g.robust_sigmas = mc.getDouble("robust_sigmas", g.robust_sigmas, InRange{0.1, 100});
  g.max_iterations =
      static_cast<int>(mc.getInt("max_iterations", g.max_iterations, InRange{1, 1000}));
  g.odometry_gate_mahalanobis_sq =
      mc.getDouble("odometry_gate_mahalanobis_sq", g.odometry_gate_mahalanobis_sq, InRange{0, 1e6});
  g.min_agreeing = static_cast<int>(mc.getInt("min_agreeing", g.min_agreeing, InRange{0, 1000}));
  g.segment_prior_sigma_xy_m =
      mc.getDouble("segment_prior_sigma_xy_m", g.segment_prior_sigma_xy_m, InRange{1e-3, 100});
  g.segment_prior_sigma_theta_rad =
      degToRad(mc.getDouble("segment_prior_sigma_theta_deg",
                            radToDeg(g.segment_prior_sigma_theta_rad), InRange{1e-3, 180}));
  mc.requireAllKeysUsed();
}

}  // namespace

BackendStageParams BackendStageParams::load(const config::ConfigNode& node,
                                            const config::RobotConfig& robot,
                                            const backend::PrefilterParams& prefilter) {
  using config::InRange;
  BackendStageParams p;
  backend::BackendParams& b = p.backend;
  backend::FilterParams& f = b.filter;
  f.num_particles =
      static_cast<int>(node.getInt("num_particles", f.num_particles, InRange{1, 1e6}));
  f.num_threads = static_cast<int>(node.getInt("threads", f.num_threads, InRange{0, 256}));
  f.seed =
      static_cast<uint64_t>(node.getInt("seed", static_cast<int64_t>(f.seed), InRange{0, 9.0e18}));
  f.motion.sigma_translation = node.getDouble("sigma_translation", config::nonNegative());
  f.motion.sigma_rotation = node.getDouble("sigma_rotation", config::nonNegative());
  f.measurement_sigma_xy_m =
      node.getDouble("measurement_sigma_xy_m", f.measurement_sigma_xy_m, InRange{1e-4, 10.0});
  f.measurement_sigma_theta_rad = degToRad(node.getDouble(
      "measurement_sigma_theta_deg", radToDeg(f.measurement_sigma_theta_rad), InRange{1e-3, 90.0}));
  f.resample_ess_fraction =
      node.getDouble("resample_ess_fraction", f.resample_ess_fraction, InRange{0.0, 1.0});
  b.max_step_m = node.getDouble("max_step_m", b.max_step_m, config::positive());
  b.max_step_rad =
      degToRad(node.getDouble("max_step_deg", radToDeg(b.max_step_rad), InRange{1, 180}));
  b.max_measurement_age_s =
      node.getDouble("max_measurement_age_s", b.max_measurement_age_s, InRange{0.01, 600});
  b.max_measurement_lead_s =
      node.getDouble("max_measurement_lead_s", b.max_measurement_lead_s, InRange{0, 60});
  b.measurement_sigma_xy_per_m =
      node.getDouble("measurement_sigma_xy_per_m", b.measurement_sigma_xy_per_m, InRange{0, 10.0});
  b.measurement_sigma_theta_rad_per_m =
      degToRad(node.getDouble("measurement_sigma_theta_deg_per_m",
                              radToDeg(b.measurement_sigma_theta_rad_per_m), InRange{0, 90.0}));
  b.landmark_min_interval_s =
      node.getDouble("landmark_min_interval_s", b.landmark_min_interval_s, InRange{0, 60});
  if (node.has("map_prior_file") && !node.getString("map_prior_file", true).empty())
    p.map_prior_file = node.getPath("map_prior_file", true);
  p.map_prior_sigma_xy_m =
      node.getDouble("map_prior_sigma_xy_m", p.map_prior_sigma_xy_m, InRange{1e-4, 10.0});
  p.map_prior_sigma_theta_rad = degToRad(node.getDouble(
      "map_prior_sigma_theta_deg", radToDeg(p.map_prior_sigma_theta_rad), InRange{1e-3, 90.0}));
  const std::string start = node.getString("map_prior_start", "origin");
  if (start != "origin" && start != "unknown")
    throw node.error("map_prior_start", "expected origin or unknown, not '" + start + "'");
  p.map_prior_unknown_start = start == "unknown";
  p.map_rate_hz = node.getDouble("map_rate_hz", p.map_rate_hz, InRange{0, 100});
  p.particles_rate_hz = node.getDouble("particles_rate_hz", p.particles_rate_hz, InRange{0, 100});
  p.odometry_timeout_s =
      node.getDouble("odometry_timeout_s", p.odometry_timeout_s, InRange{0.05, 3600});

  rejectInstancePrefilter(node);
  b.prefilter = prefilter;
  if (node.has("mixture")) loadMixture(node.child("mixture"), f.mixture);
  if (node.has("outlier")) loadOutlier(node.child("outlier"), f.outlier);
  if (node.has("kidnap")) loadKidnap(node.child("kidnap"), f.kidnap);
  if (node.has("odometry_calibration"))
    loadOdometryCalibration(node.child("odometry_calibration"), b.odometry_calibration);
  if (node.has("map_correction"))
    loadMapCorrection(node.child("map_correction"), b.map_correction, f.motion);
  p.odometry_channel = robot.channels.odometry;
  p.landmark_update_channel = robot.channels.landmark_update;
  p.landmark_proposal_channel = robot.channels.landmark_proposal;
  p.measurement_channel = robot.channels.visual_measurement;
  p.filtered_channel = robot.channels.visual_measurement_filtered;
  p.pose_channel = robot.channels.pose_estimate;
  p.map_channel = robot.channels.map;
  p.particles_channel = robot.channels.particles;
  try {
    b.validate();
  } catch (const std::invalid_argument& e) {
    throw node.error("num_particles", e.what());
  }
  return p;
}

BackendStage::BackendStage(BackendStageParams params)
    : params_(std::move(params)), backend_(params_.backend) {
  if (!params_.map_prior_file.empty()) loadMapPrior();
}

void BackendStage::loadMapPrior() {
  landmark_db::StoreOptions options;
  options.create_if_missing = false;
  options.read_only = true;
  // Throws MapFileError naming the file: a map that cannot be read is a
  // configuration error, not an empty map.
  landmark_db::LandmarkStore store(params_.map_prior_file, options);
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  covariance(0, 0) = covariance(1, 1) = params_.map_prior_sigma_xy_m * params_.map_prior_sigma_xy_m;
  covariance(2, 2) = params_.map_prior_sigma_theta_rad * params_.map_prior_sigma_theta_rad;
  std::vector<backend::ParticleFilter::KnownLandmark> known;
  size_t without_pose = 0;
  for (const landmark_db::LandmarkInfo& info : store.loadAllInfo()) {
    // Only poses the back-end estimated are in the map frame; a creation
    // odometry pose is in its run's odometry frame.
    if (info.pose_source != landmark_db::PoseSource::kMap) {
      ++without_pose;
      continue;
    }
    backend::LandmarkEstimate e;
    e.mean = {info.map_pose.x, info.map_pose.y, info.map_pose.theta};
    e.covariance = covariance;
    e.num_observations = std::max(1, info.stats.num_accepted);
    known.push_back({info.id, e});
  }
  backend_.filter().loadMap(known);
  prior_landmarks_ = known.size();
  if (params_.map_prior_unknown_start && !known.empty()) backend_.filter().startKidnapped();
  params_.database_id = store.databaseId();
  if (known.empty()) {
    log::warn("map prior ", params_.map_prior_file.string(),
              ": no landmark has a back-end pose; starting with an empty map");
  } else {
    log::info(
        "map prior ", params_.map_prior_file.string(), ": ", known.size(), " landmarks (database ",
        store.databaseId(), ")",
        without_pose > 0 ? ", " + std::to_string(without_pose) + " without a pose skipped" : "");
  }
}

std::vector<std::string> BackendStage::outputChannels() const {
  return {params_.filtered_channel, params_.pose_channel, params_.map_channel,
          params_.particles_channel};
}

void BackendStage::start(bus::StageContext& ctx) {
  ctx_ = &ctx;
  started_clock_ = ctx.clock.now();  // 0 in a replay before its first event
  ctx.bus.subscribe<vslam::odometry_t>(params_.odometry_channel,
                                       [this](const vslam::odometry_t& m) { onOdometry(m); });
  // Several front-ends publish here; a burst of a frame's measurements from
  // each camera must not overflow the queue.
  ctx.bus.subscribe<visual_measurement_t>(
      params_.measurement_channel, [this](const visual_measurement_t& m) { onMeasurement(m); },
      100);
  if (params_.backend.map_correction.enabled) {
    // Map correction needs each landmark's creation time: from the landmark
    // DB's announcements, or, from front-ends that run without a DB, from
    // their proposals, which then carry the landmark's id.
    ctx.bus.subscribe<vslam::landmark_update_t>(
        params_.landmark_update_channel,
        [this](const vslam::landmark_update_t& m) { onLandmarkUpdate(m); }, 100);
    ctx.bus.subscribe<vslam::landmark_update_t>(
        params_.landmark_proposal_channel,
        [this](const vslam::landmark_update_t& m) { onLandmarkUpdate(m); }, 100);
  }
}

void BackendStage::onLandmarkUpdate(const vslam::landmark_update_t& msg) {
  using U = vslam::landmark_update_t;
  const bool announces = msg.op == U::OP_CREATED || msg.op == U::OP_LOADED ||
                         msg.op == U::OP_SNAPSHOT ||
                         (msg.op == U::OP_PROPOSED && msg.landmark.landmark_id >= 0);
  if (!announces || msg.landmark.landmark_id < 0) return;
  backend_.addLandmarkCreation(msg.landmark.landmark_id, msg.landmark.created_utime);
}

template <class... Args>
void BackendStage::logLimited(LogReason reason, const Args&... args) {
  warnings_.warn(reason, ctx_->clock.now(), args...);
}

void BackendStage::onOdometry(const vslam::odometry_t& msg) {
  const Utime now = ctx_->clock.now();
  const Utime before = last_odometry_clock_.exchange(now);
  if (odometry_quiet_logged_.exchange(false)) {
    log::info("odometry back on ", params_.odometry_channel, " after ", toSeconds(now - before),
              " s without");
  }
  using Outcome = OdometryIncrements::Outcome;
  const Outcome outcome = backend_.addOdometry({msg.utime, msg.seq, {msg.x, msg.y, msg.theta}});
  switch (outcome) {
    case Outcome::kStep:
    case Outcome::kFirst:
      break;
    case Outcome::kInvalid:
      ctx_->bus.reportMalformed(
          params_.odometry_channel,
          "odometry seq " + std::to_string(msg.seq) + " has a non-finite pose");
      return;
    case Outcome::kStale:
      ctx_->bus.countDropped();
      return;
    case Outcome::kReset:
    case Outcome::kImplausible:
      logLimited(kLogOdometry, "odometry seq ", msg.seq, ": ",
                 OdometryIncrements::describe(outcome));
      break;
  }
  publishPose(msg);
  if (params_.map_rate_hz > 0 && msg.utime >= next_map_) {
    publishMap(msg.utime);
    next_map_ = msg.utime + periodUs(params_.map_rate_hz);
  }
  if (params_.particles_rate_hz > 0 && msg.utime >= next_particles_) {
    publishParticles(msg.utime);
    next_particles_ = msg.utime + periodUs(params_.particles_rate_hz);
  }
}

void BackendStage::onMeasurement(const visual_measurement_t& msg) {
  backend::MeasurementInput in;
  in.utime = msg.utime;
  in.landmark_id = msg.landmark_id;
  in.relative = {msg.dx, msg.dy, msg.dtheta};
  in.proj_err_rms_px = msg.proj_err_rms;
  in.num_points = msg.num_points;
  in.slope = msg.slope;
  const Utime t0 = monotonicUtime();
  const backend::MeasurementResult r = backend_.addMeasurement(in);
  const double ms = 1e-3 * static_cast<double>(monotonicUtime() - t0);

  visual_measurement_t out = msg;
  out.status = static_cast<int8_t>(r.status);
  ctx_->bus.publish(params_.filtered_channel, out);

  switch (r.use) {
    case MeasurementUse::kUsed:
      ++period_updates_;
      period_update_ms_ += ms;
      period_max_update_ms_ = std::max(period_max_update_ms_, ms);
      log::debug("update t ", msg.utime, " ", msg.camera, " landmark ", msg.landmark_id, " ",
                 backend::toString(r.update.kind), " agreement ", r.update.agreement, " smoothed ",
                 r.update.smoothed_agreement, " dual ", r.update.num_dual, " outliers ",
                 r.update.num_outliers, " ess ", r.update.ess,
                 r.update.suspect ? " look-alike" : "");
      if (r.update.evidence) {
        const Pose2& j = r.update.jump;
        log::info("evidence of a pose ", std::hypot(j.x, j.y), " m, ", radToDeg(j.theta),
                  " deg from the estimate at t ", msg.utime, " (Mahalanobis^2 ",
                  r.update.jump_mahalanobis_sq, " under the drift covariance): ",
                  r.update.drift_corrected ? "drift, the particles moved onto it" : "kidnapping");
      }
      if (r.update.kidnap_detected) {
        log::warn("kidnapping detected at t ", msg.utime, ", measurement ", msg.seq, " of ",
                  msg.camera, " (landmark ", msg.landmark_id, ", agreement ", r.update.agreement,
                  "): sampling all particles from the measurements");
      }
      if (r.update.recovered) {
        log::info("relocalized at t ", msg.utime, ", measurement ", msg.seq, " of ", msg.camera,
                  " (landmark ", msg.landmark_id, ", agreement ", r.update.agreement, ")");
      }
      break;
    case MeasurementUse::kRejected:
      if (r.status == MeasurementStatus::kRejectedInvalid) {
        ctx_->bus.reportMalformed(params_.measurement_channel,
                                  "measurement seq " + std::to_string(msg.seq) + " of " +
                                      msg.camera + " has non-finite or negative fields");
      }
      break;
    case MeasurementUse::kThinned:
    case MeasurementUse::kRetired:
      break;
    case MeasurementUse::kInvalidLandmark:
      logLimited(kLogLandmark, "measurement seq ", msg.seq, " of ", msg.camera,
                 ": invalid landmark id ", msg.landmark_id, "; not used");
      ctx_->bus.countDropped();
      break;
    case MeasurementUse::kNoOdometry:
    case MeasurementUse::kTooOld:
    case MeasurementUse::kTooNew: {
      const auto& last = backend_.lastOdometry();
      logLimited(kLogTiming, "measurement seq ", msg.seq, " of ", msg.camera, " at ", msg.utime,
                 ": ", backend::toString(r.use), " (newest odometry ", last ? last->utime : 0,
                 "); not used");
      ctx_->bus.countDropped();
      break;
    }
  }
}

void BackendStage::logOdometryCalibration(const backend::OdometryNoiseEstimate& n) {
  // Every kCalibrationLogPairs new pairs: what the measurements say of the odometry.
  constexpr int kCalibrationLogPairs = 100;
  if (!n.valid || n.pairs < calibration_logged_pairs_ + kCalibrationLogPairs) return;
  calibration_logged_pairs_ = n.pairs;
  log::info("odometry calibration (", n.pairs, " pairs): sigma_translation ", n.sigma_translation,
            " m/sqrt(m), sigma_rotation ", n.sigma_rotation, " rad/sqrt(m+rad), scale_bias ",
            n.scale_bias, ", heading_bias ", n.heading_bias, " rad/m; motion model ",
            backend_.filter().params().motion.sigma_translation, ", ",
            backend_.filter().params().motion.sigma_rotation);
}

void BackendStage::publishPose(const vslam::odometry_t& msg) {
  const backend::PoseEstimate e = backend_.filter().estimate();
  vslam::pose_estimate_t out;
  out.utime = msg.utime;
  out.seq = pose_seq_++;
  out.estimator = ctx_->instance;
  out.x = e.mean.x;
  out.y = e.mean.y;
  out.theta = e.mean.theta;
  copyCovariance(e.covariance, out.covariance);
  out.odom_x = msg.x;
  out.odom_y = msg.y;
  out.odom_theta = msg.theta;
  out.num_particles = static_cast<int32_t>(backend_.filter().particles().size());
  out.effective_sample_size = e.ess;
  out.kidnapped = e.kidnapped;
  ctx_->bus.publish(params_.pose_channel, out);
}

void BackendStage::publishMap(Utime utime) {
  const backend::ParticleFilter& pf = backend_.filter();
  const backend::Particle& best = pf.particles()[pf.bestParticle()];
  vslam::map_t out;
  out.utime = utime;
  out.seq = map_seq_++;
  out.estimator = ctx_->instance;
  out.database_id = params_.database_id;
  best.map.forEach([&](uint32_t slot, const backend::LandmarkEstimate& lm) {
    vslam::landmark_pose_t l;
    l.landmark_id = pf.landmarkId(slot);
    l.x = lm.mean.x();
    l.y = lm.mean.y();
    l.theta = lm.mean.z();
    copyCovariance(lm.covariance, l.covariance);
    l.num_observations = lm.num_observations;
    out.landmarks.push_back(l);
  });
  out.num_landmarks = static_cast<int32_t>(out.landmarks.size());
  ctx_->bus.publish(params_.map_channel, out);
}

void BackendStage::publishParticles(Utime utime) {
  const backend::ParticleFilter& pf = backend_.filter();
  const std::vector<double> w = pf.normalizedWeights();
  vslam::particle_set_t out;
  out.utime = utime;
  out.seq = particles_seq_++;
  out.estimator = ctx_->instance;
  double s2 = 0;
  out.particles.reserve(w.size());
  for (size_t i = 0; i < w.size(); ++i) {
    const backend::Particle& p = pf.particles()[i];
    vslam::particle_t q;
    q.x = p.pose.x;
    q.y = p.pose.y;
    q.theta = p.pose.theta;
    q.weight = w[i];
    q.kind = p.dual ? vslam::particle_t::KIND_DUAL : vslam::particle_t::KIND_NOMINAL;
    out.particles.push_back(q);
    s2 += w[i] * w[i];
  }
  out.effective_sample_size = 1.0 / s2;
  out.dual_ratio = pf.lastDualRatio();
  out.num_particles = static_cast<int32_t>(out.particles.size());
  ctx_->bus.publish(params_.particles_channel, out);
}

void BackendStage::checkOdometryQuiet(bus::HealthReport& report) {
  const Utime now = ctx_->clock.now();
  if (started_clock_ <= 0) started_clock_ = now;
  const Utime last = last_odometry_clock_.load();
  const Utime since = last > 0 ? last : started_clock_;
  const double quiet_s = toSeconds(now - since);
  report.add("odometry_age_s", quiet_s, "s");
  if (quiet_s <= params_.odometry_timeout_s) return;
  const std::string why = (last > 0 ? "no odometry on " : "no odometry yet on ") +
                          params_.odometry_channel + " for " + std::to_string(quiet_s) +
                          " s: the pose does not move with the robot";
  report.warn(why);
  if (!odometry_quiet_logged_.exchange(true)) log::warn(why);
}

void BackendStage::collectHealth(bus::HealthReport& report) {
  const backend::BackendCounters& c = backend_.counters();
  for (int s = static_cast<int>(MeasurementStatus::kAccepted); s < backend::kNumMeasurementStatus;
       ++s) {
    report.add(
        std::string("measurements_") + backend::metricName(static_cast<MeasurementStatus>(s)),
        static_cast<double>(c.status[s]), "count");
  }
  report.add("measurements_used",
             static_cast<double>(c.use[static_cast<int>(MeasurementUse::kUsed)]), "count");
  report.add("measurements_unused_landmark_id",
             static_cast<double>(c.use[static_cast<int>(MeasurementUse::kInvalidLandmark)]),
             "count");
  report.add("measurements_unused_timing",
             static_cast<double>(c.use[static_cast<int>(MeasurementUse::kNoOdometry)] +
                                 c.use[static_cast<int>(MeasurementUse::kTooOld)] +
                                 c.use[static_cast<int>(MeasurementUse::kTooNew)]),
             "count");
  report.add("measurements_thinned",
             static_cast<double>(c.use[static_cast<int>(MeasurementUse::kThinned)]), "count");
  report.add("measurements_unused_retired",
             static_cast<double>(c.use[static_cast<int>(MeasurementUse::kRetired)]), "count");
  report.add("landmarks", static_cast<double>(backend_.filter().numLandmarks()), "count");
  report.add("particles", static_cast<double>(backend_.filter().particles().size()), "count");
  const backend::PoseEstimate e = backend_.filter().estimate();
  report.add("effective_sample_size", e.ess, "count");
  report.add("dual_ratio", backend_.filter().lastDualRatio());
  report.add("kidnapped", e.kidnapped ? 1.0 : 0.0);
  report.add("kidnaps_detected", static_cast<double>(c.kidnaps_detected), "count");
  report.add("recoveries", static_cast<double>(c.recoveries), "count");
  report.add("drift_corrections", static_cast<double>(c.drift_corrections), "count");
  report.add("landmarks_mapped_after_relocalization",
             static_cast<double>(c.landmarks_mapped_after_relocalization), "count");
  report.add("resamplings", static_cast<double>(c.resamplings), "count");
  report.add("odometry_ignored", static_cast<double>(c.odometry_ignored), "count");
  report.add("position_sigma", std::sqrt(e.covariance(0, 0) + e.covariance(1, 1)), "m");
  if (params_.backend.odometry_calibration.enabled) {
    // The odometry as the measurements see it, and the motion model in use.
    const backend::OdometryNoiseEstimate n = backend_.odometryNoise();
    logOdometryCalibration(n);
    report.add("odometry_calibration_pairs", n.pairs, "count");
    if (n.valid) {
      report.add("odometry_sigma_translation_est", n.sigma_translation, "m/sqrt(m)");
      report.add("odometry_sigma_rotation_est", n.sigma_rotation, "rad/sqrt(m+rad)");
      report.add("odometry_scale_bias_est", n.scale_bias);
      report.add("odometry_heading_bias_est", n.heading_bias, "rad/m");
    }
    report.add("motion_sigma_translation", backend_.filter().params().motion.sigma_translation,
               "m/sqrt(m)");
    report.add("motion_sigma_rotation", backend_.filter().params().motion.sigma_rotation,
               "rad/sqrt(m+rad)");
  }
  report.add("updates", static_cast<double>(period_updates_), "count");
  report.add("update_ms_mean",
             period_updates_ > 0 ? period_update_ms_ / static_cast<double>(period_updates_) : 0.0,
             "ms");
  report.add("update_ms_max", period_max_update_ms_, "ms");
  if (const backend::PoseGraph* g = backend_.poseGraph()) {
    report.add("graph_nodes", static_cast<double>(g->numNodes()), "count");
    report.add("graph_landmarks", static_cast<double>(c.landmarks_in_graph), "count");
    report.add("graph_landmark_creations_unused", static_cast<double>(c.landmark_creations_unused),
               "count");
    report.add("graph_landmarks_distrusted", static_cast<double>(g->numDistrustedLandmarks()),
               "count");
    report.add("graph_measurements", static_cast<double>(c.graph_measurements), "count");
    report.add("graph_solves", static_cast<double>(c.graph_solves), "count");
    report.add("graph_solve_failures", static_cast<double>(c.graph_solve_failures), "count");
    report.add("graph_odometry_breaks", static_cast<double>(c.graph_odometry_breaks), "count");
    report.add("graph_solve_ms", c.graph_last_solve_ms, "ms");
  }
  if (e.kidnapped) report.warn("kidnapping suspected: relocalizing from visual measurements");
  checkOdometryQuiet(report);
  period_updates_ = 0;
  period_update_ms_ = 0;
  period_max_update_ms_ = 0;
}

void registerBackend(bus::StageRegistry& registry) {
  registry.add("backend", [](const bus::StageSetup& setup) {
    return std::make_unique<BackendStage>(
        BackendStageParams::load(setup.params, setup.stack.robot, loadPrefilter(setup.stack)));
  });
}

}  // namespace vslam::stages
