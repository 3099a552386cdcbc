#include "stages/backend_stage.hpp"

#include <vslam/landmark_update_t.hpp>
#include <vslam/map_t.hpp>
#include <vslam/particle_set_t.hpp>
#include <vslam/pose_estimate_t.hpp>

#include "landmark_db/landmark_store.hpp"
#include "stages/landmark_db_stage.hpp"
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

using config::InRange;
using config::ParamTable;

ParamTable<backend::MixtureParams> mixtureTable() {
  using M = backend::MixtureParams;
  ParamTable<M> t;
  t.add("dual_ratio_min", &M::dual_ratio_min, InRange{0, 1}, "",
        "dual fraction while measurements agree")
      .add("dual_ratio_max", &M::dual_ratio_max, InRange{0, 1}, "",
           "dual fraction approached as the agreement falls")
      .add("agreement_smoothing", &M::agreement_smoothing, InRange{1e-3, 1}, "",
           "weight of the newest measurement in the running agreement")
      .add("motion_min_sigma_xy_m", &M::motion_min_sigma_xy_m, InRange{1e-4, 100}, "m",
           "floor of the motion density that weighs particles")
      .degrees("motion_min_sigma_theta_deg", &M::motion_min_sigma_theta_rad, InRange{1e-3, 180},
               "same for θ")
      .check([](const config::ConfigNode& node, const M& m) {
        if (m.dual_ratio_max < m.dual_ratio_min)
          throw node.error("dual_ratio_max", "must be at least dual_ratio_min");
      });
  return t;
}

ParamTable<backend::OutlierParams> outlierTable() {
  using O = backend::OutlierParams;
  ParamTable<O> t;
  t.add("probability", &O::probability, InRange{0, 0.999}, "",
        "ε of the robust likelihood (0: Gaussian, no gate)")
      .add("area_m2", &O::area_m2, InRange{1e-3, 1e9}, "m²",
           "support of the uniform outlier density")
      .add("gate_mahalanobis_sq", &O::gate_mahalanobis_sq, InRange{1e-3, 1e9}, "",
           "larger innovations do not update the particle's landmark filter");
  return t;
}

ParamTable<backend::KidnapParams> kidnapTable() {
  using K = backend::KidnapParams;
  ParamTable<K> t;
  t.add("detect_agreement", &K::detect_agreement, InRange{0, 1}, "",
        "a measurement agreeing less is \"inconsistent\"")
      .add("detect_count", &K::detect_count, InRange{1, 1000}, "",
           "inconsistent measurements in a row that declare a kidnapping")
      .add("recover_agreement", &K::recover_agreement, InRange{0, 1}, "",
           "while kidnapped, a measurement agreeing at least this much is \"consistent\"")
      .add("recover_count", &K::recover_count, InRange{1, 1000}, "",
           "consistent measurements in a row that end it")
      .add("detect_landmarks", &K::detect_landmarks, InRange{1, 1000}, "",
           "...from at least this many distinct landmarks (that agree on one pose, below)")
      .add("detect_min_span_s", &K::detect_min_span_s, InRange{0, 600}, "s",
           "...and the inconsistent run must last this long (measurement capture times)")
      .add("cluster_xy_m", &K::cluster_xy_m, InRange{1e-3, 100}, "m",
           "`detect_landmarks` must agree on one robot pose (each measurement's implied pose, "
           "carried to now by the odometry) within this distance...")
      .degrees("cluster_deg", &K::cluster_theta_rad, InRange{1e-3, 180}, "...and this angle")
      .add("suspect_after", &K::suspect_after, InRange{0, 1000}, "",
           "a landmark in this many contradicted runs (ended by a consistent measurement), and in "
           "at least half as many as its consistent measurements, is a look-alike: no kidnap "
           "evidence, no dual particles, ignored while kidnapped, and unless consistent "
           "(`recover_agreement`) weighs no particle; 0: never")
      .add("recover_landmarks", &K::recover_landmarks, InRange{1, 1000}, "",
           "consistent measurements that end a kidnapping come from at least this many distinct "
           "landmarks")
      .add("recover_window_s", &K::recover_window_s, InRange{0, 600}, "s",
           "also confirmed when `recover_landmarks` distinct landmarks measured within this "
           "window agree on one pose (`cluster_*`), the newest among them; 0: off")
      .add("drift_gate_mahalanobis_sq", &K::drift_gate_mahalanobis_sq, InRange{0, 1e6}, "",
           "evidence of a pose within this squared Mahalanobis distance of the estimate is drift: "
           "the particles move towards it (fused by the two covariances), no kidnapping; 0: every "
           "such evidence is a kidnapping")
      .add("drift_sigma_scale", &K::drift_sigma_scale, InRange{1e-3, 1000}, "",
           "...under this scale² × the particles' covariance + the evidence's own (its "
           "landmarks' and measurements' covariance)")
      .add("detect_dissent_ratio", &K::detect_dissent_ratio, InRange{0, 1000}, "",
           "evidence beyond the drift gate, away from a view jump, declares a kidnapping only if "
           "the run's landmarks that put the robot elsewhere are fewer than this x those that "
           "agree on it (a busy repeated pattern scatters its look-alikes); 0: off")
      .add("cancel_count", &K::cancel_count, InRange{0, 1000}, "",
           "while kidnapped, this many measurements that agree with the particles as they were "
           "when it was declared (carried by the odometry) cancel it: look-alikes declared it; "
           "0: never")
      .add("retest_margin_s", &K::retest_margin_s, InRange{-1, 600}, "s",
           "after a relocalization, landmarks placed from this long before the first "
           "measurement of where the robot was moved to are re-tested: kept, or moved with the "
           "relocalization, as their next measurement agrees; < 0: off")
      .add("view_jump_window_s", &K::view_jump_window_s, InRange{0, 600}, "s",
           "for this long after a front-end's view jumped (carried, kidnapped), landmarks placed "
           "since the jump do not end a run of inconsistent measurements (they agree with the "
           "pose the robot was thought to be at by construction), and a kidnapping declared is "
           "known to be real: relocalized with every measurement, not cancelled by landmarks "
           "placed since it began; for as long after a moved robot's relocalization, landmarks "
           "that disagree with it are not taken for look-alikes; 0: view jumps are ignored")
      .add("unchecked_jump_window_s", &K::unchecked_jump_window_s, InRange{0, 600}, "s",
           "while no landmark placed before a view jump has agreed with the particles since it "
           "(the robot carried into a part of the home it has not mapped), the jump's window "
           "lasts up to this long, and landmarks recognised at more than one place meanwhile "
           "still count toward a kidnapping; 0: view_jump_window_s alone")
      .add("moved_evidence_s", &K::moved_evidence_s, InRange{0, 600}, "s",
           "for this long after a front-end's view jumped, inconsistent measurements the "
           "back-end thins (`landmark_min_interval_s`) still count toward a kidnapping, and a "
           "run begun in it needs no `detect_min_span_s`; so also while no landmark placed "
           "before the jump has agreed since (`unchecked_jump_window_s`); 0: off")
      .add("declare_on_every_view_jump", &K::declare_on_every_view_jump,
           "a view jump of every camera at once (two at least, within 0.15 s; cameras heard from "
           "in the last 10 s, none of which jumped in the `view_jump_window_s` before) declares "
           "a kidnapping then: the robot was moved (needs "
           "`view_jump_window_s`); false: landmarks must show it");
  return t;
}

ParamTable<backend::OdometryCalibrationParams> odometryCalibrationTable() {
  using C = backend::OdometryCalibrationParams;
  ParamTable<C> t;
  t.add("enabled", &C::enabled,
        "estimate the odometry's noise and biases from the measurements (health, log)")
      .add("adopt", &C::adopt,
           "the motion model and the graph's odometry edges take the estimated sigmas")
      .add("min_travel", &C::min_travel, InRange{1e-3, 100}, "m + rad", "a pair's shortest span")
      .add("max_travel", &C::max_travel, InRange{1e-3, 1000}, "m + rad", "a pair's longest span")
      .add("max_span_s", &C::max_span_s, InRange{1e-3, 3600}, "s", "a pair's longest time span")
      .add("max_residual_m", &C::max_residual_m, InRange{1e-3, 100}, "m",
           "larger residuals are not odometry noise")
      .degrees("max_residual_deg", &C::max_residual_rad, InRange{1e-3, 180}, "same for θ")
      .add("min_pairs", &C::min_pairs, InRange{3, 1e6}, "", "pairs before an estimate is valid")
      .add("max_pairs", &C::max_pairs, InRange{3, 1e7}, "", "window of the newest pairs")
      .check([](const config::ConfigNode& node, const C& c) {
        if (c.max_pairs < c.min_pairs) throw node.error("max_pairs", "must be at least min_pairs");
        if (c.max_travel <= c.min_travel) throw node.error("max_travel", "must exceed min_travel");
      });
  return t;
}

ParamTable<backend::MapCorrectionParams> mapCorrectionTable() {
  using M = backend::MapCorrectionParams;
  using Loss = backend::PoseGraphParams::RobustLoss;
  ParamTable<M> t;
  t.add("enabled", &M::enabled, "the pose graph of docs/backend.md, Map correction")
      .add("solve_interval_s", &M::solve_interval_s, InRange{0, 3600}, "s",
           "robot time between solves (each needs a new measurement in the graph)")
      .add("solve_in_background", &M::solve_in_background,
           "solve on a worker thread, the result taken solve_result_after_s later (repeatable); "
           "false: on the update that triggers it")
      .add("solve_result_after_s", &M::solve_result_after_s, InRange{0, 3600}, "s",
           "in the background: the filter takes a solve's result at the first measurement this "
           "long after the solve began (waiting for it if need be)")
      .add("max_outlier_fraction", &M::max_outlier_fraction, InRange{0, 1}, "",
           "a measurement enters if at most this fraction of the particles gates it out")
      .add("measurement_min_interval_s", &M::measurement_min_interval_s, InRange{0, 3600}, "s",
           "at most one measurement per landmark per interval into the graph")
      .add("creation_max_age_s", &M::creation_max_age_s, InRange{0.01, 3600}, "s",
           "odometry kept to place creation nodes; must exceed the front-ends' view span (20 s) "
           "plus the DB's round trip")
      .add("kidnap_jump_m", &M::kidnap_jump_m, InRange{1e-3, 1000}, "m",
           "a relocalization this far from the odometry's prediction breaks the graph's odometry "
           "chain")
      .degrees("kidnap_jump_deg", &M::kidnap_jump_rad, InRange{1e-3, 180}, "...or this far turned")
      .add("kidnap_jump_mahalanobis_sq", &M::kidnap_jump_mahalanobis_sq, InRange{0, 1e6}, "",
           "...or beyond this squared Mahalanobis distance under the odometry's noise over the "
           "path since the map last pinned the robot (a wheel slip); 0: no test")
      .add("landmark_sigma_xy_m", &M::landmark_sigma_xy_m, InRange{1e-4, 10}, "m",
           "covariance of the filter's landmarks after a correction, x and y")
      .degrees("landmark_sigma_theta_deg", &M::landmark_sigma_theta_rad, InRange{1e-3, 90},
               "...and θ")
      .add(
          "measurement_sigma_xy_m", [](auto& m) -> auto& { return m.graph.measurement_sigma_xy_m; },
          InRange{1e-4, 10}, "m",
          "σ(d) = hypot(σ₀, k d) of a measurement edge, d its distance from the creation pose: σ₀")
      .add(
          "measurement_sigma_xy_per_m",
          [](auto& m) -> auto& { return m.graph.measurement_sigma_xy_per_m; }, InRange{0, 10},
          "m/m", "...k")
      .degrees(
          "measurement_sigma_theta_deg",
          [](auto& m) -> auto& { return m.graph.measurement_sigma_theta_rad; }, InRange{1e-3, 90},
          "the same for θ: σ₀")
      .degrees(
          "measurement_sigma_theta_deg_per_m",
          [](auto& m) -> auto& { return m.graph.measurement_sigma_theta_rad_per_m; },
          InRange{0, 90}, "...k", "deg/m")
      .add(
          "max_measurement_distance_m",
          [](auto& m) -> auto& { return m.graph.max_measurement_distance_m; }, InRange{1e-3, 100},
          "m", "farther measurements stay out of the graph")
      .add(
          "landmark_frame_sigma_xy_m",
          [](auto& m) -> auto& { return m.graph.landmark_frame_sigma_xy_m; }, InRange{0, 10}, "m",
          "a landmark's frame is its creation pose moved by an offset with this prior (its "
          "structure's own error, shared by all its measurements), x and y; 0 (with θ): none")
      .degrees(
          "landmark_frame_sigma_theta_deg",
          [](auto& m) -> auto& { return m.graph.landmark_frame_sigma_theta_rad; }, InRange{0, 90},
          "...and θ")
      .choice(
          "robust_loss", [](auto& m) -> auto& { return m.graph.robust_loss; },
          std::vector<std::pair<std::string, Loss>>{{"huber", Loss::kHuber},
                                                    {"cauchy", Loss::kCauchy}},
          "robust loss of the measurement edges: `cauchy` (the influence of an edge falls beyond "
          "the scale, so a badly built landmark loses weight) or `huber` (the loss before "
          "2026-11-25)")
      .add(
          "robust_sigmas", [](auto& m) -> auto& { return m.graph.robust_sigmas; },
          InRange{0.1, 100}, "σ", "its scale (Huber: 3.0)")
      .add(
          "max_iterations", [](auto& m) -> auto& { return m.graph.max_iterations; },
          InRange{1, 1000}, "", "Levenberg-Marquardt iterations per solve")
      .add(
          "odometry_gate_mahalanobis_sq",
          [](auto& m) -> auto& { return m.graph.odometry_gate_mahalanobis_sq; }, InRange{0, 1e6},
          "",
          "a measurement agrees with the odometry since its landmark's creation if within this; "
          "0: no test, every edge enters")
      .add(
          "min_agreeing", [](auto& m) -> auto& { return m.graph.min_agreeing; }, InRange{0, 1000},
          "",
          "a landmark's edges enter a solve once this many of its measurements agreed; one with at "
          "least two against and as many against as for is retired (graph and filter)")
      .add(
          "segment_prior_sigma_xy_m",
          [](auto& m) -> auto& { return m.graph.segment_prior_sigma_xy_m; }, InRange{1e-3, 100},
          "m", "weak prior of the first node after such a break, x and y")
      .degrees(
          "segment_prior_sigma_theta_deg",
          [](auto& m) -> auto& { return m.graph.segment_prior_sigma_theta_rad; },
          InRange{1e-3, 180}, "...and θ")
      .add(
          "recent_nodes", [](auto& m) -> auto& { return m.graph.recent_nodes; },
          InRange{2, 1000000}, "",
          "the newest nodes keep all their measurements (the graph's size is bounded by the map: "
          "docs/backend.md)")
      .add(
          "old_measurements_per_landmark",
          [](auto& m) -> auto& { return m.graph.old_measurements_per_landmark; },
          InRange{0, 1000000}, "",
          "of older measurements each landmark keeps this many, spread over its history; older "
          "nodes left with none go");
  return t;
}

}  // namespace

const ParamTable<BackendStageParams>& BackendStageParams::table() {
  using P = BackendStageParams;
  static const ParamTable<P> declared = [] {
    ParamTable<P> t;
    t.add(
         "num_particles", [](auto& p) -> auto& { return p.backend.filter.num_particles; },
         InRange{1, 1e6}, "", "particles (paper: 200)")
        .add(
            "threads", [](auto& p) -> auto& { return p.backend.filter.num_threads; },
            InRange{0, 256}, "", "TBB threads for particle updates; 0 = one per core")
        .add(
            "seed", [](auto& p) -> auto& { return p.backend.filter.seed; }, InRange{0, 9.0e18}, "",
            "random seed; runs are reproducible for a given seed")
        .add(
            "sigma_translation",
            [](auto& p) -> auto& { return p.backend.filter.motion.sigma_translation; },
            config::nonNegative(), "m/√m", "σ_T of the motion model (as `deadreckon`)")
        .required()
        .add(
            "sigma_rotation",
            [](auto& p) -> auto& { return p.backend.filter.motion.sigma_rotation; },
            config::nonNegative(), "rad/√(m or rad)", "σ_R of the motion model")
        .required()
        .add(
            "measurement_sigma_xy_m",
            [](auto& p) -> auto& { return p.backend.filter.measurement_sigma_xy_m; },
            InRange{1e-4, 10.0}, "m", "Σ_vis, x and y (paper: 81 cm²)")
        .degrees(
            "measurement_sigma_theta_deg",
            [](auto& p) -> auto& { return p.backend.filter.measurement_sigma_theta_rad; },
            InRange{1e-3, 90.0}, "Σ_vis, θ (paper: 0.0019 rad²)")
        .add(
            "resample_ess_fraction",
            [](auto& p) -> auto& { return p.backend.filter.resample_ess_fraction; },
            InRange{0.0, 1.0}, "", "resample when ESS < this × particles")
        .add(
            "max_step_m", [](auto& p) -> auto& { return p.backend.max_step_m; }, config::positive(),
            "m", "larger odometry jumps are faults: reference reset, no motion")
        .degrees(
            "max_step_deg", [](auto& p) -> auto& { return p.backend.max_step_rad; },
            InRange{1, 180}, "same for rotation")
        .add(
            "max_measurement_age_s",
            [](auto& p) -> auto& { return p.backend.max_measurement_age_s; }, InRange{0.01, 600},
            "s", "odometry kept to align measurements; older ones are not used")
        .add(
            "max_measurement_lead_s",
            [](auto& p) -> auto& { return p.backend.max_measurement_lead_s; }, InRange{0, 60}, "s",
            "measurements newer than the newest odometry by more are not used")
        .add(
            "measurement_sigma_xy_per_m",
            [](auto& p) -> auto& { return p.backend.measurement_sigma_xy_per_m; }, InRange{0, 10.0},
            "m/m", "growth of Σ_vis (x, y) with the distance from the creation pose")
        .degrees(
            "measurement_sigma_theta_deg_per_m",
            [](auto& p) -> auto& { return p.backend.measurement_sigma_theta_rad_per_m; },
            InRange{0, 90.0}, "same for θ", "deg/m")
        .add(
            "landmark_min_interval_s",
            [](auto& p) -> auto& { return p.backend.landmark_min_interval_s; }, InRange{0, 60}, "s",
            "at most one measurement per landmark per interval (0: all)")
        .custom(
            "map_prior_file", "path",
            "an earlier run's landmark map file (copy of `landmark_db.map_file`): its landmarks "
            "with a back-end pose start in every particle (localization in a known map); "
            "`landmark_db`: this stack's landmark DB's map file, if it exists (with "
            "`map_prior_start: unknown`, a restarted back-end relocalizes in the DB's map)",
            [](const config::ConfigNode& node, const std::string& key, P& p) {
              if (!node.has(key)) return node.markUsed(key);
              const std::string text = node.getString(key, true);
              p.map_prior_from_landmark_db = text == "landmark_db";
              p.map_prior_file = text.empty() || p.map_prior_from_landmark_db
                                     ? std::filesystem::path()
                                     : node.getPath(key, true);
            },
            [](const P& p) {
              return p.map_prior_from_landmark_db ? std::string("landmark_db")
                                                  : config::valueText(p.map_prior_file.string());
            })
        .add("map_prior_sigma_xy_m", &P::map_prior_sigma_xy_m, InRange{1e-4, 10.0}, "m",
             "their standard deviation, x and y")
        .degrees("map_prior_sigma_theta_deg", &P::map_prior_sigma_theta_rad, InRange{1e-3, 90.0},
                 "...and θ")
        .choice("map_prior_start", &P::map_prior_unknown_start,
                std::vector<std::pair<std::string, bool>>{{"origin", false}, {"unknown", true}},
                "`origin`: the robot starts at the map's origin (where its first run started); "
                "`unknown`: global relocalization, all dual particles from the first measurements "
                "until confirmed")
        .add("map_prior_resume_max_gap_s", &P::map_prior_resume_max_gap_s, InRange{0, 86400}, "s",
             "a map file holding the robot's last pose (the landmark DB saves the back-end's "
             "estimates), saved at most this long before the first odometry (robot time): the "
             "back-end resumes there, whatever `map_prior_start` says (a restart after a crash; "
             "a wrong resume is a kidnapping to the filter); 0: never")
        .add("map_rate_hz", &P::map_rate_hz, InRange{0, 100}, "Hz",
             "`MAP` messages per second of robot time (0: none)")
        .add("particles_rate_hz", &P::particles_rate_hz, InRange{0, 100}, "Hz",
             "`PARTICLES` messages per second of robot time (0: none)")
        .add("odometry_timeout_s", &P::odometry_timeout_s, InRange{0.05, 3600}, "s",
             "odometry quieter than this (the stage's clock) is logged once, reported as "
             "`odometry_age_s` and raises health to WARN until it resumes")
        .block(
            "mixture", [](auto& p) -> auto& { return p.backend.filter.mixture; }, mixtureTable())
        .block(
            "outlier", [](auto& p) -> auto& { return p.backend.filter.outlier; }, outlierTable())
        .block(
            "kidnap", [](auto& p) -> auto& { return p.backend.filter.kidnap; }, kidnapTable())
        .block(
            "odometry_calibration", [](auto& p) -> auto& { return p.backend.odometry_calibration; },
            odometryCalibrationTable())
        .block(
            "map_correction", [](auto& p) -> auto& { return p.backend.map_correction; },
            mapCorrectionTable());
    return t;
  }();
  return declared;
}

BackendStageParams BackendStageParams::load(const config::ConfigNode& node,
                                            const config::RobotConfig& robot,
                                            const backend::PrefilterParams& prefilter) {
  rejectInstancePrefilter(node);
  BackendStageParams p;
  table().load(node, p);
  backend::BackendParams& b = p.backend;
  b.prefilter = prefilter;
  // The graph's odometry edges take the motion model's noise.
  b.map_correction.graph.sigma_translation = std::max(b.filter.motion.sigma_translation, 1e-4);
  b.map_correction.graph.sigma_rotation = std::max(b.filter.motion.sigma_rotation, 1e-4);
  p.odometry_channel = robot.channels.odometry;
  p.landmark_update_channel = robot.channels.landmark_update;
  p.landmark_proposal_channel = robot.channels.landmark_proposal;
  p.measurement_channel = robot.channels.visual_measurement;
  p.view_jump_channel = robot.channels.view_jump;
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
  if (params_.map_prior_from_landmark_db) {
    std::error_code ec;
    if (params_.map_prior_file.empty() || !std::filesystem::exists(params_.map_prior_file, ec)) {
      log::info("no landmark DB map file yet: starting a new map at the origin");
      return;
    }
  }
  if (!params_.map_prior_file.empty()) loadMapPrior();
}

namespace {

// The map file of the stack's landmark DB (empty: none, or in memory).
std::filesystem::path landmarkDbMapFile(const config::StackConfig& stack) {
  for (const auto& instance : stack.instances()) {
    if (stack.roleOf(instance) != "landmark_db") continue;
    return LandmarkDbParams::load(stack.process(instance), stack.robot).map_file;
  }
  return {};
}

}  // namespace

Eigen::Matrix3d BackendStage::mapPriorCovariance() const {
  const double xy = params_.map_prior_sigma_xy_m, theta = params_.map_prior_sigma_theta_rad;
  return Eigen::Vector3d(xy * xy, xy * xy, theta * theta).asDiagonal();
}

void BackendStage::loadMapPrior() {
  landmark_db::StoreOptions options;
  options.create_if_missing = false;
  options.read_only = true;
  // Throws MapFileError naming the file: a map that cannot be read is a
  // configuration error, not an empty map.
  landmark_db::LandmarkStore store(params_.map_prior_file, options);
  const Eigen::Matrix3d covariance = mapPriorCovariance();
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
  backend_.loadMap(known);
  prior_landmarks_ = known.size();
  if (!known.empty()) {
    // A saved robot pose is judged at the first odometry (is it recent?).
    if (params_.map_prior_resume_max_gap_s > 0) saved_robot_pose_ = store.robotPose();
    if (!saved_robot_pose_ && params_.map_prior_unknown_start) backend_.filter().startKidnapped();
  }
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
  odometry_watchdog_ = std::make_unique<bus::InputWatchdog>(
      "odometry on " + params_.odometry_channel, "odometry_age_s", params_.odometry_timeout_s,
      ": the pose does not move with the robot");
  odometry_watchdog_->begin(ctx.clock.now());
  ctx.bus.subscribe<vslam::odometry_t>(params_.odometry_channel,
                                       [this](const vslam::odometry_t& m) { onOdometry(m); });
  // Several front-ends publish here; a burst of a frame's measurements from
  // each camera must not overflow the queue.
  ctx.bus.subscribe<visual_measurement_t>(
      params_.measurement_channel, [this](const visual_measurement_t& m) { onMeasurement(m); },
      100);
  if (params_.backend.filter.kidnap.view_jump_window_s > 0) {
    ctx.bus.subscribe<vslam::view_jump_t>(params_.view_jump_channel,
                                          [this](const vslam::view_jump_t& m) { onViewJump(m); });
  }
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

void BackendStage::onViewJump(const vslam::view_jump_t& msg) {
  if (msg.utime <= 0 || !std::isfinite(msg.matched_share)) {
    ctx_->bus.reportMalformed(params_.view_jump_channel, "view jump of camera '" + msg.camera +
                                                             "' at " + std::to_string(msg.utime) +
                                                             " has no valid time or share");
    return;
  }
  ++view_jumps_;
  if (backend_.noteViewJump(msg.camera, msg.utime)) {
    log::warn("kidnapping detected at t ", msg.utime, ": every camera's view jumped (", msg.camera,
              " the last): the robot was moved; sampling all particles from the "
              "measurements");
  }
}

template <class... Args>
void BackendStage::logLimited(LogReason reason, const Args&... args) {
  warnings_.warn(reason, ctx_->clock.now(), args...);
}

void BackendStage::chooseStart(const vslam::odometry_t& first) {
  const landmark_db::RobotPoseRecord saved = *saved_robot_pose_;
  saved_robot_pose_.reset();  // judged once
  // In double: a damaged file's utime must not overflow the subtraction.
  const double gap_s = 1e-6 * (static_cast<double>(first.utime) - static_cast<double>(saved.utime));
  if (gap_s < 0 || gap_s > params_.map_prior_resume_max_gap_s) {
    log::info("the map file's robot pose was saved ", gap_s,
              " s before the first odometry (robot time): not resumed");
  } else {
    // The odometry frame is the one the pose was saved in (the back-end
    // restarted, not the odometry), so map<-odom still holds.
    const Pose2 map_T_odom = saved.map_pose.compose(saved.odom_pose.inverse());
    const Pose2 pose = map_T_odom.compose(Pose2{first.x, first.y, first.theta});
    // The saved uncertainty, and the map's own (the landmarks' prior).
    const Eigen::Matrix3d covariance =
        Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(saved.covariance.data()) +
        mapPriorCovariance();
    try {
      backend_.filter().startAt(pose, covariance);
      resumed_ = true;
      log::info("resumed at the robot pose the map file saved ", gap_s,
                " s before the first odometry: (", pose.x, ", ", pose.y, ", ", radToDeg(pose.theta),
                " deg)");
      return;
    } catch (const std::invalid_argument& e) {
      log::warn("the map file's robot pose cannot start the filter: ", e.what());
    }
  }
  if (params_.map_prior_unknown_start) backend_.filter().startKidnapped();
}

void BackendStage::onOdometry(const vslam::odometry_t& msg) {
  odometry_watchdog_->arrived(ctx_->clock.now(), msg.utime);
  if (saved_robot_pose_ && std::isfinite(msg.x) && std::isfinite(msg.y) &&
      std::isfinite(msg.theta)) {
    chooseStart(msg);
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
  // While kidnapped (also a start in a saved map before its relocalization)
  // the pose is in no frame yet: the DB must not store landmark poses of it.
  if (params_.map_rate_hz > 0 && msg.utime >= next_map_ && !backend_.filter().kidnapped()) {
    publishMap(msg.utime);
    next_map_ = msg.utime + periodUs(params_.map_rate_hz);
  }
  if (params_.particles_rate_hz > 0 && msg.utime >= next_particles_) {
    publishParticles(msg.utime);
    next_particles_ = msg.utime + periodUs(params_.particles_rate_hz);
  }
}

void BackendStage::onMeasurement(const visual_measurement_t& msg) {
  if (repeated_measurements_.repeated(msg.camera, msg.seq, msg.utime)) return;
  backend::MeasurementInput in;
  in.utime = msg.utime;
  in.landmark_id = msg.landmark_id;
  in.relative = {msg.dx, msg.dy, msg.dtheta};
  in.proj_err_rms_px = msg.proj_err_rms;
  in.num_points = msg.num_points;
  in.slope = msg.slope;
  in.camera = msg.camera;
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
        log::info(
            "evidence of a pose ", std::hypot(j.x, j.y), " m, ", radToDeg(j.theta),
            " deg from the estimate at t ", msg.utime, " (Mahalanobis^2 ",
            r.update.jump_mahalanobis_sq, " under the drift covariance): ",
            r.update.drift_corrected ? "drift, the particles moved towards it" : "kidnapping");
      }
      if (r.update.kidnap_detected) {
        log::warn("kidnapping detected at t ", msg.utime, ", measurement ", msg.seq, " of ",
                  msg.camera, " (landmark ", msg.landmark_id, ", agreement ", r.update.agreement,
                  "): sampling all particles from the measurements");
      }
      if (r.update.cancelled) {
        log::info("kidnapping cancelled at t ", msg.utime, ", measurement ", msg.seq, " of ",
                  msg.camera, " (landmark ", msg.landmark_id,
                  "): measurements agree with the pose before it; the landmarks that declared it "
                  "were look-alikes");
      } else if (r.update.recovered) {
        log::info("relocalized at t ", msg.utime, ", measurement ", msg.seq, " of ", msg.camera,
                  " (landmark ", msg.landmark_id, ", agreement ", r.update.agreement, ")");
      }
      if (r.join) {
        log::info("map correction: ",
                  r.join->broken ? "the robot was moved, the odometry chain is broken"
                                 : "a loop closure, the odometry chain is kept",
                  " (jump ", r.join->jump_m, " m, ", radToDeg(r.join->jump_rad),
                  " deg from the odometry; drift span ", r.join->span_m, " m driven, ",
                  radToDeg(r.join->span_rad), " deg turned; Mahalanobis^2 ",
                  r.join->jump_mahalanobis_sq, ")");
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
            " m/sqrt(m), sigma_rotation ", n.sigma_rotation, " rad/sqrt(m+rad), heading_bias ",
            n.heading_bias, " rad/m; motion model ",
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

void BackendStage::collectHealth(bus::HealthReport& report) {
  const backend::BackendCounters& c = backend_.counters();
  for (int s = static_cast<int>(MeasurementStatus::kAccepted); s < backend::kNumMeasurementStatus;
       ++s) {
    report.add(
        std::string("measurements_") + backend::metricName(static_cast<MeasurementStatus>(s)),
        static_cast<double>(c.status[s]), "count");
  }
  report.add("view_jumps", static_cast<double>(view_jumps_), "count");
  report.add("resumed_at_saved_pose", resumed_ ? 1.0 : 0.0, "bool");
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
  report.add("measurements_ignored_look_alike",
             static_cast<double>(c.look_alike_measurements_ignored), "count");
  report.add("landmarks", static_cast<double>(backend_.filter().numLandmarks()), "count");
  report.add("particles", static_cast<double>(backend_.filter().particles().size()), "count");
  const backend::PoseEstimate e = backend_.filter().estimate();
  report.add("effective_sample_size", e.ess, "count");
  report.add("dual_ratio", backend_.filter().lastDualRatio());
  report.add("kidnapped", e.kidnapped ? 1.0 : 0.0);
  report.add("kidnaps_detected", static_cast<double>(c.kidnaps_detected), "count");
  report.add("recoveries", static_cast<double>(c.recoveries), "count");
  report.add("kidnaps_cancelled", static_cast<double>(c.kidnaps_cancelled), "count");
  report.add("drift_corrections", static_cast<double>(c.drift_corrections), "count");
  report.add("landmarks_mapped_after_relocalization",
             static_cast<double>(c.landmarks_mapped_after_relocalization), "count");
  report.add("landmarks_moved_after_relocalization",
             static_cast<double>(c.landmarks_moved_after_relocalization), "count");
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
    report.add("graph_nodes_removed", static_cast<double>(g->numNodesRemoved()), "count");
    report.add("graph_edges_measurement", static_cast<double>(g->numMeasurements()), "count");
    report.add("graph_landmarks", static_cast<double>(c.landmarks_in_graph), "count");
    report.add("graph_landmark_creations_unused", static_cast<double>(c.landmark_creations_unused),
               "count");
    report.add("graph_landmarks_distrusted", static_cast<double>(g->numDistrustedLandmarks()),
               "count");
    report.add("graph_measurements", static_cast<double>(c.graph_measurements), "count");
    report.add("graph_solves", static_cast<double>(c.graph_solves), "count");
    report.add("graph_solve_failures", static_cast<double>(c.graph_solve_failures), "count");
    report.add("graph_odometry_breaks", static_cast<double>(c.graph_odometry_breaks), "count");
    report.add("graph_segments_moved", static_cast<double>(c.graph_segments_moved), "count");
    report.add("graph_solve_ms", c.graph_last_solve_ms, "ms");
    report.add("graph_solve_waits", static_cast<double>(c.graph_solve_waits), "count");
    report.add("graph_solve_wait_ms", c.graph_solve_wait_ms, "ms");
  }
  if (e.kidnapped) report.warn("kidnapping suspected: relocalizing from visual measurements");
  if (odometry_watchdog_) odometry_watchdog_->report(ctx_->clock.now(), report);
  report.add("repeated_measurements", static_cast<double>(repeated_measurements_.repeats()),
             "count");
  period_updates_ = 0;
  period_update_ms_ = 0;
  period_max_update_ms_ = 0;
}

void registerBackend(bus::StageRegistry& registry) {
  registry.add(
      "backend",
      [](const bus::StageSetup& setup) {
        BackendStageParams p =
            BackendStageParams::load(setup.params, setup.stack.robot, loadPrefilter(setup.stack));
        if (p.map_prior_from_landmark_db) p.map_prior_file = landmarkDbMapFile(setup.stack);
        return std::make_unique<BackendStage>(std::move(p));
      },
      bus::describeWith(BackendStageParams::table()));
}

}  // namespace vslam::stages
