// The back-end's inputs: the pre-filter's verdicts (paper section 5), and the
// odometry and measurement handling of backend::Backend (duplicated, lost,
// out-of-order and non-finite odometry; measurements moved to the particles'
// time; bad measurements counted, never fatal).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "backend/backend.hpp"
#include "backend/measurement_model.hpp"
#include "backend/prefilter.hpp"

using namespace vslam;
using namespace vslam::backend;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

PrefilterInput good() { return {{0.3, -0.1, 0.05}, 1.0, 25, 0.01}; }

BackendParams params(int particles, double sigma) {
  BackendParams p;
  p.filter.num_particles = particles;
  p.filter.motion = {sigma, sigma};
  p.filter.mixture.dual_ratio_min = 0;
  p.filter.mixture.dual_ratio_max = 0;
  return p;
}

constexpr int64_t kT0 = 1700000000000000LL;
int64_t at(double s) { return kT0 + static_cast<int64_t>(s * 1e6); }

// A robot driving a circle: cumulative odometry at 50 Hz.
OdometryReading reading(int64_t seq) {
  const double t = static_cast<double>(seq) / 50.0;
  // Arc of radius 2 m at 0.3 m/s.
  const double a = 0.3 * t / 2.0;
  return {at(t), seq, {2.0 * std::sin(a), 2.0 * (1 - std::cos(a)), wrapAngle(a)}};
}

// A measurement at odometry reading `seq` of landmark `id`, made at reading
// `landmark_seq` of that circle: exact, or composed with `offset` (a
// look-alike's).
MeasurementInput circleMeasurement(int64_t id, int64_t landmark_seq, int64_t seq,
                                   const Pose2& offset = {}) {
  MeasurementInput m;
  m.landmark_id = id;
  m.utime = reading(seq).utime;
  m.relative = reading(landmark_seq).pose.between(reading(seq).pose).compose(offset);
  m.proj_err_rms_px = 1;
  m.num_points = 30;
  return m;
}

// A back-end driven along the circle of reading(), reading by reading.
struct OnTheCircle {
  explicit OnTheCircle(const BackendParams& p) : be(p) {}
  void driveTo(int64_t last) {
    for (; seq <= last; ++seq) be.addOdometry(reading(seq));
  }
  Backend be;
  int64_t seq = 0;
};

}  // namespace

// --- Pre-filter -----------------------------------------------------------------

TEST(Prefilter, PaperDefaultsAndBoundaries) {
  const PrefilterParams p;
  EXPECT_EQ(p.max_proj_err_rms_px, 3.0);
  EXPECT_EQ(p.min_num_points, 10);
  EXPECT_EQ(p.max_slope, 0.1);
  PrefilterInput m = good();
  EXPECT_EQ(prefilter(m), MeasurementStatus::kAccepted);
  m.proj_err_rms_px = 3.0;  // the bound passes
  EXPECT_EQ(prefilter(m), MeasurementStatus::kAccepted);
  m.proj_err_rms_px = 3.0001;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedProjErr);
  m = good();
  m.num_points = 10;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kAccepted);
  m.num_points = 9;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedNumPoints);
  m = good();
  m.slope = 0.1;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kAccepted);
  m.slope = 0.1001;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedSlope);
  m.slope = kInf;  // tilted 90 degrees or more
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedSlope);
}

TEST(Prefilter, FirstFailedTestInThePapersOrder) {
  PrefilterInput m = good();
  m.proj_err_rms_px = 5;
  m.num_points = 3;
  m.slope = 0.5;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedProjErr);
  m.proj_err_rms_px = 1;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedNumPoints);
  m.num_points = 30;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedSlope);
}

TEST(Prefilter, InvalidInputs) {
  for (int field = 0; field < 6; ++field) {
    PrefilterInput m = good();
    switch (field) {
      case 0:
        m.relative.x = kNaN;
        break;
      case 1:
        m.relative.theta = kInf;
        break;
      case 2:
        m.proj_err_rms_px = kNaN;
        break;
      case 3:
        m.slope = kNaN;
        break;
      case 4:
        m.num_points = -1;
        break;
      case 5:
        m.proj_err_rms_px = -0.5;
        break;
    }
    EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedInvalid) << "field " << field;
  }
}

TEST(Prefilter, CustomAcceptanceRegion) {
  PrefilterParams wide;
  wide.max_proj_err_rms_px = 6;
  wide.min_num_points = 6;
  wide.max_slope = 0.3;
  PrefilterInput m = good();
  m.proj_err_rms_px = 5;
  m.num_points = 7;
  m.slope = 0.2;
  EXPECT_EQ(prefilter(m), MeasurementStatus::kRejectedProjErr);
  EXPECT_EQ(prefilter(m, wide), MeasurementStatus::kAccepted);
  wide.min_num_points = -1;
  EXPECT_THROW(wide.validate(), std::invalid_argument);
}

TEST(Prefilter, VerdictsAreCountedByTheBackend) {
  Backend be(params(10, 0.01));
  be.addOdometry(reading(0));
  MeasurementInput m;
  m.utime = at(0);
  m.landmark_id = 5;
  m.relative = {0.1, 0, 0};
  m.num_points = 30;
  m.proj_err_rms_px = 1;
  EXPECT_EQ(be.addMeasurement(m).status, MeasurementStatus::kAccepted);
  m.proj_err_rms_px = 4;
  const MeasurementResult r = be.addMeasurement(m);
  EXPECT_EQ(r.status, MeasurementStatus::kRejectedProjErr);
  EXPECT_EQ(r.use, MeasurementUse::kRejected);
  m.proj_err_rms_px = 1;
  m.slope = kNaN;
  EXPECT_EQ(be.addMeasurement(m).status, MeasurementStatus::kRejectedInvalid);
  const BackendCounters& c = be.counters();
  EXPECT_EQ(c.status[static_cast<int>(MeasurementStatus::kAccepted)], 1);
  EXPECT_EQ(c.status[static_cast<int>(MeasurementStatus::kRejectedProjErr)], 1);
  EXPECT_EQ(c.status[static_cast<int>(MeasurementStatus::kRejectedInvalid)], 1);
  EXPECT_EQ(c.use[static_cast<int>(MeasurementUse::kUsed)], 1);
  EXPECT_EQ(be.filter().numLandmarks(), 1u);  // only the accepted one reached the filter
}

// --- Odometry -------------------------------------------------------------------

TEST(BackendOdometry, DuplicatedAndOutOfOrderReadingsChangeNothing) {
  // The same seed, the same readings: once clean, once with every reading
  // duplicated and some arriving late. The particle sets must be identical.
  Backend clean(params(50, 0.05));
  Backend messy(params(50, 0.05));
  for (int64_t s = 0; s <= 200; ++s) clean.addOdometry(reading(s));
  int ignored = 0;
  for (int64_t s = 0; s <= 200; ++s) {
    messy.addOdometry(reading(s));
    ignored += messy.addOdometry(reading(s)) == OdometryIncrements::Outcome::kStale;
    if (s >= 20 && s % 10 == 0) {
      ignored += messy.addOdometry(reading(s - 3)) == OdometryIncrements::Outcome::kStale;
    }
  }
  EXPECT_EQ(ignored, 201 + 19);
  EXPECT_EQ(messy.counters().odometry_ignored, 220);
  for (size_t i = 0; i < 50; ++i) {
    const Pose2& a = clean.filter().particles()[i].pose;
    const Pose2& b = messy.filter().particles()[i].pose;
    EXPECT_EQ(a.x, b.x);
    EXPECT_EQ(a.y, b.y);
    EXPECT_EQ(a.theta, b.theta);
  }
  // The mean follows the odometry (it started at the map origin).
  const Pose2 e = clean.filter().estimate().mean;
  const Pose2 o = reading(200).pose;
  EXPECT_LT(std::hypot(e.x - o.x, e.y - o.y), 0.05);
}

TEST(BackendOdometry, LostReadingsLoseNoMotion) {
  // Noise-free: every second reading lost, and a gap of 30; the pose still
  // equals the odometry's, since steps are differences of cumulative poses.
  Backend be(params(5, 0.0));
  for (int64_t s = 0; s <= 300; s += (s > 100 && s < 130) ? 30 : 2) be.addOdometry(reading(s));
  be.addOdometry(reading(301));
  const Pose2 e = be.filter().estimate().mean;
  const Pose2 o = reading(301).pose;
  EXPECT_NEAR(e.x, o.x, 1e-9);
  EXPECT_NEAR(e.y, o.y, 1e-9);
  EXPECT_NEAR(e.theta, o.theta, 1e-9);
}

TEST(BackendOdometry, NonFiniteAndImplausibleReadingsAreIgnored) {
  Backend be(params(5, 0.0));
  be.addOdometry(reading(0));
  be.addOdometry(reading(1));
  OdometryReading bad = reading(2);
  bad.pose.x = kNaN;
  EXPECT_EQ(be.addOdometry(bad), OdometryIncrements::Outcome::kInvalid);
  OdometryReading jump = reading(3);
  jump.pose.x += 50;  // 50 m in 40 ms: a fault, not motion
  EXPECT_EQ(be.addOdometry(jump), OdometryIncrements::Outcome::kImplausible);
  const Pose2 before = be.filter().estimate().mean;
  EXPECT_LT(std::hypot(before.x - reading(1).pose.x, before.y - reading(1).pose.y), 1e-9);
  EXPECT_EQ(be.counters().odometry_ignored, 2);
  // Motion continues from the new reference.
  OdometryReading next = reading(4);
  next.pose.x += 50;
  EXPECT_EQ(be.addOdometry(next), OdometryIncrements::Outcome::kStep);
  EXPECT_TRUE(be.filter().estimate().mean.isFinite());
}

// --- Measurements in time ---------------------------------------------------------

TEST(BackendMeasurements, AreMovedToTheParticlesTime) {
  // Noise-free odometry; a landmark initialised at t = 1 s from the exact
  // relative pose; at t = 3 s a measurement of the robot as it was at 2 s
  // arrives. Moved by the odometry between 2 s and 3 s it agrees perfectly;
  // taken as if it were of now, it would not.
  const Pose2 phi{2.5, 0.5, 0.3};  // landmark pose in the map = odom frame
  auto measurementAt = [&](double t) {
    MeasurementInput m;
    m.utime = at(t);
    m.landmark_id = 77;
    m.relative = predictMeasurement(reading(static_cast<int64_t>(t * 50)).pose, phi);
    m.proj_err_rms_px = 1;
    m.num_points = 30;
    return m;
  };
  for (bool aligned : {true, false}) {
    Backend be(params(20, 0.0));
    for (int64_t s = 0; s <= 50; ++s) be.addOdometry(reading(s));
    ASSERT_EQ(be.addMeasurement(measurementAt(1.0)).update.kind, UpdateKind::kInitialized);
    for (int64_t s = 51; s <= 150; ++s) be.addOdometry(reading(s));
    MeasurementInput m = measurementAt(2.0);
    if (!aligned) m.utime = at(3.0);
    const MeasurementResult r = be.addMeasurement(m);
    ASSERT_EQ(r.use, MeasurementUse::kUsed);
    if (aligned) {
      EXPECT_NEAR(r.update.agreement, 1.0, 1e-6);
    } else {
      EXPECT_LT(r.update.agreement, 0.05);  // 30 cm and 9 degrees off
    }
  }
}

TEST(BackendMeasurements, OutsideTheOdometryHistoryOrBeforeAnyOdometry) {
  BackendParams p = params(5, 0.0);
  p.max_measurement_age_s = 2.0;
  p.max_measurement_lead_s = 0.5;
  Backend be(p);
  MeasurementInput m;
  m.landmark_id = 1;
  m.relative = {0.2, 0, 0};
  m.proj_err_rms_px = 1;
  m.num_points = 30;
  m.utime = at(0);
  EXPECT_EQ(be.addMeasurement(m).use, MeasurementUse::kNoOdometry);
  for (int64_t s = 0; s <= 250; ++s) be.addOdometry(reading(s));  // 0 .. 5 s
  m.utime = at(1.0);                                              // older than the 2 s kept
  EXPECT_EQ(be.addMeasurement(m).use, MeasurementUse::kTooOld);
  m.utime = at(6.0);  // 1 s ahead of the newest odometry
  EXPECT_EQ(be.addMeasurement(m).use, MeasurementUse::kTooNew);
  m.utime = at(5.2);  // a little ahead: taken as of the newest odometry
  EXPECT_EQ(be.addMeasurement(m).use, MeasurementUse::kUsed);
  m.landmark_id = -3;
  m.utime = at(4.5);
  EXPECT_EQ(be.addMeasurement(m).use, MeasurementUse::kInvalidLandmark);
  const BackendCounters& c = be.counters();
  EXPECT_EQ(c.use[static_cast<int>(MeasurementUse::kNoOdometry)], 1);
  EXPECT_EQ(c.use[static_cast<int>(MeasurementUse::kTooOld)], 1);
  EXPECT_EQ(c.use[static_cast<int>(MeasurementUse::kTooNew)], 1);
  EXPECT_EQ(c.use[static_cast<int>(MeasurementUse::kInvalidLandmark)], 1);
  EXPECT_EQ(c.use[static_cast<int>(MeasurementUse::kUsed)], 1);
}

TEST(BackendMeasurements, ThinnedToOnePerLandmarkPerInterval) {
  BackendParams p = params(5, 0.0);
  p.landmark_min_interval_s = 0.5;
  Backend be(p);
  for (int64_t s = 0; s <= 250; ++s) be.addOdometry(reading(s));  // 0 .. 5 s
  MeasurementInput m;
  m.landmark_id = 1;
  m.relative = {0.2, 0, 0};
  m.proj_err_rms_px = 1;
  m.num_points = 30;
  m.utime = at(3.0);
  EXPECT_EQ(be.addMeasurement(m).use, MeasurementUse::kUsed);
  m.utime = at(3.2);
  EXPECT_EQ(be.addMeasurement(m).use, MeasurementUse::kThinned);
  m.landmark_id = 2;  // another landmark is not affected
  EXPECT_EQ(be.addMeasurement(m).use, MeasurementUse::kUsed);
  m.landmark_id = 1;
  m.utime = at(3.5);  // the interval since the last used one (3.0), not the thinned one
  EXPECT_EQ(be.addMeasurement(m).use, MeasurementUse::kUsed);
  EXPECT_EQ(be.counters().use[static_cast<int>(MeasurementUse::kThinned)], 1);
}

TEST(BackendMeasurements, WhileRelocalizingAMovedRobotNoneAreThinned) {
  // Landmarks 1 and 2 mapped on the circle; the filter starts again from an
  // unknown pose (as a start in a saved map: the robot was moved). Until it
  // relocalizes, every measurement goes to it, however soon after the last
  // one of its landmark: two landmarks in a row confirm the pose within
  // 0.1 s, where one per landmark per 2 s would take seconds. Relocalized,
  // they are thinned again.
  BackendParams p = params(50, 0.01);
  p.landmark_min_interval_s = 2.0;
  p.filter.kidnap.recover_landmarks = 2;
  OnTheCircle c(p);
  Backend& be = c.be;
  c.driveTo(50);
  be.addMeasurement(circleMeasurement(1, 0, 50));
  be.addMeasurement(circleMeasurement(2, 25, 50));
  be.filter().startKidnapped();
  ASSERT_TRUE(be.filter().robotWasMoved());
  bool recovered = false;
  for (int64_t s = 60; s < 70 && !recovered; ++s) {
    c.driveTo(s);
    const MeasurementResult r =
        be.addMeasurement(circleMeasurement(s % 2 ? 1 : 2, s % 2 ? 0 : 25, s));
    EXPECT_EQ(r.use, MeasurementUse::kUsed) << "reading " << s;
    recovered = r.update.recovered;
  }
  ASSERT_TRUE(recovered) << "not relocalized within 0.2 s";
  EXPECT_FALSE(be.filter().kidnapped());
  c.driveTo(c.seq + 1);
  EXPECT_EQ(be.addMeasurement(circleMeasurement(1, 0, c.seq - 1)).use, MeasurementUse::kThinned);
}

TEST(BackendMeasurements, MeasurementCovarianceGrowsWithDistance) {
  // Two backends, one with growth; a far measurement of a landmark whose
  // particles disagree with it by 20 cm: the growing covariance is less sure.
  auto agreementFor = [](double per_m) {
    BackendParams p = params(20, 0.0);
    p.measurement_sigma_xy_per_m = per_m;
    p.filter.outlier.probability = 0;
    Backend be(p);
    for (int64_t s = 0; s <= 50; ++s) be.addOdometry(reading(s));
    MeasurementInput m;
    m.landmark_id = 1;
    m.relative = {3.0, 0, 0};
    m.proj_err_rms_px = 1;
    m.num_points = 30;
    m.utime = at(0.9);
    be.addMeasurement(m);
    m.relative = {3.2, 0, 0};
    m.utime = at(0.95);
    return be.addMeasurement(m).update.agreement;
  };
  EXPECT_GT(agreementFor(0.1), agreementFor(0.0));
}

TEST(BackendMeasurements, ALandmarkFirstSeenWhileKidnappedIsMappedAtTheRelocalization) {
  // On a circle with exact odometry: landmarks 1 and 2 are mapped, then the
  // filter is lost. Landmark 3 is first seen while it is: deferred, not
  // mapped. Landmarks 1 and 2 relocalize it; landmark 3 is then mapped from
  // its last measurement carried to now by the odometry, where it is: its
  // next measurement agrees with the particles.
  BackendParams p = params(50, 0.01);
  p.filter.kidnap.recover_landmarks = 2;
  OnTheCircle c(p);
  Backend& be = c.be;
  c.driveTo(50);
  EXPECT_EQ(be.addMeasurement(circleMeasurement(1, 0, 50)).update.kind, UpdateKind::kInitialized);
  EXPECT_EQ(be.addMeasurement(circleMeasurement(2, 25, 50)).update.kind, UpdateKind::kInitialized);
  be.filter().startKidnapped();
  for (int64_t s : {110, 130}) {
    c.driveTo(s);
    const MeasurementResult r = be.addMeasurement(circleMeasurement(3, 100, s));
    EXPECT_EQ(r.use, MeasurementUse::kUsed);
    EXPECT_TRUE(r.update.deferred);
  }
  EXPECT_EQ(be.filter().numLandmarks(), 2u);
  bool recovered = false;
  for (int64_t s = 150; s < 200 && !recovered; s += 5) {
    c.driveTo(s);
    recovered =
        be.addMeasurement(circleMeasurement(s % 2 ? 1 : 2, s % 2 ? 0 : 25, s)).update.recovered;
  }
  ASSERT_TRUE(recovered);
  EXPECT_EQ(be.counters().landmarks_mapped_after_relocalization, 1);
  EXPECT_EQ(be.filter().numLandmarks(), 3u);
  c.driveTo(220);
  const MeasurementResult again = be.addMeasurement(circleMeasurement(3, 100, 220));
  EXPECT_EQ(again.update.kind, UpdateKind::kMixture);
  EXPECT_GT(again.update.agreement, 0.5);
}

TEST(BackendMeasurements, AKnownLookAlikesInconsistentMeasurementIsCountedAsIgnored) {
  // Landmarks 1 and 2 are twice measured as if the robot stood 2 m to the
  // side (a look-alike wall), each run contradicted by landmark 3: they
  // become known look-alikes. Their next inconsistent measurement weighs
  // nothing, and health counts it.
  BackendParams p = params(100, 0.01);
  p.filter.kidnap.detect_count = 100;  // the runs end by landmark 3, not by a kidnapping
  p.filter.kidnap.suspect_after = 2;
  Backend be(p);
  const Pose2 aside{0, 2, 0};
  int64_t seq = 0;
  auto driveTo = [&](int64_t last) {
    for (; seq <= last; ++seq) be.addOdometry(reading(seq));
  };
  driveTo(50);
  for (int64_t id : {1, 2, 3}) be.addMeasurement(circleMeasurement(id, 50, 50, {}));
  for (int64_t s : {60, 70}) {
    driveTo(s);
    be.addMeasurement(circleMeasurement(1, 50, s, aside));
    be.addMeasurement(circleMeasurement(2, 50, s, aside));
    EXPECT_EQ(be.addMeasurement(circleMeasurement(3, 50, s, {})).update.kind, UpdateKind::kMixture);
  }
  EXPECT_EQ(be.filter().numSuspectLandmarks(), 2u);
  EXPECT_EQ(be.counters().look_alike_measurements_ignored, 0);
  driveTo(80);
  const MeasurementResult r = be.addMeasurement(circleMeasurement(1, 50, 80, aside));
  EXPECT_EQ(r.use, MeasurementUse::kUsed);
  EXPECT_EQ(r.update.kind, UpdateKind::kIgnored);
  EXPECT_EQ(be.counters().look_alike_measurements_ignored, 1);
  // A consistent one of the same landmark weighs the particles as usual.
  EXPECT_EQ(be.addMeasurement(circleMeasurement(1, 50, 80, {})).update.kind, UpdateKind::kMixture);
  EXPECT_EQ(be.counters().look_alike_measurements_ignored, 1);
}

TEST(BackendViewJumps, EveryCamerasViewJumpingAtOnceDeclaresTheRobotMoved) {
  // Cameras measure landmarks on the circle (each at its reading), then
  // views jump. Every camera heard from in the last 10 s, two at least,
  // within 0.15 s: the robot was moved (carried), declared at once, the
  // estimate held where it was. One camera's jump alone, jumps seconds
  // apart, a robot with one camera, or the parameter off: not.
  using Heard = std::vector<std::pair<std::string, int64_t>>;  // camera, reading
  using Jumps = std::vector<std::pair<std::string, double>>;   // camera, seconds
  auto declared = [](bool enabled, const Heard& heard, const Jumps& jumps) {
    BackendParams p = params(50, 0.01);
    p.filter.kidnap.view_jump_window_s = 20.0;
    p.filter.kidnap.declare_on_every_view_jump = enabled;
    OnTheCircle c(p);
    Backend& be = c.be;
    int64_t id = 0;
    for (const auto& [camera, s] : heard) {
      c.driveTo(s);
      MeasurementInput m = circleMeasurement(++id, s - 10, s);
      m.camera = camera;
      be.addMeasurement(m);
    }
    c.driveTo(c.seq + 10);
    const Pose2 before = be.filter().estimate().mean;
    int declarations = 0;
    for (const auto& [camera, s] : jumps) declarations += be.noteViewJump(camera, at(s));
    EXPECT_EQ(be.filter().kidnapped(), declarations > 0);
    EXPECT_EQ(be.counters().kidnaps_detected, declarations);
    if (declarations > 0) {
      EXPECT_TRUE(be.filter().robotWasMoved());
      EXPECT_NEAR(be.filter().estimate().mean.x, before.x, 1e-9);  // held
      EXPECT_NEAR(be.filter().estimate().mean.y, before.y, 1e-9);
    }
    return declarations;
  };
  const Heard two = {{"forward", 50}, {"backward", 60}};
  EXPECT_EQ(declared(true, two, {{"forward", 1.3}, {"backward", 1.3}}), 1);
  // Not triggered together: a frame apart is one instant, 0.3 s is not.
  EXPECT_EQ(declared(true, two, {{"forward", 1.2}, {"backward", 1.3}}), 1);
  EXPECT_EQ(declared(true, two, {{"forward", 1.0}, {"backward", 1.3}}), 0);
  EXPECT_EQ(declared(true, two, {{"forward", 1.3}}), 0);
  // A camera whose view jumped less than view_jump_window_s (20 s) before
  // keeps jumping in place (people walking past): it cannot tell a move.
  EXPECT_EQ(declared(true, two, {{"forward", 0.3}, {"forward", 1.3}, {"backward", 1.3}}), 0);
  EXPECT_EQ(declared(true, two, {{"forward", 0.3}, {"forward", 21.0}, {"backward", 21.0}}), 1);
  EXPECT_EQ(declared(true, two, {{"forward", 0.3}, {"backward", 1.3}}), 0);
  EXPECT_EQ(declared(true, {{"forward", 50}}, {{"forward", 1.3}}), 0);
  EXPECT_EQ(declared(false, two, {{"forward", 1.3}, {"backward", 1.3}}), 0);
  // Three cameras: two jumping is not all of them...
  const Heard three = {{"forward", 50}, {"backward", 55}, {"left", 60}};
  EXPECT_EQ(declared(true, three, {{"left", 1.3}, {"backward", 1.3}}), 0);
  // ...unless the third has not been heard from for over 10 s (stopped).
  const Heard stopped = {{"left", 50}, {"forward", 600}, {"backward", 610}};
  EXPECT_EQ(declared(true, stopped, {{"forward", 12.3}, {"backward", 12.3}}), 1);
}
