// Trajectory metrics on hand-made trajectories with known answers: timestamp
// association, every alignment mode, ATE statistics, RPE by time and by
// distance, TUM file parsing, planar conversion.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <sstream>

#include "eval/align.hpp"
#include "eval/associate.hpp"
#include "eval/errors.hpp"
#include "eval/evaluate.hpp"
#include "eval/metrics.hpp"
#include "eval/planar.hpp"
#include "eval/tum_file.hpp"

using namespace vslam::eval;

namespace {

constexpr double kTol = 1e-9;

// A 2 m square driven counter-clockwise from (0, 0) facing +x: 8 poses per
// edge 0.25 m apart, one every 0.5 s, 32 poses, heading along each edge.
Trajectory square(double t0 = 100.0) {
  Trajectory tr;
  tr.name = "square";
  const double step = 0.25;
  double x = 0, y = 0;
  for (int edge = 0; edge < 4; ++edge) {
    const double heading = edge * M_PI / 2;
    for (int k = 0; k < 8; ++k) {
      tr.poses.push_back(
          planarPose(t0 + 0.5 * static_cast<double>(tr.poses.size()), x, y, 0.0, heading));
      x += step * std::cos(heading);
      y += step * std::sin(heading);
    }
  }
  return tr;
}

// Applies x -> s R x + t to every pose (orientation R q).
Trajectory transformed(const Trajectory& in, const Eigen::Matrix3d& R, const Eigen::Vector3d& t,
                       double s = 1.0) {
  Similarity T;
  T.R = R;
  T.t = t;
  T.scale = s;
  Trajectory out = T.apply(in);
  out.name = "estimate";
  return out;
}

Eigen::Matrix3d rotZ(double a) { return Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).matrix(); }

EstimateEvaluation evaluate(const Trajectory& ref, const Trajectory& est, AlignMode mode,
                            double delta = 1.0, DeltaUnit unit = DeltaUnit::kSeconds) {
  TrajectoryEvalOptions o;
  o.align = mode;
  o.rpe.delta = delta;
  o.rpe.unit = unit;
  return evaluateEstimate(ref, {est, EstimateKind::kEstimate, "test"}, o);
}

// Root mean square of the distance of the positions from their centroid.
double rmsAboutCentroid(const Trajectory& tr) {
  Eigen::Vector3d m = Eigen::Vector3d::Zero();
  for (const auto& p : tr.poses) m += p.position;
  m /= static_cast<double>(tr.size());
  double s = 0;
  for (const auto& p : tr.poses) s += (p.position - m).squaredNorm();
  return std::sqrt(s / static_cast<double>(tr.size()));
}

}  // namespace

// ---- statistics -------------------------------------------------------------

TEST(EvalStats, NumpyDefinitions) {
  const ErrorStats s = computeStats({4, 1, 3, 2});
  EXPECT_EQ(s.count, 4u);
  EXPECT_NEAR(s.rmse, std::sqrt(30.0 / 4), kTol);
  EXPECT_NEAR(s.mean, 2.5, kTol);
  EXPECT_NEAR(s.median, 2.5, kTol);           // mean of the two middle values
  EXPECT_NEAR(s.std, std::sqrt(1.25), kTol);  // population (ddof = 0)
  EXPECT_EQ(s.min, 1);
  EXPECT_EQ(s.max, 4);
  EXPECT_NEAR(computeStats({5, 1, 3}).median, 3.0, kTol);
  EXPECT_TRUE(std::isnan(computeStats({}).rmse));
}

// ---- association ------------------------------------------------------------

TEST(EvalAssociate, DropsPairsBeyondMaxDiffStrictly) {
  const std::vector<double> ref = {0.0, 1.0, 2.0, 3.0, 4.0};
  const std::vector<double> est = {0.005, 1.03, 1.99, 3.019, 4.5};
  const auto m = associate(ref, est, 0.0, 0.02);
  ASSERT_EQ(m.size(), 3u);
  EXPECT_EQ(m[0], (Match{0, 0}));
  EXPECT_EQ(m[1], (Match{2, 2}));
  EXPECT_EQ(m[2], (Match{3, 3}));
  // |4.0 - 4.5| == 0.5 exactly: not strictly less than max-diff 0.5.
  const auto m2 = associate({4.0}, {4.5}, 0.0, 0.5);
  EXPECT_TRUE(m2.empty());
  EXPECT_EQ(associate({4.0}, {4.5}, 0.0, 0.5000001).size(), 1u);
}

TEST(EvalAssociate, GreedyByDifferenceEachStampOnce) {
  // 1.002 is closest to 1.0 and takes it; 0.995 is left unmatched.
  auto m = associate({1.0, 2.0}, {0.995, 1.002, 2.03}, 0.0, 0.02);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0], (Match{0, 1}));
  // Globally smallest first: (1.01, 1.012) 0.002 before (1.0, 1.004) 0.004.
  m = associate({1.0, 1.01}, {1.004, 1.012}, 0.0, 0.02);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0], (Match{0, 0}));
  EXPECT_EQ(m[1], (Match{1, 1}));
  // 1.006 is nearer 1.01 than 1.0.
  m = associate({1.0, 1.01}, {1.006}, 0.0, 0.02);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0], (Match{1, 0}));
  // A pose whose nearest partner was taken may match its second nearest.
  m = associate({1.0, 1.015}, {1.012}, 0.0, 0.02);
  ASSERT_EQ(m.size(), 1u);
  EXPECT_EQ(m[0], (Match{1, 0}));
  m = associate({1.0, 1.015}, {1.012, 1.013}, 0.0, 0.02);
  ASSERT_EQ(m.size(), 2u);
  EXPECT_EQ(m[0], (Match{0, 0}));  // 1.012 lost 1.015 to 1.013 and took 1.0 (0.012 < 0.02)
  EXPECT_EQ(m[1], (Match{1, 1}));
}

TEST(EvalAssociate, OffsetIsAddedToEstimateStamps) {
  const std::vector<double> ref = {10.0, 10.1, 10.2};
  const std::vector<double> est = {9.5, 9.6, 9.7};
  EXPECT_TRUE(associate(ref, est, 0.0, 0.02).empty());
  EXPECT_EQ(associate(ref, est, 0.5, 0.02).size(), 3u);
}

TEST(EvalAssociate, FindClosestIndex) {
  const std::vector<double> v = {0.0, 1.0, 2.0, 3.0};
  EXPECT_EQ(findClosestIndex(v, -5), 0u);
  EXPECT_EQ(findClosestIndex(v, 1.2), 1u);
  EXPECT_EQ(findClosestIndex(v, 1.7), 2u);
  EXPECT_EQ(findClosestIndex(v, 3.0), 3u);
  EXPECT_EQ(findClosestIndex(v, 99), 3u);
}

// ---- ATE and alignment --------------------------------------------------------

TEST(EvalAte, TranslatedEstimateWithoutAlignmentHasKnownError) {
  const Trajectory ref = square();
  const Trajectory est = transformed(ref, Eigen::Matrix3d::Identity(), {0.3, -0.4, 0.0});
  const auto e = evaluate(ref, est, AlignMode::kNone);
  EXPECT_EQ(e.ate.stats.count, 32u);
  EXPECT_NEAR(e.ate.stats.rmse, 0.5, kTol);
  EXPECT_NEAR(e.ate.stats.mean, 0.5, kTol);
  EXPECT_NEAR(e.ate.stats.median, 0.5, kTol);
  EXPECT_NEAR(e.ate.stats.std, 0.0, kTol);
  EXPECT_NEAR(e.ate.stats.min, 0.5, kTol);
  EXPECT_NEAR(e.ate.stats.max, 0.5, kTol);
}

TEST(EvalAte, RigidMotionVanishesWithSe2Se3Sim3) {
  const Trajectory ref = square();
  const double yaw = 30.0 * M_PI / 180;
  const Eigen::Vector3d t(1.0, 2.0, 0.0);
  const Trajectory est = transformed(ref, rotZ(yaw), t);
  for (const AlignMode mode : {AlignMode::kSE2, AlignMode::kSE3, AlignMode::kSim3}) {
    const auto e = evaluate(ref, est, mode);
    EXPECT_LT(e.ate.stats.max, 1e-9) << toString(mode);
    EXPECT_NEAR(e.ate.alignment.yaw(), -yaw, 1e-9) << toString(mode);
    EXPECT_NEAR(e.ate.alignment.scale, 1.0, 1e-9) << toString(mode);
    EXPECT_EQ(e.ate.stats.count, 32u);
  }
  // Without alignment each point is off by |R p + t - p|.
  const auto none = evaluate(ref, est, AlignMode::kNone);
  std::vector<double> expected;
  for (const auto& p : ref.poses)
    expected.push_back((rotZ(yaw) * p.position + t - p.position).norm());
  const ErrorStats s = computeStats(expected);
  EXPECT_NEAR(none.ate.stats.rmse, s.rmse, kTol);
  EXPECT_NEAR(none.ate.stats.median, s.median, kTol);
  EXPECT_GT(none.ate.stats.rmse, 1.0);
}

TEST(EvalAte, OriginAlignmentPutsTheFirstPosesTogether) {
  // A rigidly moved copy is undone exactly by making the first poses coincide.
  const Trajectory ref = square();
  const double yaw = 50.0 * M_PI / 180;
  const Trajectory moved = transformed(ref, rotZ(yaw), {3.0, -1.0, 0.0});
  const auto e = evaluate(ref, moved, AlignMode::kOrigin);
  EXPECT_LT(e.ate.stats.max, 1e-9);
  EXPECT_NEAR(e.ate.alignment.yaw(), -yaw, 1e-9);
  // A heading error at the start is not averaged away, unlike a fit: an
  // estimate that turned 10 degrees too far at the start, then drove the
  // square, ends up to 2 m * 2 sin(5 deg) from the reference.
  Trajectory bent = ref;
  for (auto& p : bent.poses) {
    p.position = rotZ(10.0 * M_PI / 180) * p.position;
    p.orientation = Eigen::Quaterniond(rotZ(10.0 * M_PI / 180)) * p.orientation;
  }
  bent.poses.front().orientation = ref.poses.front().orientation;  // first pose agrees
  bent.poses.front().position = ref.poses.front().position;
  const auto o = evaluate(ref, bent, AlignMode::kOrigin);
  double worst = 0;
  for (const auto& p : ref.poses) {
    worst = std::max(worst, (rotZ(10.0 * M_PI / 180) * p.position - p.position).norm());
  }
  EXPECT_NEAR(o.ate.stats.max, worst, 1e-9);
  EXPECT_LT(evaluate(ref, bent, AlignMode::kSE2).ate.stats.max, 1e-9);
}

TEST(EvalAte, TiltIsRemovedBySe3ButNotSe2) {
  const Trajectory ref = square();
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX()).matrix();
  const Trajectory est = transformed(ref, tilt, {0, 0, 0.5});
  EXPECT_LT(evaluate(ref, est, AlignMode::kSE3).ate.stats.max, 1e-9);
  EXPECT_GT(evaluate(ref, est, AlignMode::kSE2).ate.stats.rmse, 0.05);
}

TEST(EvalAte, Se2LeavesHeightAlone) {
  // Points alternately 0.1 m above and below the reference: the planar
  // alignment keeps z, so every error is exactly 0.1.
  const Trajectory ref = square();
  Trajectory est = ref;
  for (std::size_t i = 0; i < est.size(); ++i) est.poses[i].position.z() = i % 2 ? 0.1 : -0.1;
  const auto e = evaluate(ref, est, AlignMode::kSE2);
  EXPECT_NEAR(e.ate.stats.rmse, 0.1, kTol);
  EXPECT_NEAR(e.ate.stats.min, 0.1, kTol);
  EXPECT_NEAR(e.ate.stats.max, 0.1, kTol);
}

TEST(EvalAte, ScaleIsRecoveredBySim3Only) {
  const Trajectory ref = square();
  const Trajectory est = transformed(ref, rotZ(-0.7), {3.0, -1.0, 0.2}, 2.0);
  const auto sim3 = evaluate(ref, est, AlignMode::kSim3);
  EXPECT_NEAR(sim3.ate.alignment.scale, 0.5, 1e-9);
  EXPECT_LT(sim3.ate.stats.max, 1e-9);
  // Rigid alignment leaves |s - 1| |p - centroid| = |p - centroid| per point.
  const auto se3 = evaluate(ref, est, AlignMode::kSE3);
  EXPECT_NEAR(se3.ate.alignment.scale, 1.0, kTol);
  EXPECT_NEAR(se3.ate.stats.rmse, rmsAboutCentroid(ref), 1e-9);
  const auto se2 = evaluate(ref, est, AlignMode::kSE2);
  EXPECT_NEAR(se2.ate.stats.rmse, std::sqrt(std::pow(rmsAboutCentroid(ref), 2) + 0.2 * 0.2), 1e-9);
}

TEST(EvalAte, KnownOffsetsGiveHandComputedStatistics) {
  // Offsets 0.1, 0.2, 0.3, 0.4 m along x, repeating: rmse sqrt(0.075),
  // mean = median = 0.25, std sqrt(0.0125).
  const Trajectory ref = square();
  Trajectory est = ref;
  for (std::size_t i = 0; i < est.size(); ++i) {
    est.poses[i].position.x() += 0.1 * static_cast<double>(i % 4 + 1);
  }
  const auto e = evaluate(ref, est, AlignMode::kNone);
  EXPECT_NEAR(e.ate.stats.rmse, std::sqrt(0.075), kTol);
  EXPECT_NEAR(e.ate.stats.mean, 0.25, kTol);
  EXPECT_NEAR(e.ate.stats.median, 0.25, kTol);
  EXPECT_NEAR(e.ate.stats.std, std::sqrt(0.0125), kTol);
  EXPECT_NEAR(e.ate.stats.min, 0.1, kTol);
  EXPECT_NEAR(e.ate.stats.max, 0.4, kTol);
}

TEST(EvalAte, HeadingErrorIsTheShortestArcAfterAlignment) {
  // Headings off by +5, -10, +15, -20 degrees (repeating) at the right
  // positions: |errors| 5, 10, 15, 20 -> mean 12.5, max 20; the positions are
  // exact, so no alignment changes them.
  const Trajectory ref = square();
  Trajectory est = ref;
  const double offsets_deg[4] = {5, -10, 15, -20};
  for (std::size_t i = 0; i < est.size(); ++i) {
    est.poses[i].orientation =
        Eigen::Quaterniond(rotZ(offsets_deg[i % 4] * M_PI / 180)) * est.poses[i].orientation;
  }
  const auto e = evaluate(ref, est, AlignMode::kNone);
  EXPECT_LT(e.ate.stats.max, 1e-12);
  EXPECT_NEAR(e.ate.heading.mean * 180 / M_PI, 12.5, 1e-9);
  EXPECT_NEAR(e.ate.heading.max * 180 / M_PI, 20.0, 1e-9);
  EXPECT_NEAR(e.ate.heading.min * 180 / M_PI, 5.0, 1e-9);
  // Across +-180 degrees: 179 against -179 is 2 degrees, not 358.
  Trajectory r1, e1;
  r1.poses = {planarPose(0, 0, 0, 0, M_PI * 179 / 180)};
  e1.poses = {planarPose(0, 0, 0, 0, -M_PI * 179 / 180)};
  EXPECT_NEAR(evaluate(r1, e1, AlignMode::kNone).ate.heading.max * 180 / M_PI, 2.0, 1e-9);
  // The alignment's rotation applies to the headings too: a rigidly rotated
  // copy has no heading error once aligned.
  const Trajectory moved = transformed(ref, rotZ(0.7), {1.0, 2.0, 0.0});
  EXPECT_LT(evaluate(ref, moved, AlignMode::kSE2).ate.heading.max, 1e-9);
  EXPECT_NEAR(evaluate(ref, moved, AlignMode::kNone).ate.heading.max, 0.7, 1e-9);
}

TEST(EvalAte, AssociationLimitsThePairs) {
  const Trajectory ref = square();
  Trajectory est = ref;
  // Every third estimate pose is 30 ms late: dropped at max-diff 0.02 s.
  for (std::size_t i = 0; i < est.size(); i += 3) est.poses[i].t += 0.03;
  EXPECT_EQ(evaluate(ref, est, AlignMode::kNone).ate.stats.count, 32u - 11u);
  TrajectoryEvalOptions o;
  o.max_diff = 0.05;
  EXPECT_EQ(evaluateEstimate(ref, {est, EstimateKind::kEstimate, ""}, o).ate.stats.count, 32u);
  // Shifted by 100 s: nothing to associate, unless the offset says so.
  Trajectory late = ref;
  for (auto& p : late.poses) p.t += 100.0;
  EXPECT_THROW(evaluate(ref, late, AlignMode::kNone), DataError);
  o = {};
  o.offset = -100.0;
  EXPECT_EQ(evaluateEstimate(ref, {late, EstimateKind::kEstimate, ""}, o).ate.stats.count, 32u);
}

TEST(EvalAlign, NeedsEnoughPointsAndMotionForScale) {
  const std::vector<Eigen::Vector3d> two = {{0, 0, 0}, {1, 0, 0}};
  EXPECT_NO_THROW(alignPositions(two, two, AlignMode::kSE2));
  EXPECT_THROW(alignPositions(two, two, AlignMode::kSE3), DataError);
  const std::vector<Eigen::Vector3d> still(5, Eigen::Vector3d(1, 2, 3));
  const std::vector<Eigen::Vector3d> moving = {
      {0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {3, 1, 0}, {4, 2, 0}};
  EXPECT_THROW(alignPositions(still, moving, AlignMode::kSim3), DataError);
  EXPECT_EQ(parseAlignMode("sim3"), AlignMode::kSim3);
  EXPECT_FALSE(parseAlignMode("SE3").has_value());
}

// ---- RPE ------------------------------------------------------------------------

TEST(EvalRpe, ConstantDriftGivesDriftTimesDelta) {
  // The estimate drifts 0.05 m/s along world x; orientations exact. Every
  // pair 1 s apart is off by 0.05 m, no rotation error. Pairs: i = 0..28
  // (j = i + 2; j = 31, the last pose, is skipped as in evaluate_rpe.py).
  const Trajectory ref = square();
  Trajectory est = ref;
  for (auto& p : est.poses) p.position.x() += 0.05 * (p.t - ref.poses.front().t);
  const auto e = evaluate(ref, est, AlignMode::kNone, 1.0);
  EXPECT_EQ(e.rpe.trans.count, 29u);
  EXPECT_NEAR(e.rpe.trans.rmse, 0.05, kTol);
  EXPECT_NEAR(e.rpe.trans.max, 0.05, kTol);
  EXPECT_NEAR(e.rpe.rot.max, 0.0, 1e-7);
  // Twice the delta, twice the error; rigid alignment does not change RPE.
  const auto e2 = evaluate(ref, est, AlignMode::kSE3, 2.0);
  EXPECT_NEAR(e2.rpe.trans.mean, 0.10, kTol);
  EXPECT_EQ(e2.rpe.trans.count, 32u - 5u);
}

TEST(EvalRpe, HeadingDriftUsesTheScriptsComposition) {
  // Straight line along x at 1 m/s, sampled at 10 Hz; the estimate's heading
  // drifts 0.1 rad/s. Rotation error per 1 s pair: 0.1 rad. Translation error
  // of E = (P_i^-1 P_j)(Q_i^-1 Q_j)^-1 is 2 |d| sin(w t_j / 2) with d = 1 m
  // and t_j the pair's end time (evo's Q_rel^-1 P_rel would give t_i).
  const double w = 0.1;
  Trajectory ref, est;
  for (int i = 0; i <= 50; ++i) {
    const double t = 0.1 * i;
    ref.poses.push_back(planarPose(t, t, 0, 0, 0));
    est.poses.push_back(planarPose(t, t, 0, 0, w * t));
  }
  const auto e = evaluate(ref, est, AlignMode::kNone, 1.0);
  ASSERT_EQ(e.rpe.trans.count, 40u);  // i = 0..39, j = i + 10 < 50
  std::vector<double> expected;
  for (const auto& p : e.rpe.pairs) {
    EXPECT_NEAR(p.t_est1 - p.t_est0, 1.0, 1e-9);
    EXPECT_NEAR(p.rot, w * 1.0, 1e-9);
    expected.push_back(2.0 * std::sin(w * p.t_est1 / 2));
  }
  EXPECT_NEAR(e.rpe.trans.rmse, computeStats(expected).rmse, 1e-9);
  EXPECT_NEAR(e.rpe.rot.mean, 0.1, 1e-9);
}

TEST(EvalRpe, DeltaInMetresFollowsDistanceTravelled) {
  // 0.1 m per sample along x, one sample every 0.05 s; the estimate drifts
  // sideways 0.1 m per metre. delta 1 m: j = i + 10, error 0.1 m, 20 pairs
  // (31 poses); delta 1 s: j = i + 20, error 0.2 m, 10 pairs.
  Trajectory ref, est;
  for (int i = 0; i <= 30; ++i) {
    const double s = 0.1 * i;
    ref.poses.push_back(planarPose(0.05 * i, s, 0, 0, 0));
    est.poses.push_back(planarPose(0.05 * i, s, 0.1 * s, 0, 0));
  }
  const auto by_m = evaluate(ref, est, AlignMode::kNone, 1.0, DeltaUnit::kMetres);
  EXPECT_EQ(by_m.rpe.trans.count, 20u);
  EXPECT_NEAR(by_m.rpe.trans.rmse, 0.1, 1e-9);
  const auto by_s = evaluate(ref, est, AlignMode::kNone, 1.0, DeltaUnit::kSeconds);
  EXPECT_EQ(by_s.rpe.trans.count, 10u);
  EXPECT_NEAR(by_s.rpe.trans.rmse, 0.2, 1e-9);
}

TEST(EvalRpe, Sim3ScaleAppliesToRelativeMotion) {
  Trajectory ref, est;
  for (int i = 0; i <= 40; ++i) {
    const double t = 0.1 * i;
    ref.poses.push_back(planarPose(t, t, 0.1 * t * t, 0, 0.2 * t));
    est.poses.push_back(planarPose(t, 2 * t, 0.2 * t * t, 0, 0.2 * t));
  }
  EXPECT_LT(evaluate(ref, est, AlignMode::kSim3).rpe.trans.max, 1e-9);
  EXPECT_GT(evaluate(ref, est, AlignMode::kSE3).rpe.trans.min, 0.5);
}

TEST(EvalRpe, EstimatePosesFarFromReferenceStampsAreSkipped) {
  // The reference stops at 3 s (10 Hz, tolerance 2 x 0.1 s); the estimate,
  // 50 ms later than each reference stamp, runs to 5.05 s. Pairs need both
  // ends within 0.2 s of a reference stamp: t_j <= 3.15 s, so t_i <= 2.15 s.
  Trajectory ref, est;
  for (int i = 0; i <= 30; ++i) ref.poses.push_back(planarPose(0.1 * i, 0.1 * i, 0, 0, 0));
  for (int i = 0; i <= 50; ++i) est.poses.push_back(planarPose(0.1 * i + 0.05, 0.1 * i, 0, 0, 0));
  const auto r = computeRpe(ref, est, {1.0, DeltaUnit::kSeconds, 0.0});
  EXPECT_NEAR(r.ref_max_time_diff, 0.2, 1e-9);
  EXPECT_EQ(r.trans.count, 22u);
  for (const auto& p : r.pairs) EXPECT_LT(p.t_est1, 3.2);
  EXPECT_TRUE(computeRpe(ref, Trajectory{"one", {est.poses[0]}}, {}).pairs.empty());
}

// ---- TUM files -------------------------------------------------------------------

TEST(EvalTum, ParsesCommentsSeparatorsAndSortsKeepingTheLastDuplicate) {
  std::istringstream in(
      "# ground truth\n"
      "   # indented comment\n"
      "\n"
      "2.0 1 2 3 0 0 0 1\r\n"
      "1.0,0.5,0,0,0,0,0.7071067811865476,0.7071067811865476\n"
      "3.0\t1\t1\t1\t0\t0\t0\t2\n"
      "2.0 9 9 9 0 0 0 1\n");
  const Trajectory t = parseTum(in, "mem.txt");
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(t.poses[0].t, 1.0);
  EXPECT_NEAR(headingOf(t.poses[0].orientation), M_PI / 2, 1e-12);
  EXPECT_EQ(t.poses[1].position, Eigen::Vector3d(9, 9, 9));  // the later 2.0 line
  EXPECT_NEAR(t.poses[2].orientation.norm(), 1.0, 1e-12);    // normalised
}

TEST(EvalTum, MalformedLinesNameFileAndLine) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"# c\n1 0 0 0 0 0 0 1\n2 0 0 0 0 0 1\n", "bad.txt:3: expected 8 fields"},
      {"1 0 0 0 0 0 0 1\n2 0 x 0 0 0 0 1\n", "bad.txt:2: ty 'x' is not a number"},
      {"1 0 0 nan 0 0 0 1\n", "bad.txt:1: tz is nan"},
      {"1 0 0 0 0 0 0 0\n", "bad.txt:1: quaternion"},
      {"1.5abc 0 0 0 0 0 0 1\n", "bad.txt:1: timestamp '1.5abc'"},
      {"# only a comment\n\n", "bad.txt: no poses"},
  };
  for (const auto& [text, message] : cases) {
    std::istringstream in(text);
    try {
      parseTum(in, "bad.txt");
      ADD_FAILURE() << "no error for: " << text;
    } catch (const DataError& e) {
      EXPECT_NE(std::string(e.what()).find(message), std::string::npos)
          << e.what() << " (expected '" << message << "')";
    }
  }
  EXPECT_THROW(readTumFile("/nonexistent/traj.txt"), DataError);
}

TEST(EvalTum, WriteThenReadIsExactToTheMicrosecond) {
  Trajectory t = square(1700000000.123456);
  const auto file = std::filesystem::temp_directory_path() /
                    ("vslam_eval_tum_" + std::to_string(::getpid()) + ".txt");
  writeTumFile(file, t);
  const Trajectory back = readTumFile(file);
  std::filesystem::remove(file);
  ASSERT_EQ(back.size(), t.size());
  for (std::size_t i = 0; i < t.size(); ++i) {
    EXPECT_NEAR(back.poses[i].t, t.poses[i].t, 1e-6);
    EXPECT_NEAR((back.poses[i].position - t.poses[i].position).norm(), 0, 1e-9);
    EXPECT_NEAR(back.poses[i].orientation.angularDistance(t.poses[i].orientation), 0, 1e-8);
  }
}

// ---- planar poses from 3-D --------------------------------------------------------

TEST(EvalPlanar, FloorAxesAndHeading) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotZ(0.5).matrix();
  T.translation() = Eigen::Vector3d(1, 2, 3);
  PlanarPose p = planarFromPose(T, FloorAxes::kXY);
  EXPECT_NEAR(p.x, 1, kTol);
  EXPECT_NEAR(p.y, 2, kTol);
  EXPECT_NEAR(p.z, 3, kTol);
  EXPECT_NEAR(p.theta, 0.5, kTol);
  // xz: floor = (x, z), up = -y. A body turned by +0.5 about up (-y) has its
  // x axis at angle 0.5 from world x towards world z.
  T.linear() = Eigen::AngleAxisd(0.5, -Eigen::Vector3d::UnitY()).matrix();
  p = planarFromPose(T, FloorAxes::kXZ);
  EXPECT_NEAR(p.x, 1, kTol);
  EXPECT_NEAR(p.y, 3, kTol);
  EXPECT_NEAR(p.z, -2, kTol);
  EXPECT_NEAR(p.theta, 0.5, kTol);
}
