#include "backend/particle_filter.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "backend/measurement_model.hpp"
#include "backend/rng.hpp"

namespace vslam::backend {

namespace {

// The jump from one pose to another as a vector (x, y, wrapped theta): what
// the drift gate weighs and the drift correction moves by a share of.
Eigen::Vector3d jumpBetween(const Pose2& from, const Pose2& to) {
  return {to.x - from.x, to.y - from.y, wrapAngle(to.theta - from.theta)};
}

// What each random stream is for (part of its seed).
enum Purpose : uint64_t {
  kMotion = 1,
  kDual = 2,
  kSelect = 3,
  kResample = 4,
  kMotionBefore = 5,
  kStart = 6
};

// The newest measurements kept for the kidnap and relocalization tests:
// their cost must not grow with a long run of inconsistent measurements
// (a look-alike that never gives enough evidence).
constexpr size_t kMaxRunMeasurements = 64;
// Recent inconsistent measurements kept to find where a kidnapping began.
constexpr size_t kMaxRecentInconsistent = 256;
// Measurements kept for the relocalization's window (recover_window_s): a
// moved robot's relocalization takes every measurement, 20-40 a second with
// two cameras, so 64 held under 3 s of the window's 10 (generated home 1217's
// second start in its saved map: relocalized in 8.4 s with 256, 13.2 s with
// 64).
constexpr size_t kMaxRelocalizationMeasurements = 256;

// How far (in cluster sizes, KidnapParams::cluster_*) a landmark's implied
// poses in one run of inconsistent measurements may lie apart before it
// counts as recognised at more than one wrong place (kidnapEvidence).
constexpr double kWanderingClusterScale = 2.0;

template <class T>
void pushBounded(std::vector<T>& run, T value, size_t max_size = kMaxRunMeasurements) {
  if (run.size() >= max_size) run.erase(run.begin());
  run.push_back(std::move(value));
}

// A landmark estimate moved by a map-frame transform.
LandmarkEstimate movedBy(const LandmarkEstimate& lm, const Pose2& shift) {
  LandmarkEstimate out = lm;
  out.mean = shift.compose(toPose(lm.mean)).vector();
  const double c = std::cos(shift.theta), s = std::sin(shift.theta);
  Eigen::Matrix3d j;
  j << c, -s, 0,  //
      s, c, 0,    //
      0, 0, 1;
  out.covariance = j * lm.covariance * j.transpose();
  return out;
}

// E[exp(-d^2/2)] for d^2 ~ chi^2 with 3 degrees of freedom: (1 + 1)^(-3/2).
constexpr double kConsistentAgreement = 0.35355339059327373;

double logSumExp(const double* v, size_t n) {
  double m = -std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < n; ++i) m = std::max(m, v[i]);
  if (!std::isfinite(m)) return m;
  double s = 0;
  for (size_t i = 0; i < n; ++i) s += std::exp(v[i] - m);
  return m + std::log(s);
}

// The particles' log weights, normalised so that their exponentials sum to
// 1: in the log domain, as plain numbers they may underflow when the
// particles disagree with the measurements.
std::vector<double> normalizedLogWeightsOf(const std::vector<Particle>& particles) {
  std::vector<double> log_w(particles.size());
  for (size_t i = 0; i < log_w.size(); ++i) log_w[i] = particles[i].log_weight;
  const double lse = logSumExp(log_w.data(), log_w.size());
  for (double& v : log_w) v -= lse;
  return log_w;
}

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("backend filter: " + what);
}

// The robust likelihood of OutlierParams: log of (1 - eps) N + eps u.
class RobustLikelihood {
 public:
  explicit RobustLikelihood(const OutlierParams& op)
      : robust_(op.probability > 0),
        log_inlier_(robust_ ? std::log1p(-op.probability) : 0.0),
        log_floor_(robust_ ? std::log(op.probability) - std::log(op.area_m2 * 2 * M_PI) : 0.0) {}
  bool robust() const { return robust_; }
  double log(const Innovation& in) const {
    if (!robust_) return in.log_likelihood;
    const double a = log_inlier_ + in.log_likelihood, b = log_floor_;
    return std::max(a, b) + std::log1p(std::exp(-std::abs(a - b)));
  }

 private:
  bool robust_;
  double log_inlier_, log_floor_;
};

// The motion model's density of a particle's move since its anchor (its pose
// at the previous update): the odometry u since then, with its accumulated
// covariance (the anchor's frame, the same for every particle) plus the
// floors that regularise the nearly singular covariance of a short drive.
class MotionDensity {
 public:
  MotionDensity(const PoseWithCovariance& since_update, const MixtureParams& mix)
      : u_(since_update.pose()) {
    Eigen::Matrix3d cov = since_update.covariance();
    cov(0, 0) += mix.motion_min_sigma_xy_m * mix.motion_min_sigma_xy_m;
    cov(1, 1) += mix.motion_min_sigma_xy_m * mix.motion_min_sigma_xy_m;
    cov(2, 2) += mix.motion_min_sigma_theta_rad * mix.motion_min_sigma_theta_rad;
    inv_ = cov.inverse();
    log_norm_ = -0.5 * (std::log(cov.determinant()) + 3 * 1.8378770664093453);
  }
  double log(const Particle& p) const {
    const Pose2 moved = p.anchor.between(p.pose);
    const Eigen::Vector3d d(moved.x - u_.x, moved.y - u_.y, wrapAngle(moved.theta - u_.theta));
    return log_norm_ - 0.5 * d.dot(inv_ * d);
  }

 private:
  Pose2 u_;
  Eigen::Matrix3d inv_;
  double log_norm_;
};

}  // namespace

const char* toString(UpdateKind k) {
  switch (k) {
    case UpdateKind::kInitialized:
      return "initialized";
    case UpdateKind::kMixture:
      return "mixture";
    case UpdateKind::kKidnapped:
      return "kidnapped";
    case UpdateKind::kIgnored:
      return "ignored";
  }
  return "?";
}

void FilterParams::validate() const {
  require(num_particles >= 1, "num_particles must be >= 1");
  require(motion.sigma_translation >= 0 && motion.sigma_rotation >= 0,
          "motion sigmas must be >= 0");
  require(measurement_sigma_xy_m > 0 && measurement_sigma_theta_rad > 0,
          "measurement sigmas must be > 0");
  require(resample_ess_fraction >= 0 && resample_ess_fraction <= 1,
          "resample_ess_fraction must be in [0, 1]");
  require(mixture.dual_ratio_min >= 0 && mixture.dual_ratio_min <= mixture.dual_ratio_max &&
              mixture.dual_ratio_max <= 1,
          "need 0 <= dual_ratio_min <= dual_ratio_max <= 1");
  require(mixture.agreement_smoothing > 0 && mixture.agreement_smoothing <= 1,
          "agreement_smoothing must be in (0, 1]");
  require(mixture.motion_min_sigma_xy_m > 0 && mixture.motion_min_sigma_theta_rad > 0,
          "motion_min_sigma_xy_m and motion_min_sigma_theta_rad must be > 0");
  require(kidnap.detect_agreement >= 0 && kidnap.detect_agreement <= 1 &&
              kidnap.recover_agreement >= 0 && kidnap.recover_agreement <= 1,
          "kidnap agreements must be in [0, 1]");
  require(kidnap.detect_count >= 1 && kidnap.recover_count >= 1 && kidnap.detect_landmarks >= 1 &&
              kidnap.recover_landmarks >= 1,
          "kidnap counts must be >= 1");
  require(kidnap.detect_min_span_s >= 0 && kidnap.suspect_after >= 0 && kidnap.cancel_count >= 0,
          "kidnap detect_min_span_s, suspect_after and cancel_count must be >= 0");
  require(kidnap.detect_dissent_ratio >= 0, "kidnap detect_dissent_ratio must be >= 0");
  require(kidnap.cluster_xy_m > 0 && kidnap.cluster_theta_rad > 0,
          "kidnap cluster tolerances must be > 0");
  require(std::isfinite(kidnap.retest_margin_s), "kidnap retest_margin_s must be finite");
  require(kidnap.view_jump_window_s >= 0 && std::isfinite(kidnap.view_jump_window_s),
          "kidnap view_jump_window_s must be finite and >= 0");
  require(kidnap.unchecked_jump_window_s >= 0 && std::isfinite(kidnap.unchecked_jump_window_s),
          "kidnap unchecked_jump_window_s must be finite and >= 0");
  require(outlier.probability >= 0 && outlier.probability < 1,
          "outlier probability must be in [0, 1)");
  require(outlier.area_m2 > 0 && outlier.gate_mahalanobis_sq > 0,
          "outlier area and gate must be > 0");
  require(num_threads >= 0, "num_threads must be >= 0");
  require(grain_size >= 1, "grain_size must be >= 1");
  require(initial_pose.isFinite(), "initial_pose must be finite");
}

Eigen::Matrix3d FilterParams::measurementCovariance() const {
  return Eigen::Vector3d(measurement_sigma_xy_m * measurement_sigma_xy_m,
                         measurement_sigma_xy_m * measurement_sigma_xy_m,
                         measurement_sigma_theta_rad * measurement_sigma_theta_rad)
      .asDiagonal();
}

ParticleFilter::ParticleFilter(FilterParams params) : params_(std::move(params)) {
  params_.validate();
  // (A copy of `automatic`: the constant is declared but not defined in oneTBB 2021.)
  const int automatic = tbb::task_arena::automatic;
  arena_ =
      std::make_unique<tbb::task_arena>(params_.num_threads > 0 ? params_.num_threads : automatic);
  particles_.resize(static_cast<size_t>(params_.num_particles));
  for (Particle& p : particles_) p.pose = p.anchor = params_.initial_pose;
}

ParticleFilter::~ParticleFilter() = default;

template <class F>
void ParticleFilter::forEachParticle(F&& f) const {
  forEachIndex(particles_.size(), std::forward<F>(f));
}

template <class F>
void ParticleFilter::forEachIndex(size_t m, F&& f) const {
  const size_t grain = static_cast<size_t>(params_.grain_size);
  if (m <= grain || params_.num_threads == 1) {
    for (size_t i = 0; i < m; ++i) f(i);
    return;
  }
  arena_->execute([&] {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, m, grain),
                      [&](const tbb::blocked_range<size_t>& r) {
                        for (size_t i = r.begin(); i != r.end(); ++i) f(i);
                      });
  });
}

int64_t ParticleFilter::slotOf(int64_t landmark_id) const {
  const auto it = slots_.find(landmark_id);
  return it == slots_.end() ? -1 : static_cast<int64_t>(it->second);
}

void ParticleFilter::predict(const Pose2& step) {
  if (step.x == 0 && step.y == 0 && step.theta == 0) return;  // standing still: no noise either
  const uint64_t k = step_++;
  const uint64_t seed = params_.seed;
  const MotionNoise noise = params_.motion;
  const MotionNoise::StepNoise step_noise(noise, step);
  since_update_.apply(step, noise.stepCovariance(step));
  odometry_ = odometry_.compose(step);
  if (kidnapped_) held_ = held_.compose(step);
  forEachParticle([&](size_t i) {
    RandomStream rng(seed, k, i, kMotion);
    const double nt = rng.normal();
    const double nr = rng.normal();
    particles_[i].pose = particles_[i].pose.compose(step_noise.perturb(nt, nr));
  });
  if (before_kidnap_.empty()) return;
  before_kidnap_since_update_.apply(step, noise.stepCovariance(step));
  forEachIndex(before_kidnap_.size(), [&](size_t i) {
    RandomStream rng(seed, k, i, kMotionBefore);
    const double nt = rng.normal();
    const double nr = rng.normal();
    before_kidnap_[i].pose = before_kidnap_[i].pose.compose(step_noise.perturb(nt, nr));
  });
}

UpdateReport ParticleFilter::initialize(uint32_t slot, const Observation& obs,
                                        const Eigen::Matrix3d& r) {
  ++step_;
  forEachParticle([&](size_t i) {
    Particle& p = particles_[i];
    p.map.mutableSlot(slot) = initializeLandmark(p.pose, obs.relative, r);
    p.anchor = p.pose;
  });
  since_update_ = PoseWithCovariance();
  return unweighedReport(UpdateKind::kInitialized, 1);
}

UpdateReport ParticleFilter::unweighedReport(UpdateKind kind, double agreement) const {
  UpdateReport rep;
  rep.kind = kind;
  rep.agreement = agreement;
  rep.smoothed_agreement = smoothed_agreement_;
  rep.ess = effectiveSampleSize();
  return rep;
}

UpdateReport ParticleFilter::update(const Observation& obs) {
  if (!obs.relative.isFinite() || !obs.covariance.allFinite())
    throw std::invalid_argument("backend filter: non-finite observation");
  const Eigen::Matrix3d r = measurementCovarianceOf(obs);
  const auto found = slots_.find(obs.landmark_id);
  if (found == slots_.end() && kidnapped_) {
    // A landmark first seen while kidnapped would be placed relative to
    // wherever each particle happens to be: its next measurements would then
    // agree with every particle and confirm a relocalization that never
    // happened (a carried robot that makes new landmarks before it sees an
    // old one "recovered" where the look-alike that declared the kidnapping
    // put it). It is mapped at its first measurement after the relocalization.
    UpdateReport rep = unweighedReport(UpdateKind::kKidnapped, 0);
    rep.deferred = true;
    return rep;
  }
  if (found == slots_.end()) {
    const auto slot = static_cast<uint32_t>(ids_.size());
    slots_.emplace(obs.landmark_id, slot);
    ids_.push_back(obs.landmark_id);
    placed_utime_.push_back(obs.utime);
    retest_pending_.push_back(0);
    return initialize(slot, obs, r);
  }
  const uint32_t slot = found->second;
  const bool suspect = isSuspect(slot);
  if (kidnapped_ && suspect) {
    // A known look-alike neither proposes nor confirms a relocalization.
    UpdateReport rep = unweighedReport(UpdateKind::kKidnapped, 0);
    rep.suspect = true;
    return rep;
  }
  if (kidnapped_ && robot_was_moved_ && placed_utime_[slot] >= moved_since_utime_) {
    // Placed after a view jump moved the robot and before the kidnapping was
    // declared: from the pose the robot was thought to be at, so it agrees
    // with that pose by construction and says nothing of where the robot is.
    // All dual from it, the particles went back there, and it "confirmed"
    // that pose (reporting home 1018's third carry: relocalized 1.9 m off,
    // corrected 10 s later). It neither proposes nor confirms; it is
    // re-tested after the relocalization, as it was already.
    return unweighedReport(UpdateKind::kKidnapped, 0);
  }
  // While kidnapped, does it agree with the hypothesis the kidnapping
  // replaced? Then it was a look-alike's, and this measurement updates
  // that hypothesis as usual.
  const bool cancelled = kidnapped_ && cancelKidnapping(slot, obs, r);
  const uint64_t k = step_++;
  const size_t m = particles_.size();
  const Pose2 y = obs.relative;

  // Prior weights, normalised, in the log domain (they may underflow as
  // plain numbers when the particles disagree with the measurements).
  const std::vector<double> log_w = normalizedLogWeights();

  // (0) Placed before a kidnapping was detected: where does it belong?
  UpdateReport rep;
  if (!kidnapped_ && retest_pending_[slot]) rep.moved = retest(slot, obs);

  // (1) How well do the particles, as they are, explain the measurement?
  const double agreement = agreementWith(slot, obs, r, log_w, &innovations_);

  // (2) Mode: kidnap detection and recovery, the dynamic ratio. (A landmark
  // still to be re-tested that agrees with neither place gives kidnap
  // evidence as it is: held back, a landmark made before a first carry and
  // next seen after a second one would hide the second; tuning homes 43, 48.)
  rep.agreement = agreement;
  rep.suspect = suspect;
  rep.recovered = rep.cancelled = cancelled;
  const MixtureParams& mix = params_.mixture;
  bool confirmed_by_cluster = false;
  const bool all_dual = updateMode(slot, obs, agreement, suspect, &rep, &confirmed_by_cluster);
  // (With the robust likelihood.) A known look-alike's measurement weighs
  // the particles only if it is consistent (a >= recover_agreement, as its
  // record counts it): otherwise it is most likely the look-alike again, and
  // it weighs no particle and updates no landmark filter (it already proposes
  // no dual particles and gives no kidnap evidence). Weighed, the few
  // particles of the set's tail within its gate would take all the weight,
  // and the estimate would jump to them (docs/backend.md, "Known look-alikes").
  if (suspect && params_.outlier.probability > 0 && !all_dual && !rep.drift_corrected &&
      agreement < params_.kidnap.recover_agreement) {
    rep.kind = UpdateKind::kIgnored;
    for (const Innovation& in : innovations_)
      rep.num_outliers += in.mahalanobis_sq > params_.outlier.gate_mahalanobis_sq;
    rep.smoothed_agreement = smoothed_agreement_;
    rep.ess = effectiveSampleSize();
    return rep;
  }
  const double ratio = all_dual ? 1.0
                                : mix.dual_ratio_min + (mix.dual_ratio_max - mix.dual_ratio_min) *
                                                           (1.0 - smoothed_agreement_);
  // A known look-alike proposes no dual particles: they would land on its twin.
  const auto n_dual =
      suspect ? uint64_t{0}
              : static_cast<uint64_t>(std::min<double>(static_cast<double>(m),
                                                       std::round(ratio * static_cast<double>(m))));
  // (3) Sample, weight, and update each particle's Kalman filter of the landmark.
  // (A drift correction moved the particles: their innovations are new.)
  rep.num_outliers = drawAndWeigh(slot, y, r, log_w, n_dual, all_dual, k,
                                  rep.drift_corrected ? nullptr : &innovations_);
  normalize();
  rep.kind = all_dual ? UpdateKind::kKidnapped : UpdateKind::kMixture;
  if (kidnapped_ && confirmed_by_cluster) {
    kidnapped_ = false;
    rep.recovered = true;
    recover_count_ = 0;
    recover_landmarks_.clear();
  }
  if (rep.recovered && !rep.cancelled) {
    if (robot_was_moved_) moved_relocalized_utime_ = obs.utime;
    // Relocalized: the landmarks placed while the robot may already have
    // been moved are re-tested with the shift from the pose held to here.
    retest_shift_ = estimate().mean.compose(held_.inverse());
    for (uint32_t s : retest_candidates_) retest_pending_[s] = 1;
    retest_candidates_.clear();
  }
  if (!kidnapped_) {
    reloc_run_.clear();
    forgetBeforeKidnap();
  }
  rep.num_dual = static_cast<int>(n_dual);
  rep.dual_ratio = static_cast<double>(n_dual) / static_cast<double>(m);
  rep.smoothed_agreement = smoothed_agreement_;
  rep.ess = effectiveSampleSize();
  last_dual_ratio_ = rep.dual_ratio;
  if (rep.ess < params_.resample_ess_fraction * static_cast<double>(m)) {
    resample();
    rep.resampled = true;
  }
  return rep;
}

int ParticleFilter::drawAndWeigh(uint32_t slot, const Pose2& y, const Eigen::Matrix3d& r,
                                 const std::vector<double>& log_w, uint64_t n_dual, bool all_dual,
                                 uint64_t k, const std::vector<Innovation>* prior_innovations) {
  const uint64_t seed = params_.seed;
  const size_t m = particles_.size();
  const MixtureParams& mix = params_.mixture;
  const OutlierParams& op = params_.outlier;
  const RobustLikelihood robust_likelihood(op);
  // Which particles are dual: n_dual of them, evenly spread over the
  // (ancestor-ordered) set from a random offset.
  RandomStream select_rng(seed, k, 0, kSelect);
  const uint64_t offset = select_rng.next() % m;
  auto isDual = [&](size_t i) { return (i * n_dual + offset) % m < n_dual; };

  // Importance factors (docs/backend.md, "Mixture proposal"). Slot i holds
  // the history of particle i (prior weight w_i) and a pose s drawn from the
  // mixture g_i(s) = (1 - rho) p(s | a_i, u) + rho p(y | s, m_i): the motion
  // model from the particle's own previous pose a_i (its anchor: its pose at
  // the previous update) and the odometry u since, or the measurement model
  // given its own map m_i (a density in s that integrates to 1, since
  // |det dh/ds| = 1). The target is w_i p(s | a_i, u) p(y | s, m_i), so
  //   W_i = w_i p(s | a_i, u) p(y | s, m_i) / g_i(s)
  // for nominal and dual particles alike: consistent by construction, and
  // bounded by min(p(y|s) / (1 - rho), p(s|a,u) / rho), so neither kind can
  // swamp the other (the balance heuristic of multiple importance sampling;
  // with rho = 0 it is FastSLAM's w_i p(y | s, m_i)). p(s | a_i, u) is the
  // Gaussian of the odometry's accumulated covariance since the previous
  // update (the anchor's frame, the same for every particle), floored.
  const double rho = static_cast<double>(n_dual) / static_cast<double>(m);
  const double log_rho = std::log(rho), log_1_rho = std::log1p(-rho);
  const MotionDensity motion_density(since_update_, mix);
  Eigen::Matrix3d chol_r = Eigen::Matrix3d::Zero();
  if (n_dual > 0) chol_r = r.llt().matrixL();

  std::vector<char> outlier(m, 0);
  forEachParticle([&](size_t i) {
    Particle& p = particles_[i];
    LandmarkEstimate& lm = p.map.mutableSlot(slot);
    p.dual = isDual(i);
    if (p.dual) {
      RandomStream rng(seed, k, i, kDual);
      p.pose = sampleFromMeasurement(lm, y, chol_r, rng);
    }
    const Innovation in = p.dual || prior_innovations == nullptr ? innovation(lm, p.pose, y, r)
                                                                 : (*prior_innovations)[i];
    const double lp_y = robust_likelihood.log(in);  // target: robust likelihood
    if (all_dual) {
      p.log_weight = 0;  // kidnapped: uniform importance factors (paper 6.2)
    } else if (n_dual == 0) {
      p.log_weight = log_w[i] + lp_y;
    } else {
      // The proposal's dual component is the Gaussian the dual particles
      // were drawn from; the target's likelihood is the robust one.
      const double lp_motion = motion_density.log(p);
      const double a = log_1_rho + lp_motion, b = log_rho + in.log_likelihood;
      const double log_g = std::max(a, b) + std::log1p(std::exp(-std::abs(a - b)));
      p.log_weight = log_w[i] + lp_motion + lp_y - log_g;
    }
    // Gate: an outlier for this particle leaves its landmark filter alone.
    if (robust_likelihood.robust() && in.mahalanobis_sq > op.gate_mahalanobis_sq) {
      outlier[i] = 1;
    } else {
      kalmanUpdate(lm, in, r);
    }
    p.anchor = p.pose;
  });
  since_update_ = PoseWithCovariance();
  int num_outliers = 0;
  for (char o : outlier) num_outliers += o;
  return num_outliers;
}

bool ParticleFilter::updateMode(uint32_t slot, const Observation& obs, double agreement,
                                bool suspect, UpdateReport* rep, bool* confirmed_by_cluster) {
  const KidnapParams& kp = params_.kidnap;
  const MixtureParams& mix = params_.mixture;
  bool all_dual = false;
  if (kidnapped_) {
    // A look-alike seen at a wrong place before (in a contradicted run)
    // cannot confirm, alone, a kidnapping it declared, unless the robot was
    // seen to be moved (a view jump): a repeated pattern's landmarks agree
    // with one another wherever it is recognised, and they would "confirm"
    // the look-alike's place before any other landmark (one that could
    // cancel it) is seen (the living room, simulator seed 22, with refined
    // landmarks: 4.3 m off for 40 s). Landmarks never contradicted still
    // confirm alone: a loop closure beyond the drift gate is declared and
    // confirmed by the same true landmarks (the apartment, forward camera).
    // A kidnapping declared soon after a moved robot's relocalization (a
    // carry, a start in a saved map) is that relocalization being corrected,
    // from few landmarks (reporting home 1019's restart in a 7-landmark map).
    const bool may_confirm = robot_was_moved_ || recentlyRelocalizedAfterAMove(obs.utime) ||
                             !isKidnapEvidence(slot) || !wasContradicted(slot);
    if (kp.recover_window_s > 0) {
      pushBounded(reloc_run_, implied(obs, slot), kMaxRelocalizationMeasurements);
      const auto window = static_cast<int64_t>(kp.recover_window_s * 1e6);
      reloc_run_.erase(
          std::remove_if(reloc_run_.begin(), reloc_run_.end(),
                         [&](const Implied& e) { return obs.utime - e.utime > window; }),
          reloc_run_.end());
      // Measurements since the detection: recover_landmarks distinct
      // landmarks agreeing confirm it. With those that declared it (kept in
      // the window from the detection), one more: the evidence that declared
      // it and one new measurement are as strong as that, but a repeated
      // pattern can give a few landmarks that agree (tuning homes 23, 36).
      // Declared on a view jump, no landmark declared it: one more since
      // (generated home 1282: two look-alikes, 4.3 m off, agreed 36 s after
      // the carry, and confirmed a relocalization there).
      std::vector<Implied> since_detection;
      for (const Implied& e : reloc_run_)
        if (e.utime > kidnap_declared_utime_) since_detection.push_back(e);
      const int needed_since = kp.recover_landmarks + (declared_on_view_jump_ ? 1 : 0);
      *confirmed_by_cluster =
          may_confirm &&
          ((!since_detection.empty() &&
            agreeingLandmarks(since_detection, since_detection.size() - 1) >= needed_since) ||
           agreeingLandmarks(reloc_run_, reloc_run_.size() - 1) >= kp.recover_landmarks + 1);
    }
    if (agreement >= kp.recover_agreement) {
      ++recover_count_;
      if (std::find(recover_landmarks_.begin(), recover_landmarks_.end(), obs.landmark_id) ==
          recover_landmarks_.end())
        recover_landmarks_.push_back(obs.landmark_id);
    } else {
      recover_count_ = 0;
      recover_landmarks_.clear();
    }
    if (may_confirm && recover_count_ >= kp.recover_count &&
        static_cast<int>(recover_landmarks_.size()) >= kp.recover_landmarks) {
      kidnapped_ = false;
      rep->recovered = true;
      smoothed_agreement_ = agreement;
      recover_count_ = 0;
      recover_landmarks_.clear();
    } else {
      // Still kidnapped; if the cluster confirmed it, this is the last
      // all-dual draw, from this measurement (one of the cluster).
      all_dual = true;
    }
  } else {
    // A run of inconsistent measurements in a row (KidnapParams). A known
    // look-alike's inconsistent measurement neither extends nor ends it. A
    // consistent one ends it; one between the two thresholds only takes its
    // own landmark's earlier measurements out of it (that landmark is coming
    // round to the particles: its old disagreement is stale). After a wheel
    // slip the particles are a few decimetres off, and the landmarks the slip
    // left half-explained ended every run, so the drift was never corrected
    // and the landmarks made since were placed from the wrong pose (tuning
    // sequence 41: 0.54 m for the rest of its second run; docs/backend.md).
    if (agreement >= kp.recover_agreement) record(slot).consistent += 1;
    if (agreement < kp.detect_agreement) {
      if (!suspect) noteInconsistent(obs, slot);
    } else if (agreement >= kp.recover_agreement) {
      noteConsistentAfterJump(slot);
      if (endsLowRun(slot, obs.utime)) endLowRun(obs.utime);
    } else {
      dropFromLowRun(slot);
    }
    const std::optional<Evidence> evidence =
        static_cast<int>(low_run_.size()) >= kp.detect_count ? kidnapEvidence(kp) : std::nullopt;
    if (evidence) {
      const PoseEstimate now = estimate();
      const Pose2 from = now.mean;
      const Pose2& to = evidence->pose;
      rep->evidence = true;
      const Eigen::Vector3d jump = jumpBetween(from, to);
      rep->jump = {jump.x(), jump.y(), jump.z()};
      rep->jump_mahalanobis_sq = driftMahalanobisSq(now, *evidence);
      if (withinDriftGate(rep->jump_mahalanobis_sq)) {
        // Drift: every particle moves (keeping its spread and map) by the
        // share of the jump the two uncertainties give it; this measurement
        // then weighs them as usual.
        rep->drift_shift = driftCorrected(now, *evidence).compose(from.inverse());
        shiftParticles(rep->drift_shift);
        rep->drift_corrected = true;
        smoothed_agreement_ = 1;
      } else {
        const bool moved = unresolvedViewJump(obs.utime);
        beginKidnapping(obs.utime, from, moved,
                        moved ? jumps_since_utime_ : std::numeric_limits<int64_t>::max(), to);
        for (const Implied& l : low_run_)
          if (!isKidnapEvidence(l.slot)) kidnap_evidence_slots_.push_back(l.slot);
        rep->kidnap_detected = true;
        // The measurements that declared it stay in the relocalization's
        // window: they say where the robot is.
        for (const Implied& m : low_run_)
          if (agreesWith(m, to, 1.0)) reloc_run_.push_back(m);
        all_dual = true;
      }
      low_run_.clear();
    }
  }
  if (!all_dual) {
    smoothed_agreement_ += mix.agreement_smoothing * (agreement - smoothed_agreement_);
  }
  return all_dual;
}

std::vector<double> ParticleFilter::normalizedLogWeights() const {
  return normalizedLogWeightsOf(particles_);
}

bool ParticleFilter::cancelKidnapping(uint32_t slot, const Observation& obs,
                                      const Eigen::Matrix3d& r) {
  const KidnapParams& kp = params_.kidnap;
  if (kp.cancel_count <= 0 || before_kidnap_.empty() ||
      before_kidnap_.front().map.find(slot) == nullptr)
    return false;
  // The robot was moved (a view jump came with the kidnapping) and the
  // landmark was placed since the kidnapping began (a re-test candidate):
  // from the pose the robot was thought to be at, so it agrees with that
  // pose by construction and says nothing of whether the robot is there.
  // (After a false alarm such a landmark is what ends it: it was placed
  // where the robot is. Tuning home 41: two measurements of one, made 2 s
  // before the detection, cancelled a carry's kidnapping.)
  if (robot_was_moved_ && std::find(retest_candidates_.begin(), retest_candidates_.end(), slot) !=
                              retest_candidates_.end())
    return false;
  const double agreement =
      agreementWith(before_kidnap_, slot, obs, r, normalizedLogWeightsOf(before_kidnap_), nullptr);
  if (agreement < kp.recover_agreement || ++before_kidnap_agreeing_ < kp.cancel_count) return false;
  particles_.swap(before_kidnap_);
  since_update_ = before_kidnap_since_update_;
  kidnapped_ = false;
  retest_candidates_.clear();  // the robot was not moved
  // The landmarks that declared it were seen where they are not.
  for (uint32_t s : kidnap_evidence_slots_) record(s).contradicted += 1;
  low_run_.clear();
  reloc_run_.clear();
  recover_count_ = 0;
  recover_landmarks_.clear();
  forgetBeforeKidnap();
  return true;
}

void ParticleFilter::forgetBeforeKidnap() {
  before_kidnap_.clear();
  kidnap_evidence_slots_.clear();
  before_kidnap_agreeing_ = 0;
}

bool ParticleFilter::wasContradicted(uint32_t slot) const {
  return slot < records_.size() && records_[slot].contradicted > 0;
}

bool ParticleFilter::isKidnapEvidence(uint32_t slot) const {
  return std::find(kidnap_evidence_slots_.begin(), kidnap_evidence_slots_.end(), slot) !=
         kidnap_evidence_slots_.end();
}

double ParticleFilter::agreementWith(uint32_t slot, const Observation& obs,
                                     const Eigen::Matrix3d& r, const std::vector<double>& log_w,
                                     std::vector<Innovation>* innovations) const {
  return agreementWith(particles_, slot, obs, r, log_w, innovations);
}

double ParticleFilter::agreementWith(const std::vector<Particle>& particles, uint32_t slot,
                                     const Observation& obs, const Eigen::Matrix3d& r,
                                     const std::vector<double>& log_w,
                                     std::vector<Innovation>* innovations) const {
  // a = sum_i w_i exp(-d_i^2 / 2) / E[exp(-d^2/2)], clipped to 1.
  const size_t m = particles.size();
  std::vector<double> d2(m);
  if (innovations != nullptr) innovations->resize(m);
  forEachIndex(m, [&](size_t i) {
    const LandmarkEstimate* lm = particles[i].map.find(slot);
    const Innovation in = innovation(*lm, particles[i].pose, obs.relative, r);
    d2[i] = in.mahalanobis_sq;
    if (innovations != nullptr) (*innovations)[i] = in;
  });
  double agreement = 0;
  for (size_t i = 0; i < m; ++i) agreement += std::exp(log_w[i] - 0.5 * d2[i]);
  return std::min(1.0, agreement / kConsistentAgreement);
}

bool ParticleFilter::retest(uint32_t slot, const Observation& obs) {
  // Which place puts the robot where the relocalized particles are, within
  // 2 x cluster_* (as the kidnapping's onset)? Not the measurement's
  // agreement: that is as tight as the landmark's covariance, and the
  // relocalization's own error (decimetres, degrees, turned about a
  // landmark metres away) would leave both places unlikely.
  const Pose2 at = estimate().mean;
  const LandmarkEstimate* lm = particles_[bestParticle()].map.find(slot);
  const Pose2 kept = toPose(lm->mean).compose(obs.relative);
  const Pose2 moved = retest_shift_.compose(kept);
  const double kept_offset = clusterOffset(kept, at), moved_offset = clusterOffset(moved, at);
  if (moved_offset <= 2 && moved_offset < kept_offset) {
    forEachParticle([&](size_t i) {
      LandmarkEstimate& e = particles_[i].map.mutableSlot(slot);
      e = movedBy(e, retest_shift_);
    });
    retest_pending_[slot] = 0;
    return true;
  }
  if (kept_offset <= 2) retest_pending_[slot] = 0;
  return false;
}

void ParticleFilter::chooseRetestCandidates(const std::optional<Pose2>& at) {
  const KidnapParams& kp = params_.kidnap;
  retest_candidates_.clear();
  if (kp.retest_margin_s < 0) return;
  // Where the robot was moved to: the earliest recent inconsistent
  // measurement whose implied pose, carried to now, is near the evidence.
  // The robot was moved before it; landmarks placed from a little before it
  // on may have been placed from the pose it was thought to be at.
  constexpr int64_t kNever = std::numeric_limits<int64_t>::max();
  int64_t onset = kNever;
  for (const Implied& m : recent_inconsistent_)
    if (at && agreesWith(m, *at, 2.0)) onset = std::min(onset, m.utime);
  recent_inconsistent_.clear();
  int64_t from = onset == kNever ? kNever : onset - static_cast<int64_t>(kp.retest_margin_s * 1e6);
  // A robot seen to be moved was moved at its view jumps' start: every
  // landmark placed since was placed from the pose it was thought to be at,
  // however long before the first inconsistent measurement.
  if (robot_was_moved_) from = std::min(from, moved_since_utime_);
  if (from == kNever) return;
  // A re-test of an earlier relocalization is moot now.
  std::fill(retest_pending_.begin(), retest_pending_.end(), 0);
  retestLandmarksPlacedSince(from);
}

void ParticleFilter::retestLandmarksPlacedSince(int64_t from) {
  for (uint32_t s = 0; s < placed_utime_.size(); ++s)
    if (placed_utime_[s] >= from && std::find(retest_candidates_.begin(), retest_candidates_.end(),
                                              s) == retest_candidates_.end())
      retest_candidates_.push_back(s);
}

void ParticleFilter::dropFromLowRun(uint32_t slot) {
  low_run_.erase(std::remove_if(low_run_.begin(), low_run_.end(),
                                [&](const Implied& m) { return m.slot == slot; }),
                 low_run_.end());
}

void ParticleFilter::endLowRun(int64_t t) {
  if (low_run_.empty()) return;
  // Soon after a moved robot's relocalization (a carry, a start in a saved
  // map) the particles stand on as few as two landmarks' word, so a landmark
  // that disagrees with them may be right and the relocalization wrong: it
  // is not marked a look-alike then. Otherwise a relocalization on a
  // repeated pattern marks the true landmarks, and their measurements can
  // never undo it (generated home 1206: a start in the saved map stayed
  // 2.8 m off to the end).
  if (!recentlyRelocalizedAfterAMove(t)) {
    std::vector<uint32_t> seen;
    for (const Implied& l : low_run_) {
      if (std::find(seen.begin(), seen.end(), l.slot) != seen.end()) continue;
      seen.push_back(l.slot);
      record(l.slot).contradicted += 1;
    }
  }
  low_run_.clear();
}

void ParticleFilter::noteViewJump(int64_t t) {
  // A jump within the window of its series' first continues the series: the
  // robot can be carried, then turned or carried on (reporting home 1010: a
  // second jump 4.4 s after the carry; landmarks placed between the two then
  // ended every run of inconsistent measurements, and the carry was declared
  // after 15.6 s). Not within the window of the jump before: false jumps
  // every few seconds (fast turns' motion blur) chained a series back to the
  // start of the run, every landmark counted as placed after the move, and
  // none could relocalize the carried robot (generated home 1092).
  if (!withinViewJumpWindow(jumps_since_utime_, t)) jumps_since_utime_ = t;
  view_jump_utime_ = std::max(view_jump_utime_, t);
  jump_checked_ = false;
  // What was inconsistent before the jump is no evidence of the move the
  // jump shows: the robot was elsewhere then. If it agrees with what comes
  // after, the disagreement began before the jump, a look-alike's or
  // drift's (generated home 1031: two landmarks of a repeated pattern,
  // measured just before a view jump that a fast turn's motion blur caused
  // and again 5 s after it, declared a kidnapping 4.9 m away).
  if (params_.kidnap.view_jump_window_s > 0)
    low_run_.erase(std::remove_if(low_run_.begin(), low_run_.end(),
                                  [t](const Implied& m) { return m.utime < t; }),
                   low_run_.end());
  if (kidnapped_ && params_.kidnap.view_jump_window_s > 0) {
    robot_was_moved_ = true;
    moved_since_utime_ = std::min(moved_since_utime_, jumps_since_utime_);
    if (params_.kidnap.retest_margin_s >= 0) retestLandmarksPlacedSince(moved_since_utime_);
  }
}

bool ParticleFilter::declareMoved(int64_t t) {
  // Not soon after a moved robot's relocalization: the views jump again as
  // it is put down and turned (the built-in kidnap scenario: three jumps
  // 8 s after the carry, none a move), and the landmarks judge that.
  if (kidnapped_ || params_.kidnap.view_jump_window_s <= 0 || recentlyRelocalizedAfterAMove(t))
    return false;
  const int64_t moved_since = jumps_since_utime_ == std::numeric_limits<int64_t>::min()
                                  ? t
                                  : std::min(jumps_since_utime_, t);
  // No landmark declared it: no evidence slots, no pose to go to (every
  // landmark placed since the jump is re-tested).
  beginKidnapping(t, estimate().mean, true, moved_since, std::nullopt);
  low_run_.clear();
  return true;
}

void ParticleFilter::beginKidnapping(int64_t t, const Pose2& held, bool moved, int64_t moved_since,
                                     const std::optional<Pose2>& at) {
  held_ = held;  // published until the relocalization is confirmed
  kidnapped_ = true;
  declared_on_view_jump_ = !at.has_value();
  kidnap_declared_utime_ = t;
  kidnap_evidence_slots_.clear();
  if (params_.kidnap.cancel_count > 0) {
    before_kidnap_ = particles_;  // shares every map: O(particles)
    before_kidnap_since_update_ = since_update_;
    before_kidnap_agreeing_ = 0;
  }
  robot_was_moved_ = moved;
  moved_since_utime_ = moved_since;
  view_jump_utime_ = jumps_since_utime_ = std::numeric_limits<int64_t>::min();  // did their work
  chooseRetestCandidates(at);
  reloc_run_.clear();
  recover_count_ = 0;
  recover_landmarks_.clear();
}

bool ParticleFilter::withinViewJumpWindow(int64_t since, int64_t t) const {
  return withinWindow(since, t, params_.kidnap.view_jump_window_s);
}

bool ParticleFilter::withinWindow(int64_t since, int64_t t, double window_s) {
  if (window_s <= 0 || since == std::numeric_limits<int64_t>::min()) return false;
  return static_cast<double>(t - since) <= window_s * 1e6;
}

bool ParticleFilter::justAfterViewJump(int64_t t) const {
  if (t < view_jump_utime_ || params_.kidnap.moved_evidence_s <= 0) return false;
  // Carried into a part not mapped yet, the robot meets its first mapped
  // landmark only when it gets back to one (generated home 1265: 9 s after
  // the jump); until one placed before the jump has agreed, that is as
  // "just after" the move as the jump itself.
  return withinWindow(view_jump_utime_, t, params_.kidnap.moved_evidence_s) ||
         (!jump_checked_ &&
          withinWindow(view_jump_utime_, t, params_.kidnap.unchecked_jump_window_s));
}

void ParticleFilter::noteInconsistent(const Observation& obs, uint32_t slot) {
  const Implied m = implied(obs, slot);
  const bool before_latest_jump =
      params_.kidnap.view_jump_window_s > 0 && obs.utime < view_jump_utime_;
  if (!before_latest_jump) pushBounded(low_run_, m);  // see noteViewJump
  if (params_.kidnap.retest_margin_s >= 0)
    pushBounded(recent_inconsistent_, m, kMaxRecentInconsistent);
}

bool ParticleFilter::recentViewJump(int64_t t) const {
  return withinViewJumpWindow(view_jump_utime_, t);
}

bool ParticleFilter::recentlyRelocalizedAfterAMove(int64_t t) const {
  return withinViewJumpWindow(moved_relocalized_utime_, t);
}

bool ParticleFilter::unresolvedViewJump(int64_t t) const {
  return recentViewJump(t) ||
         (!jump_checked_ &&
          withinWindow(view_jump_utime_, t, params_.kidnap.unchecked_jump_window_s));
}

void ParticleFilter::noteConsistentAfterJump(uint32_t slot) {
  if (placed_utime_[slot] < jumps_since_utime_) jump_checked_ = true;
}

bool ParticleFilter::endsLowRun(uint32_t slot, int64_t t) const {
  return !(unresolvedViewJump(t) && placed_utime_[slot] >= jumps_since_utime_);
}

double ParticleFilter::noteUnused(const Observation& obs) {
  const int64_t slot = slotOf(obs.landmark_id);
  if (slot < 0 || !obs.relative.isFinite() || !obs.covariance.allFinite()) return 0;
  const Eigen::Matrix3d r = measurementCovarianceOf(obs);
  const double agreement =
      agreementWith(static_cast<uint32_t>(slot), obs, r, normalizedLogWeights());
  // Inconsistent just after a view jump: kidnap evidence (KidnapParams::
  // moved_evidence_s), judged with the next measurement the filter uses.
  if (!kidnapped_ && agreement < params_.kidnap.detect_agreement && justAfterViewJump(obs.utime) &&
      !isSuspect(static_cast<uint32_t>(slot)))
    noteInconsistent(obs, static_cast<uint32_t>(slot));
  if (!kidnapped_ && agreement >= params_.kidnap.recover_agreement) {
    record(static_cast<uint32_t>(slot)).consistent += 1;
    noteConsistentAfterJump(static_cast<uint32_t>(slot));
    if (endsLowRun(static_cast<uint32_t>(slot), obs.utime)) endLowRun(obs.utime);
  }
  return agreement;
}

Eigen::Matrix3d ParticleFilter::measurementCovarianceOf(const Observation& obs) const {
  return obs.covariance.isZero(0) ? params_.measurementCovariance() : obs.covariance;
}

ParticleFilter::Implied ParticleFilter::implied(const Observation& obs, uint32_t slot) const {
  const LandmarkEstimate* lm = particles_[bestParticle()].map.find(slot);
  // s = phi (+) y, its covariance from the landmark's and y's.
  PoseWithCovariance s(toPose(lm->mean), lm->covariance);
  s.apply(obs.relative, measurementCovarianceOf(obs));
  return {obs.landmark_id, slot, obs.utime, s.pose(), s.covariance(), odometry_};
}

Pose2 ParticleFilter::carriedToNow(const Implied& m) const {
  return m.implied.compose(m.odometry.between(odometry_));
}

double ParticleFilter::clusterOffset(const Pose2& p, const Pose2& at) const {
  const KidnapParams& kp = params_.kidnap;
  return std::max(std::hypot(p.x - at.x, p.y - at.y) / kp.cluster_xy_m,
                  std::abs(wrapAngle(p.theta - at.theta)) / kp.cluster_theta_rad);
}

bool ParticleFilter::agreesWith(const Implied& m, const Pose2& at, double scale) const {
  return clusterOffset(carriedToNow(m), at) <= scale;
}

int ParticleFilter::agreeingLandmarks(const std::vector<Implied>& run, size_t i, Evidence* cluster,
                                      bool skip_wandering) const {
  const Pose2 ref = carriedToNow(run[i]);
  std::vector<int64_t> wandering;
  if (skip_wandering) {
    for (const Implied& m : run)
      if (clusterOffset(carriedToNow(m), ref) > kWanderingClusterScale &&
          std::find(wandering.begin(), wandering.end(), m.landmark_id) == wandering.end())
        wandering.push_back(m.landmark_id);
  }
  std::vector<int64_t> agreeing;
  double sx = 0, sy = 0, sc = 0, ss = 0, members = 0;  // the cluster's mean pose
  Eigen::Matrix3d covariance_sum = Eigen::Matrix3d::Zero();
  for (const Implied& m : run) {
    const Pose2 p = carriedToNow(m);
    if (clusterOffset(p, ref) > 1) continue;
    if (std::find(wandering.begin(), wandering.end(), m.landmark_id) != wandering.end()) continue;
    sx += p.x;
    sy += p.y;
    sc += std::cos(p.theta);
    ss += std::sin(p.theta);
    covariance_sum += m.covariance;
    members += 1;
    if (std::find(agreeing.begin(), agreeing.end(), m.landmark_id) == agreeing.end())
      agreeing.push_back(m.landmark_id);
  }
  if (cluster != nullptr && members > 0)
    *cluster = {{sx / members, sy / members, std::atan2(ss, sc)}, covariance_sum / members};
  return static_cast<int>(agreeing.size());
}

std::optional<ParticleFilter::Evidence> ParticleFilter::kidnapEvidence(
    const KidnapParams& kp) const {
  if (kp.detect_min_span_s > 0 && !justAfterViewJump(low_run_.front().utime) &&
      static_cast<double>(low_run_.back().utime - low_run_.front().utime) <
          kp.detect_min_span_s * 1e6)
    return std::nullopt;
  // A landmark recognised at more than one wrong place in the run (its
  // implied poses far apart, beyond kWanderingClusterScale x the cluster's
  // size) is a pattern repeated across the home, and gives no evidence
  // (tuning home 36: each landmark of one wallpaper put the robot 2-4 m
  // away, somewhere else every few seconds; two false kidnappings). Not while
  // a view jump is unresolved: a robot being carried wanders too, and one
  // carried where nothing is mapped meets its first mapped landmarks long
  // after the jump, among look-alikes (generated home 1282: 34 s after it,
  // the true landmarks alternating with their look-alikes' places).
  const bool skip_wandering = !unresolvedViewJump(low_run_.back().utime);
  // Outvoted: a busy repeated pattern, not a move (KidnapParams::detect_dissent_ratio).
  // Not near a view jump (as above), nor soon after a moved robot's
  // relocalization: the particles then stand on a few landmarks' word, and
  // when that was a look-alike's every landmark disagrees with them, the
  // true ones agreeing with each other and the rest scattered (generated
  // home 1235: relocalized 5.5 m off after a carry, three landmarks
  // agreeing on the true pose 3 s later, outvoted by four scattered ones
  // for 32 s).
  const bool dissent_outvotes = kp.detect_dissent_ratio > 0 && skip_wandering &&
                                !recentlyRelocalizedAfterAMove(low_run_.back().utime);
  for (size_t i = 0; i < low_run_.size(); ++i) {
    Evidence at;
    const int agreeing = agreeingLandmarks(low_run_, i, &at, skip_wandering);
    if (agreeing < kp.detect_landmarks) continue;
    // The drift test last: it needs the particles' estimate, O(particles).
    if (dissent_outvotes &&
        dissentingLandmarks(low_run_, carriedToNow(low_run_[i])) >=
            kp.detect_dissent_ratio * agreeing &&
        !withinDriftGate(driftMahalanobisSq(estimate(), at)))
      continue;
    return at;
  }
  return std::nullopt;
}

int ParticleFilter::dissentingLandmarks(const std::vector<Implied>& run, const Pose2& at) const {
  std::vector<int64_t> agreeing, dissenting;
  for (const Implied& m : run) {
    auto& ids = clusterOffset(carriedToNow(m), at) <= 1 ? agreeing : dissenting;
    if (std::find(ids.begin(), ids.end(), m.landmark_id) == ids.end()) ids.push_back(m.landmark_id);
  }
  return static_cast<int>(std::count_if(dissenting.begin(), dissenting.end(), [&](int64_t id) {
    return std::find(agreeing.begin(), agreeing.end(), id) == agreeing.end();
  }));
}

bool ParticleFilter::withinDriftGate(double jump_mahalanobis_sq) const {
  const double gate = params_.kidnap.drift_gate_mahalanobis_sq;
  return gate > 0 && jump_mahalanobis_sq <= gate;
}

Eigen::Matrix3d ParticleFilter::driftSpread(const PoseEstimate& from) const {
  const double k = params_.kidnap.drift_sigma_scale;
  return k * k * from.covariance;
}

double ParticleFilter::driftMahalanobisSq(const PoseEstimate& from, const Evidence& to) const {
  const Eigen::Vector3d d = jumpBetween(from.mean, to.pose);
  return d.dot((driftSpread(from) + to.covariance).ldlt().solve(d));
}

Pose2 ParticleFilter::driftCorrected(const PoseEstimate& from, const Evidence& to) const {
  // The evidence is a measurement of the pose like any other: fused with
  // the particles' mean by the Kalman gain of the two covariances (the
  // particles' spread by drift_sigma_scale, as in the gate), not adopted
  // whole. Evidence from far-away or loosely known landmarks moved the
  // robot onto their error (reporting home 1021: three landmarks, each
  // contradicted before, said 0.62 m and 12 deg; taken whole, the run's
  // error after its first 20 s went 0.099 -> 0.161 m).
  const Eigen::Matrix3d p = driftSpread(from);
  const Eigen::Vector3d c = p * (p + to.covariance).ldlt().solve(jumpBetween(from.mean, to.pose));
  return {from.mean.x + c.x(), from.mean.y + c.y(), wrapAngle(from.mean.theta + c.z())};
}

void ParticleFilter::shiftParticles(const Pose2& shift) {
  for (Particle& p : particles_) {
    p.pose = shift.compose(p.pose);
    p.anchor = shift.compose(p.anchor);
  }
}

ParticleFilter::LandmarkRecord& ParticleFilter::record(uint32_t slot) {
  if (records_.size() <= slot) records_.resize(ids_.size());
  return records_[slot];
}

bool ParticleFilter::isSuspect(uint32_t slot) const {
  const int after = params_.kidnap.suspect_after;
  if (after <= 0 || slot >= records_.size()) return false;
  // A landmark measured consistently far more often than contradicted is
  // no look-alike: it was in a run by ill luck (drift before a loop closes).
  const LandmarkRecord& r = records_[slot];
  return r.contradicted >= after && 2 * r.contradicted >= r.consistent;
}

size_t ParticleFilter::numSuspectLandmarks() const {
  size_t n = 0;
  for (uint32_t slot = 0; slot < records_.size(); ++slot) n += isSuspect(slot);
  return n;
}

void ParticleFilter::setMotionNoise(const MotionNoise& noise) {
  if (!(noise.sigma_translation >= 0 && noise.sigma_rotation >= 0))
    throw std::invalid_argument("backend filter: motion sigmas must be >= 0");
  params_.motion = noise;
}

void ParticleFilter::startAt(const Pose2& mean, const Eigen::Matrix3d& covariance) {
  if (!mean.isFinite() || !covariance.allFinite()) {
    throw std::invalid_argument("backend filter: a start pose must be finite");
  }
  const Eigen::LLT<Eigen::Matrix3d> llt(covariance);
  if (llt.info() != Eigen::Success) {
    throw std::invalid_argument("backend filter: a start covariance must be positive definite");
  }
  const Eigen::Matrix3d l = llt.matrixL();
  const uint64_t k = step_++;
  for (size_t i = 0; i < particles_.size(); ++i) {
    RandomStream rng(params_.seed, k, i, kStart);
    const double n0 = rng.normal(), n1 = rng.normal(), n2 = rng.normal();
    const Eigen::Vector3d d = l * Eigen::Vector3d(n0, n1, n2);
    Particle& p = particles_[i];
    p.pose = {mean.x + d.x(), mean.y + d.y(), wrapAngle(mean.theta + d.z())};
    p.anchor = p.pose;
    p.log_weight = 0;
    p.dual = false;
  }
}

void ParticleFilter::startKidnapped() {
  held_ = estimate().mean;
  kidnapped_ = true;
  declared_on_view_jump_ = false;
  kidnap_declared_utime_ = std::numeric_limits<int64_t>::min();  // no measurement declared it
  robot_was_moved_ = true;
  moved_since_utime_ = std::numeric_limits<int64_t>::max();  // no landmark placed from a wrong pose
  forgetBeforeKidnap();                                      // no hypothesis to go back to
  low_run_.clear();
  reloc_run_.clear();
  recover_count_ = 0;
  recover_landmarks_.clear();
}

void ParticleFilter::normalize() {
  double mx = -std::numeric_limits<double>::infinity();
  for (const Particle& p : particles_) mx = std::max(mx, p.log_weight);
  if (!std::isfinite(mx)) {
    // Every weight is zero (or NaN): nothing to infer from; start uniform.
    for (Particle& p : particles_) p.log_weight = 0;
    return;
  }
  for (Particle& p : particles_) {
    p.log_weight =
        std::isnan(p.log_weight) ? -std::numeric_limits<double>::infinity() : p.log_weight - mx;
  }
}

std::vector<double> ParticleFilter::normalizedWeights() const {
  std::vector<double> w(particles_.size());
  double sum = 0;
  for (size_t i = 0; i < w.size(); ++i) sum += w[i] = std::exp(particles_[i].log_weight);
  for (double& v : w) v /= sum;
  return w;
}

double ParticleFilter::effectiveSampleSize() const {
  const std::vector<double> w = normalizedWeights();
  double s2 = 0;
  for (double v : w) s2 += v * v;
  return 1.0 / s2;
}

size_t ParticleFilter::bestParticle() const {
  size_t best = 0;
  for (size_t i = 1; i < particles_.size(); ++i) {
    if (particles_[i].log_weight > particles_[best].log_weight) best = i;
  }
  return best;
}

void ParticleFilter::resample() {
  const size_t m = particles_.size();
  const std::vector<double> w = normalizedWeights();
  RandomStream rng(params_.seed, step_++, 0, kResample);
  const double step = 1.0 / static_cast<double>(m);
  double u = rng.uniform() * step, c = w[0];
  size_t j = 0;
  scratch_.resize(m);
  for (size_t n = 0; n < m; ++n, u += step) {
    while (u > c && j + 1 < m) c += w[++j];
    Particle& out = scratch_[n];
    out.pose = particles_[j].pose;
    out.anchor = particles_[j].anchor;
    out.map = particles_[j].map;  // one reference count, whatever the map's size
    out.dual = particles_[j].dual;
    out.log_weight = 0;
  }
  particles_.swap(scratch_);
  // Drop the old set's references now, so the survivors' paths are unique
  // again wherever only one descendant remains.
  for (Particle& p : scratch_) p.map = LandmarkMap();
}

void ParticleFilter::loadMap(const std::vector<KnownLandmark>& landmarks) {
  slots_.clear();
  ids_.clear();
  records_.clear();
  placed_utime_.clear();
  retest_pending_.clear();
  retest_candidates_.clear();
  recent_inconsistent_.clear();
  low_run_.clear();
  forgetBeforeKidnap();
  LandmarkMap map;
  for (const KnownLandmark& l : landmarks) {
    if (l.estimate.num_observations < 1 || !l.estimate.mean.allFinite() ||
        !l.estimate.covariance.allFinite() || slots_.count(l.id))
      throw std::invalid_argument(
          "backend filter: loadMap needs distinct, observed, finite landmarks");
    const auto slot = static_cast<uint32_t>(ids_.size());
    slots_.emplace(l.id, slot);
    ids_.push_back(l.id);
    map.mutableSlot(slot) = l.estimate;
    placed_utime_.push_back(std::numeric_limits<int64_t>::min());
    retest_pending_.push_back(0);
  }
  for (Particle& p : particles_) p.map = map;
}

double ParticleFilter::outlierFraction(const Observation& obs) const {
  const int64_t slot = slotOf(obs.landmark_id);
  if (slot < 0 || particles_.empty()) return 1.0;
  const Eigen::Matrix3d r = measurementCovarianceOf(obs);
  size_t outliers = 0;
  for (const Particle& p : particles_) {
    const LandmarkEstimate* lm = p.map.find(static_cast<uint32_t>(slot));
    if (lm == nullptr || innovation(*lm, p.pose, obs.relative, r).mahalanobis_sq >
                             params_.outlier.gate_mahalanobis_sq)
      ++outliers;
  }
  return static_cast<double>(outliers) / static_cast<double>(particles_.size());
}

void ParticleFilter::correctMap(const std::vector<CorrectedLandmark>& landmarks,
                                const Eigen::Matrix3d& landmark_covariance, const Pose2& shift) {
  if (!shift.isFinite() || !landmark_covariance.allFinite())
    throw std::invalid_argument("backend filter: non-finite map correction");
  LandmarkMap map = particles_[bestParticle()].map;
  for (const CorrectedLandmark& l : landmarks) {
    const int64_t slot = slotOf(l.id);
    if (slot < 0 || !l.pose.isFinite() || map.find(static_cast<uint32_t>(slot)) == nullptr)
      continue;
    LandmarkEstimate& e = map.mutableSlot(static_cast<uint32_t>(slot));
    e.mean = l.pose.vector();
    e.covariance = landmark_covariance;
  }
  for (Particle& p : particles_) p.map = map;
  shiftParticles(shift);
}

PoseEstimate ParticleFilter::estimate() const {
  const std::vector<double> w = normalizedWeights();
  double sx = 0, sy = 0, sc = 0, ss = 0;
  for (size_t i = 0; i < w.size(); ++i) {
    const Pose2& p = particles_[i].pose;
    sx += w[i] * p.x;
    sy += w[i] * p.y;
    sc += w[i] * std::cos(p.theta);
    ss += w[i] * std::sin(p.theta);
  }
  PoseEstimate e;
  e.mean = kidnapped_ ? held_ : Pose2{sx, sy, std::atan2(ss, sc)};
  double s2 = 0;
  for (size_t i = 0; i < w.size(); ++i) {
    const Pose2& p = particles_[i].pose;
    const Eigen::Vector3d d(p.x - e.mean.x, p.y - e.mean.y, wrapAngle(p.theta - e.mean.theta));
    e.covariance += w[i] * d * d.transpose();
    s2 += w[i] * w[i];
  }
  e.ess = 1.0 / s2;
  e.kidnapped = kidnapped_;
  return e;
}

}  // namespace vslam::backend
