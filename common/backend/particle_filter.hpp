#pragma once
// The SLAM back-end of the vSLAM paper (Karlsson et al., section 6): a
// Rao-Blackwellized particle filter over the robot path (FastSLAM, Montemerlo
// et al. 2002) with one Kalman filter per landmark per particle, and the
// paper's mixture proposal (6.2): nominal particles drawn from the motion
// model, dual particles drawn from the measurement model given the measured
// landmark's pose, a dynamic ratio between them, and kidnap detection that
// switches to dual particles only, with uniform importance factors.
// docs/backend.md has the model, the derivation of the importance factors and
// the parameters. No LCM, no clocks: the caller aligns measurements in time
// (backend/backend.hpp does).
//
//   ParticleFilter pf(FilterParams{...});
//   pf.predict(odometry_step);                  // every odometry step
//   UpdateReport r = pf.update({landmark_id, y, R});
//   PoseEstimate e = pf.estimate();
//
// Particle updates run on TBB (FilterParams::num_threads); every random draw
// comes from a per-particle stream (backend/rng.hpp), so a fixed seed gives
// the same result with any number of threads.

#include <tbb/task_arena.h>

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <unordered_map>
#include <vector>

#include "backend/landmark_map.hpp"
#include "backend/measurement_model.hpp"
#include "odometry/motion_model.hpp"
#include "odometry/pose2.hpp"

namespace vslam::backend {

// The mixture proposal (paper 6.2) and its dynamic ratio.
struct MixtureParams {
  // Fraction of dual particles when the measurements agree with the
  // particles (paper: "say 20" of 200), and the fraction approached as their
  // agreement falls. 0 and 0 give the basic filter (6.1).
  double dual_ratio_min = 0.1;
  double dual_ratio_max = 0.5;
  // Weight of the newest measurement in the running agreement (0, 1].
  double agreement_smoothing = 0.3;
  // Dual particles are weighted by the motion model's density of their own
  // previous pose and the odometry since; its covariance gets these floors
  // (a regularisation: the accumulated covariance of a short straight drive
  // is nearly singular across the direction of travel).
  double motion_min_sigma_xy_m = 0.02;
  double motion_min_sigma_theta_rad = 0.02;
};

// Kidnap detection (paper 6.2: "if a kidnapping scenario is detected or
// suspected, then one should generate only dual particles, and compute the
// importance factors from a uniform distribution").
// Robustness to outliers that pass the pre-filter (aliased landmarks: a
// landmark recognised at a wrong place gives streams of mutually consistent
// measurements that are metres off). The measurement likelihood is a
// mixture of the model's Gaussian and a uniform outlier density,
//   p(y | s, m) = (1 - eps) N(nu; 0, S) + eps / (area * 2 pi),
// so a measurement far from a particle's landmark estimate costs every such
// particle the same constant instead of collapsing the weights onto whichever
// particle happens to lie nearest the wrong place; and a particle's landmark
// filter is updated only when the innovation passes the Mahalanobis gate,
// so outliers do not drag the map.
struct OutlierParams {
  double probability = 0.05;           // eps; 0: plain Gaussian likelihood, no gate
  double area_m2 = 25.0;               // support of the uniform outlier density in x, y
  double gate_mahalanobis_sq = 16.27;  // chi^2_3 at 99.9%: larger innovations do not update
};

struct KidnapParams {
  // Agreement a = E_w[exp(-d^2/2)] / 2^-1.5 (d^2: Mahalanobis distance of the
  // innovation; 2^-1.5 is its expectation for consistent 3-D Gaussians), in
  // [0, 1]. detect_count measurements in a row with a < detect_agreement
  // declare a kidnapping (one with a >= recover_agreement ends the run; one
  // in between takes its landmark's earlier ones out of it); while
  // kidnapped, recover_count measurements in a row with a >= recover_agreement
  // end it.
  // A kidnapping also needs inconsistent measurements of at least
  // detect_landmarks distinct landmarks in the run of inconsistent ones in a
  // row: one aliased landmark's stream, however long, is not a kidnapping.
  double detect_agreement = 1e-3;
  int detect_count = 3;
  int detect_landmarks = 2;
  double recover_agreement = 0.1;
  int recover_count = 2;
  // A repeated pattern (wallpaper, tiles, identical doors) gives several
  // distinct landmarks that are recognised at a wrong place, so distinct
  // landmarks alone are not evidence of a kidnapping. The inconsistent run
  // must also (a) last detect_min_span_s (Observation::utime; an alias is
  // usually interrupted by a consistent measurement of something else), and
  // (b) contain detect_landmarks distinct landmarks that agree on where the
  // robot is (implied poses, carried to the present by the odometry, within
  // cluster_xy_m / cluster_theta_rad of each other).
  double detect_min_span_s = 0.0;
  double cluster_xy_m = 0.5;
  double cluster_theta_rad = 20 * M_PI / 180;
  // Landmarks whose inconsistent measurements were contradicted (the run
  // they were in ended with a consistent measurement) this many times, and
  // at least half as often as they were measured consistently, are known
  // look-alikes: they give no kidnap evidence and no dual particles.
  // 0: never.
  int suspect_after = 0;
  // The recovery needs consistent measurements of this many distinct
  // landmarks in its run: one look-alike cannot confirm a relocalization.
  int recover_landmarks = 1;
  // It is also confirmed when recover_landmarks distinct landmarks measured
  // within the last recover_window_s (0: off) agree on one pose (cluster_*),
  // the newest measurement among them: the all-dual particles, drawn from
  // one measurement at a time, test only neighbours in a row. Either way,
  // unless the robot was seen to be moved (robotWasMoved), a look-alike
  // that declared it and was contradicted before cannot confirm it alone.
  double recover_window_s = 0.0;
  // Drift or kidnapping? Evidence that passes the tests above says where the
  // robot is; if that pose is within the uncertainty the filter has, the
  // inconsistency is the drift of a path that went unobserved (a loop
  // closing), which the paper's test cannot tell from a kidnapping (6.2):
  // the particles are moved towards the evidence (by the share of the jump
  // the two covariances below give it, as a Kalman update would) and the
  // filter goes on, with no kidnapped period. "Within": the jump's squared
  // Mahalanobis distance under drift_sigma_scale^2 x the particles'
  // covariance (spread by the motion model, whose sigmas are a guess) + the
  // evidence's own covariance (its landmarks' and its measurements',
  // Observation::covariance: grown with the distance in the back-end) is at
  // most drift_gate_mahalanobis_sq.
  // 0: every such evidence is a kidnapping.
  double drift_gate_mahalanobis_sq = 0.0;
  double drift_sigma_scale = 1.0;
  // Evidence beyond the drift gate, away from a view jump, declares a
  // kidnapping only if the run's dissenters, distinct landmarks none of
  // whose implied poses agree with it (cluster_*), are fewer than
  // detect_dissent_ratio x its agreeing ones. A carried robot's landmarks
  // agree on where it is; a busy repeated pattern (wallpaper and tiles in
  // view at once) scatters its look-alikes over several wrong places, and
  // two of them agreeing there is chance (generated home 1116: four
  // landmarks 0.65-2 m off in four directions for 20 s, two of them within
  // 0.5 m of each other). Drift corrections are not held back: refusing one
  // leaves the drift to grow into a kidnapping. Nor is the correction of a
  // moved robot's relocalization (view_jump_window_s after it): made on a
  // look-alike's word, every landmark disagrees with it. 0: off.
  double detect_dissent_ratio = 0.0;
  // The hypothesis a kidnapping replaced stays alive until it is resolved:
  // the particles as they were when it was declared, carried by the
  // odometry with the motion model's noise. A kidnapping is rare and a
  // repeated pattern is not, so cancel_count measurements (of landmarks
  // mapped before it, not look-alikes) that agree with that hypothesis
  // (a >= recover_agreement), before a relocalization is confirmed, cancel
  // the kidnapping: the filter goes on from those particles, and the
  // landmarks whose measurements declared it count as contradicted. Not
  // after startKidnapped() (there is no such hypothesis). 0: never.
  int cancel_count = 0;
  // A robot carried to another place makes new landmarks there before it
  // sees an old one: they are placed from the pose it was thought to be at,
  // carried by the odometry, and after the relocalization they would give
  // evidence of another kidnapping back (and pull the map there). At a
  // relocalization, the landmarks placed since retest_margin_s before the
  // earliest recent inconsistent measurement that agrees with the detection
  // (within 2 x cluster_*: where the robot was moved to) are re-tested at
  // their next measurement: kept where they are, or moved with the
  // relocalization's shift, whichever puts the robot within 2 x cluster_*
  // of the relocalized estimate (docs/backend.md, "Landmarks placed before
  // the detection"). < 0: off.
  double retest_margin_s = 5.0;
  // A front-end saw its view jump (noteViewJump: a frame shares almost
  // nothing with the previous one although odometry says the robot barely
  // moved: carried, kidnapped). For view_jump_window_s after it, the
  // consistent measurements of landmarks placed since the jump do not end
  // a run of inconsistent ones: they were placed from the pose the robot
  // was thought to be at and agree with it by construction, so they say
  // nothing of whether it is there. Inconsistent measurements from before
  // the jump leave the run: they cannot show a move that came after them. A
  // kidnapping declared within the window, or during which a view jumps, is
  // known to be real (robotWasMoved). For as long after a moved robot's
  // relocalization, landmarks that disagree with it are not marked
  // look-alikes (endLowRun). 0: view jumps are ignored.
  double view_jump_window_s = 0.0;
  // A robot carried into a part of the home it has not mapped sees only
  // landmarks it makes there until it comes back to mapped places (generated
  // home 1190: 26 s). While no landmark placed before a view jump has agreed
  // with the particles since it, the landmarks placed since go on not ending
  // runs of inconsistent measurements, landmarks recognised at more than one
  // place still count as kidnap evidence (kidnapEvidence), and a kidnapping
  // declared is known to be real, for up to this long after the jump (at
  // least view_jump_window_s). 0: view_jump_window_s alone.
  double unchecked_jump_window_s = 0.0;
  // Right after a view jump the robot has most likely been moved, and the
  // sooner the kidnapping is declared the less time the estimate spends at
  // the old place. For moved_evidence_s after the latest jump (0: off),
  // (a) a measurement thinned by the back-end (one per landmark per
  // landmark_min_interval_s) that is inconsistent still joins the run of
  // inconsistent ones: it weighs no particle (correlated with the landmark's
  // last one) but says where the robot is, and the distinct landmarks that
  // must agree on that keep one landmark's stream from declaring anything;
  // (b) a run that began within it needs no detect_min_span_s, which is
  // there for a repeated pattern met while driving, not for a robot seen to
  // be moved. So is the first mapped landmark met after a jump still
  // unchecked (unchecked_jump_window_s: carried into a part not mapped yet),
  // however long after the jump.
  double moved_evidence_s = 0.0;
  // A view jump seen by every camera at once (Backend::noteViewJump: two
  // cameras at least) is the robot being moved, not a glitch of one view
  // (motion blur, a plain wall): the kidnapping is declared then
  // (declareMoved), not when landmarks show it. Carried where nothing is
  // mapped, the robot otherwise went on at the old place, its estimate
  // trusted, until it met mapped landmarks again (generated home 1282: for
  // 37 s, 2-9 m off). Over generated homes 1260-1289 every jump of both
  // cameras at once was a carry (15 of 15); of the one-camera jumps, two of
  // three were not.
  bool declare_on_every_view_jump = false;
};

struct FilterParams {
  int num_particles = 200;  // paper: "e.g. 200"
  MotionNoise motion;       // sigma_T, sigma_R (odometry/motion_model.hpp)
  // Sigma_vis (paper section 5): 81 cm^2 in x and y; 0.0019 in theta, read
  // as rad^2 (sigma 2.5 degrees; the paper's "deg^2" would be 0.04 degrees,
  // far below its own reported 1-2 degree measurement errors).
  double measurement_sigma_xy_m = 0.09;
  double measurement_sigma_theta_rad = 0.043589;  // sqrt(0.0019)
  // Resample when the effective sample size falls below this fraction of the particles.
  double resample_ess_fraction = 0.5;
  MixtureParams mixture;
  OutlierParams outlier;
  KidnapParams kidnap;
  uint64_t seed = 1;
  int num_threads = 0;  // TBB threads for particle updates; 0: one per core
  int grain_size = 64;  // particles per TBB task
  Pose2 initial_pose;   // every particle starts here: the map frame is the start pose

  // Throws std::invalid_argument naming the first bad field.
  void validate() const;
  Eigen::Matrix3d measurementCovariance() const;
};

struct Particle {
  Pose2 pose;             // map frame
  Pose2 anchor;           // pose at the previous update: the motion model's s_(t-1)
  double log_weight = 0;  // normalised so that the largest is 0
  LandmarkMap map;
  bool dual = false;  // drawn from the measurement model in the last update
};

// One landmark measurement, aligned to the time of the particles' poses.
struct Observation {
  int64_t landmark_id = 0;
  Pose2 relative;                                        // y: robot now in the landmark's frame
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();  // zero: FilterParams' Sigma_vis
  int64_t utime = 0;  // capture time, microseconds (kidnap persistence; 0: unknown)
};

enum class UpdateKind {
  kInitialized,  // first measurement of the landmark: added to every particle's map
  kMixture,      // nominal + dual particles
  kKidnapped,    // all dual, uniform importance (kidnapping detected or not yet recovered)
  kIgnored,      // a known look-alike's inconsistent measurement: weighs nothing
};
const char* toString(UpdateKind k);

struct UpdateReport {
  UpdateKind kind = UpdateKind::kInitialized;
  double agreement = 1;           // this measurement's agreement with the particles, [0, 1]
  double smoothed_agreement = 1;  // running agreement after this measurement
  int num_dual = 0;
  double dual_ratio = 0;  // num_dual / particles
  double ess = 0;         // effective sample size after weighting, before resampling
  bool resampled = false;
  int num_outliers = 0;          // particles for which the measurement failed the gate
  bool kidnap_detected = false;  // this measurement started a kidnapped period
  // Evidence of a pose far from the estimate (KidnapParams) was found at this
  // measurement: the jump from the estimate to it (map frame: dx, dy, dtheta),
  // its squared Mahalanobis distance under the drift covariance, and whether
  // it was taken as drift (the particles moved towards it: part of `jump`)
  // or as a kidnapping.
  bool evidence = false;
  Pose2 jump;
  double jump_mahalanobis_sq = 0;
  bool drift_corrected = false;
  Pose2 drift_shift;       // ...by which the particles moved: p -> drift_shift (+) p (map frame)
  bool recovered = false;  // this measurement ended one
  bool cancelled = false;  // ...by agreeing with the pose before it (KidnapParams::cancel_count)
  bool suspect = false;    // the landmark is a known look-alike (KidnapParams::suspect_after)
  bool deferred = false;   // first seen while kidnapped: not mapped until the relocalization
  // Placed before a kidnapping was detected and re-tested after the
  // relocalization (KidnapParams::retest_margin_s): this measurement put the
  // robot at the estimate from its place moved by the relocalization's
  // shift, and it was moved there.
  bool moved = false;
};

struct PoseEstimate {
  // Weighted mean (circular mean of theta); while kidnapped, the pose held
  // from before the kidnapping, carried by the odometry, until the
  // relocalization is confirmed (the all-dual particles jump from one
  // measured landmark to the next), with the particles' spread about it as
  // covariance.
  Pose2 mean;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  double ess = 0;
  bool kidnapped = false;
};

class ParticleFilter {
 public:
  explicit ParticleFilter(FilterParams params);
  ~ParticleFilter();
  ParticleFilter(const ParticleFilter&) = delete;
  ParticleFilter& operator=(const ParticleFilter&) = delete;

  // Motion model (paper eq. 1): every particle moves by the odometry step
  // with its own noise draw. step: robot frame at the previous reading.
  void predict(const Pose2& step);
  // One landmark measurement (paper eq. 2): initialises the landmark on its
  // first measurement, otherwise weights the particles (mixture proposal),
  // updates each particle's Kalman filter of the landmark, and resamples when
  // the effective sample size is low.
  UpdateReport update(const Observation& obs);
  // A measurement of a known landmark that the caller does not use for an
  // update (thinned: correlated with the last one used): no weights or maps
  // change, but if the particles explain it (agreement >= recover_agreement)
  // it ends a run of inconsistent measurements, as an update would: what the
  // robot sees has a consistent explanation, so the run is no kidnap
  // evidence. An inconsistent one extends the run only just after a view
  // jump (KidnapParams::moved_evidence_s). Returns the agreement (0 for an
  // unknown landmark).
  double noteUnused(const Observation& obs);
  // A camera's view jumped at t (KidnapParams::view_jump_window_s).
  void noteViewJump(int64_t t);
  // The robot was moved at t (every camera's view jumped:
  // KidnapParams::declare_on_every_view_jump): the kidnapping is declared
  // as if landmarks had shown it, but with no pose to go to. The estimate
  // published is held (moved by the odometry) and every measurement draws
  // all particles until distinct landmarks agree on a pose (recover_*; by
  // the window's cluster, one landmark more than recover_landmarks, since
  // none declared it); measurements that agree with the pose before it
  // cancel it (cancel_count). After noteViewJump(t). Returns whether it
  // was declared (not if kidnapped already, nor within view_jump_window_s
  // of a moved robot's relocalization).
  bool declareMoved(int64_t t);
  // Systematic resampling, whatever the effective sample size. O(particles).
  void resample();
  // Starts every particle from the same known map (e.g. landmark poses saved
  // from an earlier run, or a benchmark's): the particles share it, so this
  // costs O(landmarks + particles). Replaces any landmarks seen so far.
  struct KnownLandmark {
    int64_t id;
    LandmarkEstimate estimate;  // num_observations >= 1
  };
  void loadMap(const std::vector<KnownLandmark>& landmarks);
  // Map correction (docs/backend.md, "Map correction"): every particle takes
  // the best particle's map with the given landmarks set to the given poses
  // and covariance (one shared map: O(landmarks + particles)), and its pose
  // and anchor moved by `shift` (a map-frame transform, applied on the left).
  // Landmarks the filter has not seen are skipped; weights are kept.
  struct CorrectedLandmark {
    int64_t id;
    Pose2 pose;
  };
  void correctMap(const std::vector<CorrectedLandmark>& landmarks,
                  const Eigen::Matrix3d& landmark_covariance, const Pose2& shift);

  // The fraction of particles for which the observation of a known landmark
  // is beyond the outlier gate (1 for an unknown landmark), without any update.
  double outlierFraction(const Observation& obs) const;

  PoseEstimate estimate() const;
  double effectiveSampleSize() const;
  bool kidnapped() const { return kidnapped_; }
  // The current (or last) kidnapping is known to be real, the robot moved:
  // a front-end's view jumped within view_jump_window_s before it was
  // declared or while it lasted, or the filter started kidnapped
  // (startKidnapped: a start from an unknown pose). A repeated pattern's
  // false alarm comes with no view jump, and neither does a loop closure
  // after a long unobserved drift, which the kidnap test cannot tell from a
  // short carry (paper 6.2).
  bool robotWasMoved() const { return robot_was_moved_; }
  // A robot known to have been moved relocalized no more than
  // view_jump_window_s before t.
  bool recentlyRelocalizedAfterAMove(int64_t t) const;
  // Global relocalization (e.g. a saved map and an unknown start pose):
  // all-dual until the measurements confirm a pose.
  void startKidnapped();
  // A start at a known pose in the map (a restarted back-end resuming where
  // the robot was): the particles drawn from N(mean, covariance), equal
  // weights. Before the first odometry. Throws std::invalid_argument unless
  // mean is finite and covariance positive definite.
  void startAt(const Pose2& mean, const Eigen::Matrix3d& covariance);
  // Landmarks currently marked as look-alikes (KidnapParams::suspect_after).
  size_t numSuspectLandmarks() const;
  bool isLookAlike(int64_t landmark_id) const {
    const int64_t slot = slotOf(landmark_id);
    return slot >= 0 && isSuspect(static_cast<uint32_t>(slot));
  }
  double lastDualRatio() const { return last_dual_ratio_; }
  const std::vector<Particle>& particles() const { return particles_; }
  // For tests and tools that set up a particle set by hand.
  std::vector<Particle>& mutableParticles() { return particles_; }
  std::vector<double> normalizedWeights() const;
  size_t bestParticle() const;
  size_t numLandmarks() const { return ids_.size(); }
  int64_t landmarkId(uint32_t slot) const { return ids_[slot]; }
  // The slot of a landmark id, or -1 if the filter has not seen it.
  int64_t slotOf(int64_t landmark_id) const;
  const FilterParams& params() const { return params_; }
  // The motion model's noise from now on (odometry calibration).
  void setMotionNoise(const MotionNoise& noise);

 private:
  template <class F>
  void forEachParticle(F&& f) const;
  template <class F>
  void forEachIndex(size_t m, F&& f) const;
  UpdateReport initialize(uint32_t slot, const Observation& obs, const Eigen::Matrix3d& r);
  void normalize();

  FilterParams params_;
  std::unique_ptr<tbb::task_arena> arena_;
  std::vector<Particle> particles_;
  std::vector<Particle> scratch_;        // resampling target, reused
  std::vector<Innovation> innovations_;  // update()'s, from agreementWith to drawAndWeigh
  std::unordered_map<int64_t, uint32_t> slots_;
  std::vector<int64_t> ids_;
  uint64_t step_ = 0;  // counts predict/update/resample calls: the random streams' step
  // A measurement's implied robot pose (best particle's landmark), its
  // covariance (the landmark's and the measurement's), and the odometry then.
  struct Implied {
    int64_t landmark_id;
    uint32_t slot;
    int64_t utime;
    Pose2 implied;
    Eigen::Matrix3d covariance;
    Pose2 odometry;
  };
  Implied implied(const Observation& obs, uint32_t slot) const;
  // Where a cluster of implied poses, carried to now, says the robot is,
  // and how well: the mean of its members' covariances (measurements of one
  // landmark share its error, so their number does not shrink it).
  struct Evidence {
    Pose2 pose;
    Eigen::Matrix3d covariance;
  };
  // Distinct landmarks of `run` whose implied poses, carried to now by the
  // odometry, agree with that of run[i] (KidnapParams::cluster_*); with
  // skip_wandering, not those with another implied pose in `run` far from
  // it (kWanderingClusterScale).
  int agreeingLandmarks(const std::vector<Implied>& run, size_t i, Evidence* cluster = nullptr,
                        bool skip_wandering = false) const;
  // Distinct landmarks of `run` none of whose implied poses, carried to
  // now, agree with `at` (KidnapParams::cluster_*).
  int dissentingLandmarks(const std::vector<Implied>& run, const Pose2& at) const;
  // Evidence this close to the estimate is drift, not a kidnapping
  // (KidnapParams::drift_gate_mahalanobis_sq).
  bool withinDriftGate(double jump_mahalanobis_sq) const;
  // Where the inconsistent run says the robot is, if it is evidence enough.
  std::optional<Evidence> kidnapEvidence(const KidnapParams& kp) const;
  // The particles' log weights, normalised so that their exponentials sum to 1.
  std::vector<double> normalizedLogWeights() const;
  // The particles' agreement with a measurement of the landmark in `slot`,
  // given normalizedLogWeights(); each particle's innovation into
  // *innovations if given.
  double agreementWith(uint32_t slot, const Observation& obs, const Eigen::Matrix3d& r,
                       const std::vector<double>& log_w,
                       std::vector<Innovation>* innovations = nullptr) const;
  // The same for another particle set (the hypothesis a kidnapping replaced).
  double agreementWith(const std::vector<Particle>& particles, uint32_t slot,
                       const Observation& obs, const Eigen::Matrix3d& r,
                       const std::vector<double>& log_w,
                       std::vector<Innovation>* innovations) const;
  // A landmark placed before a kidnapping's detection, re-tested after the
  // relocalization (KidnapParams::retest_margin_s): kept, or moved by
  // retest_shift_ in every particle (returns true) if this measurement
  // puts the robot at the estimate from there instead; either resolves it.
  bool retest(uint32_t slot, const Observation& obs);
  // A measurement's implied pose carried to the present by the odometry since.
  Pose2 carriedToNow(const Implied& m) const;
  // How far `p` is from `at` in units of KidnapParams::cluster_*: the larger
  // of the distance over cluster_xy_m and the angle over cluster_theta_rad.
  double clusterOffset(const Pose2& p, const Pose2& at) const;
  // Whether a measurement's implied pose, carried to now, is within scale x
  // cluster_* of `at`.
  bool agreesWith(const Implied& m, const Pose2& at, double scale) const;
  // At a kidnap detection with evidence of the pose `at` (none: declared
  // on a view jump): the landmarks to re-test after the relocalization.
  void chooseRetestCandidates(const std::optional<Pose2>& at);
  // Declares a kidnapping at t (by evidence of `at`, or by declareMoved):
  // the estimate `held` is published, the particles as they are kept to
  // cancel it, the view jumps' series done, the re-test candidates chosen
  // and the relocalization's window emptied.
  void beginKidnapping(int64_t t, const Pose2& held, bool moved, int64_t moved_since,
                       const std::optional<Pose2>& at);
  // Adds the landmarks placed at or after `from` to those re-tested.
  void retestLandmarksPlacedSince(int64_t from);
  // While kidnapped: does this measurement cancel the kidnapping
  // (KidnapParams::cancel_count)? If so, the particles are the hypothesis
  // it replaced again.
  bool cancelKidnapping(uint32_t slot, const Observation& obs, const Eigen::Matrix3d& r);
  void forgetBeforeKidnap();
  // update()'s step 3, the mixture proposal: n_dual particles drawn from the
  // measurement (all if all_dual: uniform weights), the others kept from the
  // motion model, each weighed and its landmark's Kalman filter updated
  // unless the measurement is an outlier for it. prior_innovations: the
  // particles' innovations before the draw (agreementWith's), if they have
  // not moved since. Returns the outliers.
  int drawAndWeigh(uint32_t slot, const Pose2& y, const Eigen::Matrix3d& r,
                   const std::vector<double>& log_w, uint64_t n_dual, bool all_dual, uint64_t k,
                   const std::vector<Innovation>* prior_innovations);
  // The report of a measurement that changed no weight (a new landmark, or
  // one left unused while kidnapped).
  UpdateReport unweighedReport(UpdateKind kind, double agreement) const;
  // Kidnap detection and recovery for a measurement of the landmark in
  // `slot` with this agreement (update()'s step 2): fills rep's kidnap
  // fields, moves the particles on drift; returns whether this update draws
  // every particle from the measurement (kidnapped), and sets
  // *confirmed_by_cluster if the recovery window confirmed a relocalization
  // (it ends after that draw).
  bool updateMode(uint32_t slot, const Observation& obs, double agreement, bool suspect,
                  UpdateReport* rep, bool* confirmed_by_cluster);
  // A consistent measurement of `slot`: if placed before the latest series
  // of view jumps, the jump is checked (unresolvedViewJump).
  void noteConsistentAfterJump(uint32_t slot);
  // A consistent measurement (at time t) ends the run of inconsistent ones:
  // every landmark in it was seen somewhere it is not.
  void endLowRun(int64_t t);
  // Whether a consistent measurement of `slot` at t may end the run: not if
  // the landmark was placed since the first of a series of view jumps whose
  // latest is unresolved at t (unresolvedViewJump).
  bool endsLowRun(uint32_t slot, int64_t t) const;
  // since (min: never) is no more than view_jump_window_s (0: off) before t.
  bool withinViewJumpWindow(int64_t since, int64_t t) const;
  // t is no more than window_s (0: never) after since (min: never).
  static bool withinWindow(int64_t since, int64_t t, double window_s);
  // A view jump noted no more than view_jump_window_s before t.
  bool recentViewJump(int64_t t) const;
  // recentViewJump, or no more than unchecked_jump_window_s before t with
  // no landmark placed before it consistent since.
  bool unresolvedViewJump(int64_t t) const;
  // t is no more than moved_evidence_s after the latest view jump, or the
  // jump is still unchecked (unresolvedViewJump's second case).
  bool justAfterViewJump(int64_t t) const;
  // An inconsistent measurement of a landmark that is not a look-alike: in
  // the run that may declare a kidnapping, and among those a relocalization
  // re-tests landmarks against.
  void noteInconsistent(const Observation& obs, uint32_t slot);
  // Takes the landmark's measurements out of the run of inconsistent ones
  // (a newer one of it was neither consistent nor inconsistent).
  void dropFromLowRun(uint32_t slot);
  // The particles' covariance scaled by drift_sigma_scale^2: their side of
  // the drift covariance (KidnapParams).
  Eigen::Matrix3d driftSpread(const PoseEstimate& from) const;
  // The jump from the estimate to the evidence under the drift covariance
  // (KidnapParams): the particles' spread, scaled, and the evidence's own.
  double driftMahalanobisSq(const PoseEstimate& from, const Evidence& to) const;
  // The pose a drift correction moves the estimate to: the evidence fused
  // with the estimate under the same two covariances.
  Pose2 driftCorrected(const PoseEstimate& from, const Evidence& to) const;
  // The observation's covariance (FilterParams' Sigma_vis if it has none).
  Eigen::Matrix3d measurementCovarianceOf(const Observation& obs) const;
  void shiftParticles(const Pose2& shift);
  bool isSuspect(uint32_t slot) const;
  // One of the landmarks whose measurements declared the current kidnapping.
  bool isKidnapEvidence(uint32_t slot) const;
  // The landmark was in an inconsistent run that was contradicted.
  bool wasContradicted(uint32_t slot) const;

  // Per slot: the capture time of the measurement that placed it, and
  // whether it is to be re-tested (retest); the shift of the relocalization
  // that made it so; while kidnapped, the slots to re-test after it.
  std::vector<int64_t> placed_utime_;
  std::vector<char> retest_pending_;
  Pose2 retest_shift_;
  std::vector<uint32_t> retest_candidates_;
  // Recent inconsistent measurements (not only the current run: consistent
  // measurements of landmarks made after the robot was moved interrupt it),
  // bounded: where a kidnapping began.
  std::vector<Implied> recent_inconsistent_;

  bool kidnapped_ = false;
  std::vector<Implied> low_run_;  // the current run of inconsistent measurements
  int64_t view_jump_utime_ = std::numeric_limits<int64_t>::min();  // the latest view jump
  // The first of the latest series of view jumps, each within
  // view_jump_window_s of the first.
  int64_t jumps_since_utime_ = std::numeric_limits<int64_t>::min();
  // A landmark placed before the latest series of view jumps was
  // consistent after it (KidnapParams::unchecked_jump_window_s).
  bool jump_checked_ = true;
  bool robot_was_moved_ = false;        // robotWasMoved()
  bool declared_on_view_jump_ = false;  // the kidnapping was declareMoved's
  // While kidnapped with robot_was_moved_ from a view jump: the first jump
  // of its series, when the robot was moved. Landmarks placed since were
  // placed from the pose it was thought to be at (max: none known).
  int64_t moved_since_utime_ = std::numeric_limits<int64_t>::max();
  // The latest relocalization of a robot known to have been moved.
  int64_t moved_relocalized_utime_ = std::numeric_limits<int64_t>::min();
  // While kidnapped: the measurements of the last recover_window_s, from
  // those that declared it (at kidnap_declared_utime_) on.
  std::vector<Implied> reloc_run_;
  int64_t kidnap_declared_utime_ = 0;
  // Per slot: measurements that agreed (a >= recover_agreement), and
  // inconsistent runs it was in that ended with a consistent measurement.
  struct LandmarkRecord {
    int consistent = 0;
    int contradicted = 0;
  };
  LandmarkRecord& record(uint32_t slot);
  std::vector<LandmarkRecord> records_;
  int recover_count_ = 0;
  std::vector<int64_t> recover_landmarks_;  // distinct landmarks in the recovering run
  Pose2 odometry_;                          // the predict steps composed: the run's own frame
  Pose2 held_;                              // published while kidnapped
  // While kidnapped (not after startKidnapped): the particles when it was
  // declared, carried by the odometry; the odometry since their last update;
  // the landmarks whose measurements declared it (isKidnapEvidence); the
  // measurements that agreed with them since.
  std::vector<Particle> before_kidnap_;
  PoseWithCovariance before_kidnap_since_update_;
  std::vector<uint32_t> kidnap_evidence_slots_;
  int before_kidnap_agreeing_ = 0;
  double smoothed_agreement_ = 1;
  double last_dual_ratio_ = 0;
  PoseWithCovariance since_update_;  // odometry since the previous update, anchor frame
};

}  // namespace vslam::backend
