// The path-hypothesis tree (Lee & Sowmya section V) on a small synthetic
// world: a 2 x 2 m square driven with 1 m moves and 90 degree left turns, 12
// actions a lap, 12 places. Each place shows a histogram of its own, except
// that places 0 and 1 look alike (perceptual aliasing). The snapshots are
// the stored histograms exactly, so chi2 = 0 for the right place.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "appearance/map_file.hpp"
#include "appearance/path_hypotheses.hpp"
#include "support/test_logs.hpp"

using namespace vslam;
using namespace vslam::appearance;

namespace {

constexpr int kBins = 16;
constexpr int kPlaces = 12;
const char* const kLap = "FFLFFLFFLFFL";

// A distinct histogram per place; places 0 and 1 share one.
Histogram placeHistogram(int place) {
  const int look = place == 1 ? 0 : place;
  Histogram h(kBins, 0.f);
  h[static_cast<size_t>(look)] = 0.6f;
  h[static_cast<size_t>((look + 5) % kBins)] = 0.4f;
  return h;
}

Snapshot snapshotAt(int place) {
  Snapshot z;
  z.histograms = {placeHistogram(place)};
  return z;
}

Pose2 actionOf(char c) { return c == 'F' ? Pose2{1, 0, 0} : Pose2{0, 0, M_PI / 2}; }

SlamParams params() {
  SlamParams p;
  p.beta = 1.0;
  // Distinct places here are chi2 2 apart: a new state scores at 0.05.
  p.new_state_ratio = 0.025;
  p.relocalization_candidates = 0;  // the paper's tree; seeds are tested on their own below
  p.min_chi2 = 1e-4;
  p.gate = 11.34;
  p.place_sigma_m = 0.2;
  p.place_sigma_rad = 0.17;
  p.min_belief = 1e-3;
  p.max_hypotheses = 20;
  return p;
}

ActionErrorModel model() {
  ActionErrorModel m;
  m.relative_translation = m.relative_rotation = 0.05;
  m.odometry_translation = m.odometry_rotation = 0.05;
  return m;
}

std::set<int64_t> revisitedStates(const StepResult& r) {
  std::set<int64_t> s;
  for (const auto& h : r.hypotheses)
    if (!h.is_new_state) s.insert(h.state_id);
  return s;
}

double beliefSum(const StepResult& r) {
  double s = 0;
  for (const auto& h : r.hypotheses) s += h.belief;
  return s;
}

// Drives one lap from place 0; returns the last result.
StepResult driveLap(AppearanceSlam& slam) {
  StepResult r;
  for (int i = 0; i < kPlaces; ++i) r = slam.step(actionOf(kLap[i]), snapshotAt((i + 1) % kPlaces));
  return r;
}

}  // namespace

TEST(PathHypotheses, SplitsOnAliasingAndCollapsesOnADistinctiveView) {
  AppearanceSlam slam(params(), 1, kBins);
  slam.setActionModel(model());
  StepResult r = slam.initialize(snapshotAt(0));
  ASSERT_EQ(r.hypotheses.size(), 1u);
  EXPECT_TRUE(r.best().is_new_state);
  // First lap: nothing visited is reachable, one new-state hypothesis a step
  // (place 1 looks like place 0, but 1 m from it with 5 % error it is not
  // the same place).
  for (int i = 0; i < kPlaces - 1; ++i) {
    r = slam.step(actionOf(kLap[i]), snapshotAt(i + 1));
    ASSERT_EQ(r.hypotheses.size(), 1u) << "step " << r.step;
    EXPECT_TRUE(r.best().is_new_state);
    EXPECT_EQ(r.best().state_id, i + 1);
  }
  // Back at place 0 after the lap: traced through 12 actions, places 0 and 1
  // are both within reach, and both look like the snapshot: the tree splits.
  r = slam.step(actionOf(kLap[kPlaces - 1]), snapshotAt(0));
  const auto split = revisitedStates(r);
  EXPECT_TRUE(split.count(0) && split.count(1)) << "revisits: " << split.size();
  EXPECT_GE(r.hypotheses.size(), 3u);
  EXPECT_EQ(r.best().state_id, 0) << "the traced pose is closer to place 0";
  EXPECT_FALSE(r.best().is_new_state);
  EXPECT_NEAR(beliefSum(r), 1.0, 1e-9);

  // One move on: place 1 (still looks like 0), then place 2, distinctive.
  r = slam.step(actionOf('F'), snapshotAt(1));
  r = slam.step(actionOf('F'), snapshotAt(2));
  EXPECT_EQ(r.best().state_id, 2);
  EXPECT_FALSE(r.best().is_new_state);
  EXPECT_GT(r.best().belief, 0.95);
  for (const auto& h : r.hypotheses) {
    if (!h.is_new_state) {
      EXPECT_EQ(h.state_id, 2) << "a hypothesis off the true path survived";
    }
  }
  // The map of the best hypothesis has the 12 places, no more.
  EXPECT_EQ(slam.best().node->num_states, kPlaces);
  EXPECT_EQ(slam.bestMap({"cam"}).states.size(), static_cast<size_t>(kPlaces));
}

// Equation 6 by hand: one hypothesis at state 0, a small action u = 0.1 m;
// the children are "new" (weight (new_state_ratio chi2)^-beta, the median
// distance to the one stored state being chi2) and "back in state 0":
// exp(-m^2/2) chi2^-beta with m^2 = r^T (S_u + S_place)^-1 r.
TEST(PathHypotheses, BeliefsFollowTransitionAndObservationProbabilities) {
  SlamParams p = params();
  p.beta = 2.0;
  p.new_state_ratio = 0.8;
  AppearanceSlam slam(p, 1, kBins);
  slam.setActionModel(model());
  slam.initialize(snapshotAt(0));
  Snapshot z;
  z.histograms = {Histogram(kBins, 0.f)};
  z.histograms[0][0] = 0.5f;  // half of place 0's first bin moved to bin 1
  z.histograms[0][1] = 0.1f;
  z.histograms[0][5] = 0.4f;
  const double chi2 = chiSquare(z.histograms[0], placeHistogram(0));
  const Pose2 u{0.1, 0, 0};
  const StepResult r = slam.step(u, z);
  ASSERT_EQ(r.hypotheses.size(), 2u);
  const double var_t = std::pow(0.05 * 0.1, 2) + 0.05 * 0.05 * 0.1 + 0.2 * 0.2;
  const double m2 = 0.1 * 0.1 / var_t;  // only x is off
  const double w_revisit = std::exp(-0.5 * m2) / std::pow(chi2, p.beta);
  const double w_new = 1.0 / std::pow(p.new_state_ratio * chi2, p.beta);
  double revisit = 0, fresh = 0;
  for (const auto& h : r.hypotheses) (h.is_new_state ? fresh : revisit) = h.belief;
  EXPECT_NEAR(revisit, w_revisit / (w_revisit + w_new), 1e-9);
  EXPECT_NEAR(fresh, w_new / (w_revisit + w_new), 1e-9);
}

TEST(PathHypotheses, PruningThresholdAndBound) {
  // Every place looks the same and the action error is large: each lap
  // step splits into many children.
  SlamParams p = params();
  p.max_hypotheses = 5;
  p.min_belief = 0.01;
  AppearanceSlam slam(p, 1, kBins);
  ActionErrorModel m = model();
  m.odometry_translation = m.odometry_rotation = 0.3;
  slam.setActionModel(m);
  slam.initialize(snapshotAt(0));
  int bounded = 0, thresholded = 0;
  for (int lap = 0; lap < 2; ++lap) {
    for (int i = 0; i < kPlaces; ++i) {
      const StepResult r = slam.step(actionOf(kLap[i]), snapshotAt(0));
      ASSERT_LE(r.hypotheses.size(), 5u);
      ASSERT_EQ(slam.hypotheses().size(), r.hypotheses.size());
      EXPECT_NEAR(beliefSum(r), 1.0, 1e-9);
      // Most believed first: by the summed belief of the hypotheses in the
      // same state (where the robot is now), then by belief.
      std::map<int64_t, double> at_state;
      for (const auto& h : r.hypotheses) at_state[h.state_id] += h.belief;
      for (size_t k = 1; k < r.hypotheses.size(); ++k) {
        const double here = at_state[r.hypotheses[k].state_id];
        const double before = at_state[r.hypotheses[k - 1].state_id];
        EXPECT_LE(here, before + 1e-12) << "the most believed place first";
        if (r.hypotheses[k].state_id == r.hypotheses[k - 1].state_id) {
          EXPECT_LE(r.hypotheses[k].belief, r.hypotheses[k - 1].belief) << "then by belief";
        }
      }
      // Survivors were above the threshold before renormalisation, so above it after.
      for (const auto& h : r.hypotheses) EXPECT_GE(h.belief, p.min_belief);
      EXPECT_EQ(r.children,
                static_cast<int>(r.hypotheses.size()) + r.pruned_bound + r.pruned_threshold);
      bounded += r.pruned_bound;
      thresholded += r.pruned_threshold;
    }
  }
  EXPECT_GT(bounded, 0) << "the bound never applied: the test does not test it";
  EXPECT_GT(thresholded, 0);
}

TEST(PathHypotheses, NonFiniteInputIsRejected) {
  AppearanceSlam slam(params(), 1, kBins);
  EXPECT_THROW(slam.step({0, 0, 0}, snapshotAt(0)), std::logic_error);
  slam.initialize(snapshotAt(0));
  EXPECT_THROW(slam.step({NAN, 0, 0}, snapshotAt(1)), std::invalid_argument);
  Snapshot two;
  two.histograms = {placeHistogram(0), placeHistogram(1)};
  EXPECT_THROW(slam.step({1, 0, 0}, two), std::invalid_argument);
  Snapshot short_bins;
  short_bins.histograms = {Histogram(3, 0.f)};
  EXPECT_THROW(slam.step({1, 0, 0}, short_bins), std::invalid_argument);
}

// Tracing through a revisit: once a path is back in place 0, place 1 is one
// link from it. Places 1 and 2 look alike here. With revisit_horizon the
// step after the re-localisation predicts place 1 through place 0 (a 1 m
// trace) and place 2 is out of reach; with the paper's tracing only, both
// are traced from their first-lap visits through the whole lap and both
// survive.
TEST(PathHypotheses, TracingThroughARevisitFollowsTheMap) {
  const auto look = [](int place) {
    Histogram h(kBins, 0.f);
    const int l = place == 2 ? 1 : place;
    h[static_cast<size_t>(l)] = 0.6f;
    h[static_cast<size_t>((l + 7) % kBins)] = 0.4f;
    Snapshot z;
    z.histograms = {h};
    return z;
  };
  for (const int horizon : {10, 0}) {
    SlamParams p = params();
    p.revisit_horizon = horizon;
    AppearanceSlam slam(p, 1, kBins);
    slam.setActionModel(model());
    slam.initialize(look(0));
    for (int i = 0; i < kPlaces; ++i) slam.step(actionOf(kLap[i]), look((i + 1) % kPlaces));
    ASSERT_EQ(slam.best().node->state_id, 0);
    const StepResult r = slam.step(actionOf('F'), look(1));
    const auto states = revisitedStates(r);
    EXPECT_TRUE(states.count(1)) << "horizon " << horizon;
    if (horizon > 0) {
      EXPECT_FALSE(states.count(2)) << "place 2 is two links from place 0";
      EXPECT_EQ(r.best().state_id, 1);
    } else {
      EXPECT_TRUE(states.count(2)) << "the paper's tracing cannot tell 1 from 2 here";
    }
  }
}

TEST(MapFile, RoundTripAndRelocalisationInTheLoadedMap) {
  const auto dir = vslam::test::scratchDir("appearance_map");
  const auto file = dir / "loop.map";
  SavedMap saved;
  {
    AppearanceSlam slam(params(), 1, kBins);
    slam.setActionModel(model());
    slam.initialize(snapshotAt(0));
    driveLap(slam);
    saved = slam.bestMap({"forward"});
    saveMap(file, saved);
  }
  const SavedMap loaded = loadMap(file);
  EXPECT_EQ(loaded.cameras, saved.cameras);
  EXPECT_EQ(loaded.bins, kBins);
  ASSERT_EQ(loaded.states.size(), saved.states.size());
  for (size_t i = 0; i < saved.states.size(); ++i) {
    EXPECT_EQ(loaded.states[i].id, saved.states[i].id);
    EXPECT_EQ(loaded.states[i].utime, saved.states[i].utime);
    EXPECT_EQ(loaded.states[i].histograms, saved.states[i].histograms);
  }
  ASSERT_EQ(loaded.path.size(), saved.path.size());
  for (size_t i = 0; i < saved.path.size(); ++i) {
    EXPECT_EQ(loaded.path[i].state_id, saved.path[i].state_id);
    EXPECT_EQ(loaded.path[i].link.known, saved.path[i].link.known);
    EXPECT_EQ(loaded.path[i].link.action.x, saved.path[i].link.action.x);
    EXPECT_EQ(loaded.path[i].link.action.theta, saved.path[i].link.action.theta);
    EXPECT_EQ(loaded.path[i].link.covariance, saved.path[i].link.covariance);
    EXPECT_EQ(loaded.path[i].link.model.odometry_rotation,
              saved.path[i].link.model.odometry_rotation);
  }

  // A second run in the loaded map, put down at place 5 (distinctive): it
  // re-localises there at once, then follows the map's links (turn left to
  // place 6) by tracing through the loaded path.
  AppearanceSlam second(params(), 1, kBins);
  second.setActionModel(model());
  second.loadMap(loaded, {"forward"});
  StepResult r = second.initialize(snapshotAt(5));
  EXPECT_FALSE(r.best().is_new_state);
  EXPECT_EQ(r.best().state_id, 5);
  r = second.step(actionOf('L'), snapshotAt(6));
  EXPECT_EQ(r.best().state_id, 6);
  EXPECT_FALSE(r.best().is_new_state);
  EXPECT_GT(r.best().belief, 0.9);
  // New states get ids after the map's.
  EXPECT_EQ(r.new_state_id, kPlaces + 1);
  EXPECT_THROW(second.loadMap(loaded, {"forward"}), std::logic_error);

  AppearanceSlam other_cameras(params(), 2, kBins);
  EXPECT_THROW(other_cameras.loadMap(loaded, {"forward", "backward"}), std::invalid_argument);
  { std::ofstream(dir / "junk.map") << "not a database"; }
  EXPECT_THROW(loadMap(dir / "junk.map"), MapFileError);
  EXPECT_THROW(loadMap(dir / "missing.map"), MapFileError);
  std::filesystem::remove_all(dir);
}

// Relocalization seeds (global re-localization, an addition to the paper).
// A 12-place square as above, every place its own look but for the places
// named in `alike`, each snapshot a noisy view: 10 % of its weight in a bin
// that depends on the place and the visit, so the right place is chi2 ~0.2
// away, a look-alike as much, and another place ~1.8.
namespace {

Snapshot noisyView(int place, int visit, const std::map<int, int>& alike = {}) {
  const auto it = alike.find(place);
  const int look = it == alike.end() ? place : it->second;
  Histogram h(kBins, 0.f);
  h[static_cast<size_t>(look)] += 0.54f;
  h[static_cast<size_t>((look + 5) % kBins)] += 0.36f;
  h[static_cast<size_t>((look + 2 + 3 * visit + place) % kBins)] += 0.1f;
  Snapshot z;
  z.histograms = {h};
  return z;
}

// Seeds on, with the defaults of SlamParams.
SlamParams seedingParams() {
  SlamParams p;
  p.place_sigma_m = 0.2;
  return p;
}

// The first lap from place 0 back to place 0 (visit 0), then `moves` more
// actions of the lap from `from` (visit 1) with odometry that does not know
// the robot was carried there; `on_step(step, place, result)` after each.
template <typename OnStep>
void lapThenCarried(AppearanceSlam& slam, int from, int moves, const std::map<int, int>& alike,
                    OnStep on_step) {
  slam.initialize(noisyView(0, 0, alike));
  for (int i = 0; i < kPlaces - 1; ++i) {
    const StepResult r = slam.step(actionOf(kLap[i]), noisyView(i + 1, 0, alike));
    ASSERT_TRUE(r.best().is_new_state) << "a revisit on the first lap, step " << r.step << " state "
                                       << r.best().state_id << " belief " << r.best().belief;
  }
  // Odometry says the robot went on from place 11 to place 0; it was put
  // down at `from` instead and drives on from there.
  int place = from;
  StepResult r = slam.step(actionOf(kLap[kPlaces - 1]), noisyView(place, 1, alike));
  on_step(0, place, r);
  for (int k = 1; k <= moves; ++k) {
    const char a = kLap[place % kPlaces];
    place = (place + 1) % kPlaces;
    r = slam.step(actionOf(a), noisyView(place, 1, alike));
    on_step(k, place, r);
  }
}

}  // namespace

// Carried from the end of the lap to place 6: odometry traces the robot to
// place 0, where nothing matches; a seed in place 6 follows the map along the
// places after it and becomes the most believed within a few steps. With
// seeds off (the paper's tree) the robot never re-enters its map.
TEST(RelocalizationSeeds, ACarriedRobotRelocalizesIntoItsMap) {
  for (const int candidates : {2, 0}) {
    SlamParams p = seedingParams();
    p.relocalization_candidates = candidates;
    AppearanceSlam slam(p, 1, kBins);
    slam.setActionModel(model());
    int first_correct = -1;
    // Places 7 to 11 after the carry: the map has their links from place 6.
    lapThenCarried(slam, 6, 5, {}, [&](int k, int place, const StepResult& r) {
      const bool correct = !r.best().is_new_state && r.best().state_id == place;
      if (correct && first_correct < 0) first_correct = k;
      if (first_correct >= 0) {
        EXPECT_TRUE(correct) << "lost again " << k << " steps after";
      }
      if (!r.best().is_new_state) {
        EXPECT_EQ(r.best().state_id, place) << "a wrong revisit";
      }
    });
    if (candidates > 0) {
      EXPECT_GE(first_correct, 0) << "never re-localized";
      EXPECT_LE(first_correct, 3) << "re-localized late";
      // At most the carry step's snapshot was added: the map did not grow since.
      EXPECT_LE(slam.best().node->num_states, kPlaces + 1) << "not back in the map";
    } else {
      EXPECT_EQ(first_correct, -1) << "the paper's tree cannot trace across a carry";
    }
  }
}

// Two places look alike (2 and 6). Carried to either at the end of the lap:
// both are seeded, and the tree commits to neither before the following
// views tell them apart; then it follows the right one's successors.
TEST(RelocalizationSeeds, LookAlikePlacesDoNotCommitAWrongRelocalization) {
  for (const int from : {6, 2}) {
    AppearanceSlam slam(seedingParams(), 1, kBins);
    slam.setActionModel(model());
    const std::map<int, int> alike{{6, 2}};
    std::set<int64_t> seeded;
    int first_correct = -1;
    lapThenCarried(slam, from, 6, alike, [&](int k, int place, const StepResult& r) {
      for (const auto& h : r.hypotheses)
        if (!h.is_new_state) seeded.insert(h.state_id);
      if (!r.best().is_new_state) {
        EXPECT_EQ(r.best().state_id, place) << "committed to the look-alike, step " << k;
        if (first_correct < 0) first_correct = k;
      }
    });
    EXPECT_TRUE(seeded.count(2) && seeded.count(6)) << "both look-alikes should be tried";
    EXPECT_GE(first_correct, 0) << "never re-localized, carried to " << from;
    EXPECT_LE(first_correct, 4);
  }
}

// Carried back to place 9 at the end of the lap (odometry: on to place 0),
// beside the states the robot made just before. They are among the path's
// last visits, which seeds skip while the trace decides there; but the view
// jumped (the snapshot looks no more like the last state, 11, than a new
// place would), so they are seeded too and the robot is back at once, not
// only when it reaches place 0, an older state, three steps later.
TEST(RelocalizationSeeds, ACarriedRobotRelocalizesBesideTheStatesItJustMade) {
  AppearanceSlam slam(seedingParams(), 1, kBins);
  slam.setActionModel(model());
  int first_correct = -1;
  lapThenCarried(slam, 9, 4, {}, [&](int k, int place, const StepResult& r) {
    const bool correct = !r.best().is_new_state && r.best().state_id == place;
    if (correct && first_correct < 0) first_correct = k;
    if (!r.best().is_new_state) {
      EXPECT_EQ(r.best().state_id, place) << "a wrong revisit, step " << k;
    }
  });
  EXPECT_GE(first_correct, 0) << "never re-localized";
  EXPECT_LE(first_correct, 1) << "re-localized only at an older state";
}

// Every view of a state. On its second lap the robot sees place 3 changed
// (half its view: a door open), and the trace takes that view as a revisit
// of state 3. Carried back there later, it sees place 3 as on the second
// lap: state 3's own snapshot is not a clear enough match to seed it, the
// revisit's snapshot is. Without relocalization_views only the state's own
// snapshot counts and state 3 is never seeded.
TEST(RelocalizationSeeds, AStateIsSeededByTheViewItsRevisitTook) {
  // Place 3 with half its weight moved to a look no lap place has (bin 15
  // and 15 + 5), the noise of `visit`.
  const auto changedView = [](int visit) {
    Snapshot z = noisyView(3, visit);
    Histogram& h = z.histograms[0];
    for (float& v : h) v *= 0.5f;
    h[kBins - 1] += 0.3f;
    h[(kBins - 1 + 5) % kBins] += 0.2f;
    return z;
  };
  const Snapshot own = noisyView(3, 0), lap_two = changedView(1), carried = changedView(2);
  // The premise: the changed view is far from state 3's own snapshot, close
  // to the second lap's.
  ASSERT_GT(AppearanceSlam::distance(carried.histograms, own.histograms),
            3 * AppearanceSlam::distance(carried.histograms, lap_two.histograms));
  for (const bool views : {true, false}) {
    SlamParams p = seedingParams();
    p.relocalization_views = views;
    // A seed needs chi2 at most 0.2 of the new state's: state 3's own
    // snapshot is not that close to the changed view.
    p.relocalization_match_ratio = 0.2;
    AppearanceSlam slam(p, 1, kBins);
    slam.setActionModel(model());
    slam.initialize(noisyView(0, 0));
    for (int i = 0; i < kPlaces - 1; ++i) slam.step(actionOf(kLap[i]), noisyView(i + 1, 0));
    // The second lap, places 0 to 8; place 3 changed.
    int place = 0;
    StepResult r = slam.step(actionOf(kLap[kPlaces - 1]), noisyView(place, 1));
    while (place < 8) {
      const char a = kLap[place];
      place += 1;
      r = slam.step(actionOf(a), place == 3 ? lap_two : noisyView(place, 1));
      if (place == 3) {
        ASSERT_FALSE(r.best().is_new_state) << "the changed view was not taken as a revisit";
        ASSERT_EQ(r.best().state_id, 3);
      }
    }
    ASSERT_FALSE(r.best().is_new_state);
    // Odometry: on from place 8 to place 9. The robot: put down at place 3.
    r = slam.step(actionOf(kLap[8]), carried);
    const bool seeded_at_3 = revisitedStates(r).count(3) > 0;
    if (views) {
      EXPECT_TRUE(seeded_at_3) << "the revisit's view did not seed its state";
    } else {
      EXPECT_FALSE(seeded_at_3) << "state 3's own snapshot should not match the changed view";
    }
  }
}

// Carried while it follows its map: after the lap the robot drives on along
// it (places 0 to 3, each a revisit), then it is put down at place 8 while
// odometry says it went on to place 4. The revisits traced from place 3 do
// not match, "a new place" leads that step, and the seeds come in the same
// step, so the robot is back at place 8 at once (seeding only after the
// most believed hypothesis had become a new place took one step more).
TEST(RelocalizationSeeds, ARobotCarriedWhileFollowingItsMapIsSeededAtOnce) {
  AppearanceSlam slam(seedingParams(), 1, kBins);
  slam.setActionModel(model());
  slam.initialize(noisyView(0, 0));
  for (int i = 0; i < kPlaces - 1; ++i) slam.step(actionOf(kLap[i]), noisyView(i + 1, 0));
  int place = 0;
  StepResult r = slam.step(actionOf(kLap[kPlaces - 1]), noisyView(place, 1));
  // One move along the lap from `place`, seen on the given visit.
  const auto driveOn = [&](int visit) {
    const char a = kLap[place];
    place = (place + 1) % kPlaces;
    r = slam.step(actionOf(a), noisyView(place, visit));
  };
  for (int k = 0; k < 3; ++k) driveOn(1);
  ASSERT_FALSE(r.best().is_new_state) << "not following its map before the carry";
  ASSERT_EQ(r.best().state_id, place);
  // Odometry: on from place 3 to place 4. The robot: put down at place 8.
  place = 8;
  r = slam.step(actionOf(kLap[3]), noisyView(place, 2));
  EXPECT_GT(r.relocalization_seeds, 0) << "no seed in the step of the carry";
  EXPECT_FALSE(r.best().is_new_state) << "not back in the map at the carry's step";
  EXPECT_EQ(r.best().state_id, place);
  for (int k = 1; k <= 3; ++k) {
    driveOn(2);
    EXPECT_FALSE(r.best().is_new_state) << "lost again " << k << " steps after the carry";
    EXPECT_EQ(r.best().state_id, place) << k << " steps after the carry";
  }
}

// Carried to place FROM at the end of the lap (odometry: on to place 0). The
// trace from the states' first visits, through the whole lap, still reaches
// a place a metre or two from place 0, but only as an unlikely drive
// (P(x | p, u) = exp(-m^2 / 2) below the seeds' prior): such a state is seeded
// as well, and the robot is back where it was put down, not only once the
// trace brings it to where odometry says it is.
TEST(RelocalizationSeeds, AStateTheTraceReachesOnlyUnlikelyIsSeededToo) {
  for (const int from : {1, 2}) {
    AppearanceSlam slam(seedingParams(), 1, kBins);
    slam.setActionModel(model());
    int first_correct = -1;
    lapThenCarried(slam, from, 3, {}, [&](int k, int place, const StepResult& r) {
      const bool correct = !r.best().is_new_state && r.best().state_id == place;
      if (correct && first_correct < 0) first_correct = k;
      if (!r.best().is_new_state) {
        EXPECT_EQ(r.best().state_id, place) << "a wrong revisit, step " << k;
      }
    });
    EXPECT_GE(first_correct, 0) << "never re-localized, carried to " << from;
    EXPECT_LE(first_correct, 1) << "re-localized late, carried to " << from;
  }
}

// Along a corridor whose views all look alike, each snapshot looks like the
// states made just before, a metre back: the view did not jump, so those
// states are not seeded and the robot is somewhere new at every step.
TEST(RelocalizationSeeds, ACorridorOfLookAlikeViewsSeedsNoneOfItsLastStates) {
  for (const int recent_visits : {4, 0}) {
    SlamParams p = seedingParams();
    p.relocalization_recent_visits = recent_visits;
    AppearanceSlam slam(p, 1, kBins);
    slam.setActionModel(model());
    slam.initialize(noisyView(0, 0));
    for (int i = 0; i < kPlaces - 1; ++i) slam.step(actionOf(kLap[i]), noisyView(i + 1, 0));
    // Out of the square and down a corridor: every view is place 20's look
    // (a bin no lap place uses) with its own noise.
    int revisits = 0;
    for (int k = 0; k < 6; ++k) {
      const StepResult r = slam.step({1, 0, 0}, noisyView(kBins - 1, k));
      if (!r.best().is_new_state) ++revisits;
    }
    if (recent_visits > 0) {
      EXPECT_EQ(revisits, 0) << "took the corridor's last states for where the robot is";
    } else {
      EXPECT_GT(revisits, 0) << "without the rule the corridor's last states should be taken";
    }
  }
}

// A restart in a saved map somewhere the map does not cover: the first
// snapshot matches no state (loadMap's global localization finds nothing),
// the robot drives two unmapped steps and then into the map, where a seed
// re-localizes it.
TEST(RelocalizationSeeds, ARestartInASavedMapRelocalizesWhenItReachesTheMap) {
  SavedMap saved;
  {
    AppearanceSlam slam(seedingParams(), 1, kBins);
    slam.setActionModel(model());
    slam.initialize(noisyView(0, 0));
    for (int i = 0; i < kPlaces - 1; ++i) slam.step(actionOf(kLap[i]), noisyView(i + 1, 0));
    saved = slam.bestMap({"forward"});
  }
  ASSERT_EQ(saved.states.size(), static_cast<size_t>(kPlaces));
  AppearanceSlam second(seedingParams(), 1, kBins);
  second.setActionModel(model());
  second.loadMap(saved, {"forward"});
  // Two views of a room the map does not have (gradients in every
  // direction), then the robot drives into the map at place 7 and along it.
  const auto unknownView = [](int k) {
    Snapshot z;
    z.histograms = {Histogram(kBins, 0.8f / kBins)};
    z.histograms[0][static_cast<size_t>(k)] += 0.2f;
    return z;
  };
  StepResult r = second.initialize(unknownView(0));
  EXPECT_TRUE(r.best().is_new_state) << "state " << r.best().state_id;
  r = second.step({1, 0, 0}, unknownView(3));
  EXPECT_TRUE(r.best().is_new_state) << "state " << r.best().state_id;
  int place = 7;
  int first_correct = -1;
  r = second.step({1, 0, 0}, noisyView(place, 1));
  for (int k = 0; k < 6; ++k) {
    if (!r.best().is_new_state) {
      EXPECT_EQ(r.best().state_id, place) << "a wrong revisit " << k << " steps into the map";
      if (first_correct < 0) first_correct = k;
    }
    const char a = kLap[place];
    place = (place + 1) % kPlaces;
    r = second.step(actionOf(a), noisyView(place, 1));
  }
  EXPECT_GE(first_correct, 0) << "never re-entered the saved map";
  EXPECT_LE(first_correct, 3);
}

// Where in a state (an addition): a revisit keeps the robot's traced pose
// drawn toward the state by its extent, offset = S_place (S_trace +
// S_place)^-1 r, and the saved path goes from state to state with it.
TEST(PathHypotheses, ARevisitKeepsWhereTheRobotStoodInTheState) {
  SlamParams p = params();
  p.new_state_ratio = 4.0;  // a view close to state 0's is state 0
  AppearanceSlam slam(p, 1, kBins);
  slam.setActionModel(model());
  slam.initialize(snapshotAt(0));
  const Pose2 u{0.3, 0.1, 0.05};
  Snapshot z = snapshotAt(0);  // state 0's view, a little changed, 0.3 m on
  z.histograms[0][0] = 0.5f;
  z.histograms[0][1] = 0.1f;
  slam.step(u, z);
  const Hypothesis* revisit = nullptr;
  for (const auto& h : slam.hypotheses())
    if (!h.node->is_new) revisit = &h;
  ASSERT_NE(revisit, nullptr);
  ASSERT_EQ(revisit->node->state_id, 0);
  ASSERT_EQ(slam.best().node.get(), revisit->node.get()) << "the identical view should lead";

  const Eigen::Matrix3d trace = model().covariance(u);
  Eigen::Matrix3d place = Eigen::Matrix3d::Zero();
  place.diagonal() << p.place_sigma_m * p.place_sigma_m, p.place_sigma_m * p.place_sigma_m,
      p.place_sigma_rad * p.place_sigma_rad;
  const Eigen::Matrix3d gain_complement = place * (trace + place).inverse();
  const Eigen::Vector3d offset = gain_complement * Eigen::Vector3d(u.x, u.y, u.theta);
  const Eigen::Matrix3d offset_cov = gain_complement * trace;
  EXPECT_NEAR(revisit->node->offset.x, offset.x(), 1e-12);
  EXPECT_NEAR(revisit->node->offset.y, offset.y(), 1e-12);
  EXPECT_NEAR(revisit->node->offset.theta, offset.z(), 1e-12);
  EXPECT_TRUE(revisit->node->offset_covariance.isApprox(offset_cov, 1e-9));
  // Drawn toward the state, not onto it (S_trace is not zero).
  EXPECT_GT(revisit->node->offset.x, 0.05);
  EXPECT_LT(revisit->node->offset.x, u.x);

  // Saved: the link into the revisit ends at the state, u (+) offset^-1.
  const SavedMap map = slam.bestMap({"cam"});
  ASSERT_EQ(map.path.size(), 2u);
  const Pose2 expected = u.compose(revisit->node->offset.inverse());
  EXPECT_NEAR(map.path[1].link.action.x, expected.x, 1e-12);
  EXPECT_NEAR(map.path[1].link.action.y, expected.y, 1e-12);
  EXPECT_NEAR(map.path[1].link.action.theta, expected.theta, 1e-12);
}

// Turned around (an addition): a forward and a backward camera, a corridor
// of 8 places 1 m apart driven to its end, and back. At each place the
// forward camera saw F_p and the backward one B_p; on the way back the
// forward camera sees B_p and the backward one F_p. With the cameras known
// to face each other's way the way back re-visits the corridor's states
// (from the turn on, every step, each the right one) and the map does not
// grow; without, it is a new corridor.
TEST(TurnedAround, TheWayBackIsRecognizedThroughTheOtherCamera) {
  constexpr int kCorridor = 8;
  const auto view = [](int look) {
    Histogram h(kBins, 0.f);
    h[static_cast<size_t>(look % kBins)] = 0.6f;
    h[static_cast<size_t>((look + 3) % kBins)] = 0.4f;
    return h;
  };
  const auto forwardView = [&](int place) { return view(place); };
  const auto backwardView = [&](int place) { return view(place + kCorridor); };
  for (const bool turned : {true, false}) {
    AppearanceSlam slam(params(), 2, kBins);
    slam.setActionModel(model());
    if (turned)
      slam.setTurnedCameras(
          turnedCameras({{Eigen::Vector3d::UnitX(), 1.0}, {-Eigen::Vector3d::UnitX(), 1.0}}));
    Snapshot z;
    z.histograms = {forwardView(0), backwardView(0)};
    slam.initialize(z);
    for (int place = 1; place < kCorridor; ++place) {
      z.histograms = {forwardView(place), backwardView(place)};
      ASSERT_TRUE(slam.step({1, 0, 0}, z).best().is_new_state);
    }
    // Turn around at the end, then drive back.
    int recognized = 0;
    for (int place = kCorridor - 1; place >= 0; --place) {
      z.histograms = {backwardView(place), forwardView(place)};
      const StepResult r =
          slam.step(place == kCorridor - 1 ? Pose2{0, 0, M_PI} : Pose2{1, 0, 0}, z);
      if (!r.best().is_new_state) {
        EXPECT_EQ(r.best().state_id, place) << "a wrong revisit";
        ++recognized;
      }
    }
    if (turned) {
      EXPECT_EQ(recognized, kCorridor) << "the way back was not followed state to state";
      EXPECT_EQ(slam.best().node->num_states, kCorridor) << "the map grew";
    } else {
      EXPECT_EQ(recognized, 0) << "without the turned cameras no view of the way back matches";
    }
  }
}

TEST(TurnedAround, CamerasThatFaceEachOthersWay) {
  const Eigen::Vector3d forward = Eigen::Vector3d::UnitX();
  const double fov = 1.0;
  const auto yawed = [](double deg) {
    const double a = deg * M_PI / 180;
    return Eigen::Vector3d(std::cos(a), std::sin(a), 0);
  };
  using V = std::vector<int>;
  EXPECT_EQ(turnedCameras({{forward, fov}, {-forward, fov}}), (V{1, 0}));
  EXPECT_EQ(turnedCameras({{forward, fov}, {yawed(183), fov}}), (V{1, 0})) << "within 5 degrees";
  EXPECT_EQ(turnedCameras({{forward, fov}}), (V{-1}));
  EXPECT_EQ(turnedCameras({{forward, fov}, {yawed(90), fov}}), (V{-1, -1})) << "sideways";
  EXPECT_EQ(turnedCameras({{forward, fov}, {yawed(170), fov}}), (V{-1, -1}));
  // Tilted up 20 degrees, or seeing wider: their histograms are not comparable.
  const Eigen::Vector3d tilted(-std::cos(0.35), 0, std::sin(0.35));
  EXPECT_EQ(turnedCameras({{forward, fov}, {tilted, fov}}), (V{-1, -1}));
  EXPECT_EQ(turnedCameras({{forward, fov}, {-forward, 1.5}}), (V{-1, -1}));
  // A third camera facing forward again: the first backward match is taken.
  EXPECT_EQ(turnedCameras({{forward, fov}, {-forward, fov}, {forward, fov}}), (V{1, 0, 1}));
  // setTurnedCameras checks what it is given.
  AppearanceSlam slam(params(), 2, kBins);
  EXPECT_THROW(slam.setTurnedCameras({1}), std::invalid_argument);
  EXPECT_THROW(slam.setTurnedCameras({1, 2}), std::invalid_argument);
  EXPECT_NO_THROW(slam.setTurnedCameras({-1, -1}));
}
