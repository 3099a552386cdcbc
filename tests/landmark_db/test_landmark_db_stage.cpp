// The landmark DB stage over LCM's in-memory provider, in lock-step replay:
//  - the protocol on a synthetic log (proposals from two cameras, a repeated
//    and a malformed proposal, requests, statistics, summary);
//  - on rendered frames: the forward and backward front-ends of
//    config/vslam.yaml sharing one DB: every proposal answered with a global
//    id, measurements carry global ids, each camera measures landmarks the
//    other created, and the run is deterministic.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <set>
#include <vslam/health_t.hpp>
#include <vslam/landmark_request_t.hpp>
#include <vslam/landmark_summary_t.hpp>
#include <vslam/landmark_update_t.hpp>
#include <vslam/pose_estimate_t.hpp>
#include <vslam/visual_measurement_t.hpp>

#include "bus/lockstep_replay.hpp"
#include "bus/log_writer.hpp"
#include "landmark_db/landmark_store.hpp"
#include "landmark_db_test_util.hpp"
#include "sim/simulator.hpp"
#include "stages/builtin_stages.hpp"
#include "stages/landmark_db_stage.hpp"
#include "support/test_logs.hpp"

namespace fs = std::filesystem;
using namespace vslam;
using U = vslam::landmark_update_t;

namespace {

constexpr Utime kT0 = 1767225600LL * kMicrosPerSecond;

template <class Msg>
Msg decode(const vslam::test::RecordedEvent& e) {
  Msg m;
  EXPECT_EQ(m.decode(e.data.data(), 0, static_cast<int>(e.data.size())),
            static_cast<int>(e.data.size()));
  return m;
}

U proposal(const std::string& camera, int64_t proposal_id, Utime t, uint32_t seed) {
  const auto s = landmark_db::test::syntheticStructure(30, seed);
  landmark_db::LandmarkInfo info;
  info.camera = camera;
  info.proposal_id = proposal_id;
  info.created_utime = t;
  U m{};
  m.utime = t;
  m.op = U::OP_PROPOSED;
  stages::LandmarkDbStage::fillLandmark(info, &s, &m.landmark);
  m.landmark.landmark_id = -1;
  m.landmark.version = 0;
  return m;
}

stages::LandmarkDbParams dbParams(const config::StackConfig& stack) {
  auto p = stages::LandmarkDbParams::load(stack.process("landmark_db"), stack.robot);
  p.map_file.clear();  // in memory: every run starts empty
  return p;
}

// The DB stage alone, in lock-step replay over dir/in.lcmlog into dir/out.lcmlog.
void replayDb(const fs::path& dir, const config::StackConfig& stack) {
  bus::ReplayOptions options;
  options.input = dir / "in.lcmlog";
  options.output = dir / "out.lcmlog";
  bus::LockstepReplay replay(options);
  replay.addStage("landmark_db", std::make_unique<stages::LandmarkDbStage>(dbParams(stack)));
  replay.run();
}

// The first `duration_s` of the apartment scenario, rendered into dir/sim.lcmlog.
void simulateApartment(const fs::path& dir, const config::StackConfig& stack, double duration_s) {
  sim::Scenario scenario =
      sim::Scenario::loadByName("apartment", fs::path(VSLAM_SOURCE_DIR) / "config/scenarios");
  scenario.duration_s = duration_s;
  sim::Simulator simulator(scenario, stack.robot, kT0);
  sim::LogFileSink sink((dir / "sim.lcmlog").string());
  while (simulator.step(sink)) {
  }
}

// Both front-ends and the DB over dir/sim.lcmlog, in lock-step replay.
void replayFrontendsAndDb(const fs::path& dir, const config::StackConfig& stack,
                          const fs::path& out) {
  bus::ReplayOptions options;
  options.input = dir / "sim.lcmlog";
  options.output = out;
  options.keep_inputs = false;
  bus::LockstepReplay replay(options);
  replay.addStage("landmark_db", std::make_unique<stages::LandmarkDbStage>(dbParams(stack)));
  for (const char* instance : {"frontend_forward", "frontend_backward"}) {
    replay.addStage(instance, stages::builtinStages().create(stack, instance));
  }
  replay.run();
}

}  // namespace

TEST(LandmarkDbStage, AnswersProposalsRequestsAndCountsBadInput) {
  const fs::path dir = vslam::test::scratchDir("landmark_db_stage");
  const auto stack =
      config::StackConfig::loadFile(fs::path(VSLAM_SOURCE_DIR) / "config/vslam.yaml");
  {
    bus::LogWriter log(dir / "in.lcmlog");
    Utime t = kT0;
    log.writeMessage(t, "LANDMARK_PROPOSAL", proposal("forward", 11, t, 1));
    t += 1000;
    log.writeMessage(t, "LANDMARK_PROPOSAL", proposal("backward", 11, t, 2));
    t += 1000;
    log.writeMessage(t, "LANDMARK_PROPOSAL", proposal("forward", 12, t, 3));
    t += 1000;
    log.writeMessage(t, "LANDMARK_PROPOSAL", proposal("forward", 11, kT0, 1));  // sent again
    U bad = proposal("forward", 13, t, 4);
    bad.landmark.points[3][1] = NAN;
    t += 1000;
    log.writeMessage(t, "LANDMARK_PROPOSAL", bad);
    U truncated = proposal("forward", 14, t, 5);
    truncated.landmark.descriptor_size = 64;
    for (auto& d : truncated.landmark.descriptors) d.resize(64);
    t += 1000;
    log.writeMessage(t, "LANDMARK_PROPOSAL", truncated);
    vslam::visual_measurement_t m{};
    m.utime = t;
    m.camera = "forward";
    m.landmark_id = 2;
    t += 1000;
    log.writeMessage(t, "VISUAL_MEASUREMENT", m);
    m.landmark_id = 777;  // unknown
    t += 1000;
    log.writeMessage(t, "VISUAL_MEASUREMENT", m);
    vslam::landmark_request_t r{};
    r.utime = t;
    r.requester = "frontend_late";
    r.database_id = "";
    r.since_revision = 0;
    t += 1000;
    log.writeMessage(t, "LANDMARK_REQUEST", r);
    r.requester = "frontend_ids";
    r.landmark_ids = {3, 999};
    r.num_ids = 2;
    t += 1000;
    log.writeMessage(t, "LANDMARK_REQUEST", r);
    // Past a flush and a summary period.
    vslam::visual_measurement_t later = m;
    later.landmark_id = 1;
    t += 2 * kMicrosPerSecond;
    log.writeMessage(t, "VISUAL_MEASUREMENT", later);
    t += 2 * kMicrosPerSecond;
    log.writeMessage(t, "VISUAL_MEASUREMENT", later);
    // A last event past the next flush (its timer runs before the event).
    r.requester = "nobody";
    r.landmark_ids = {999};
    r.num_ids = 1;
    t += 2 * kMicrosPerSecond;
    log.writeMessage(t, "LANDMARK_REQUEST", r);
  }
  replayDb(dir, stack);

  std::vector<U> updates;
  std::vector<vslam::landmark_summary_t> summaries;
  for (const auto& e : vslam::test::readLog(dir / "out.lcmlog")) {
    if (e.channel == "LANDMARK_UPDATE") updates.push_back(decode<U>(e));
    if (e.channel == "LANDMARK_SUMMARY") summaries.push_back(decode<vslam::landmark_summary_t>(e));
  }
  ASSERT_GE(updates.size(), 8u);
  // Three created, ids 1..3 in order, revisions 1..3, with the proposer's ids.
  EXPECT_EQ(updates[0].op, U::OP_CREATED);
  EXPECT_EQ(updates[0].landmark.landmark_id, 1);
  EXPECT_EQ(updates[0].landmark.camera, "forward");
  EXPECT_EQ(updates[0].landmark.proposal_id, 11);
  EXPECT_EQ(updates[0].landmark.num_points, 30);
  EXPECT_EQ(updates[0].revision, 1);
  EXPECT_EQ(updates[1].landmark.landmark_id, 2);
  EXPECT_EQ(updates[1].landmark.camera, "backward");
  EXPECT_EQ(updates[2].landmark.landmark_id, 3);
  EXPECT_EQ(updates[2].revision, 3);
  // The repeated proposal: the same id again, as a snapshot (no new revision).
  EXPECT_EQ(updates[3].op, U::OP_SNAPSHOT);
  EXPECT_EQ(updates[3].landmark.landmark_id, 1);
  EXPECT_EQ(updates[3].landmark.proposal_id, 11);
  EXPECT_EQ(updates[3].revision, 3);
  // The malformed ones: rejected, named by their proposal ids.
  EXPECT_EQ(updates[4].op, U::OP_REJECTED);
  EXPECT_EQ(updates[4].landmark.proposal_id, 13);
  EXPECT_EQ(updates[5].op, U::OP_REJECTED);
  EXPECT_EQ(updates[5].landmark.proposal_id, 14);
  // Request since revision 0 from a stranger: all three, addressed to it.
  std::vector<int64_t> late, by_id;
  for (const auto& u : updates) {
    if (u.op == U::OP_SNAPSHOT && u.requester == "frontend_late")
      late.push_back(u.landmark.landmark_id);
    if (u.op == U::OP_SNAPSHOT && u.requester == "frontend_ids")
      by_id.push_back(u.landmark.landmark_id);
  }
  EXPECT_EQ(late, (std::vector<int64_t>{1, 2, 3}));
  EXPECT_EQ(by_id, (std::vector<int64_t>{3}));
  // Statistics: landmark 2 measured once, 1 twice; stats-only updates after a flush.
  std::map<int64_t, int> recognitions;
  for (const auto& u : updates) {
    if (u.op == U::OP_UPDATED) {
      EXPECT_EQ(u.landmark.num_points, 0);
      recognitions[u.landmark.landmark_id] = u.landmark.num_recognitions;
    }
  }
  EXPECT_EQ(recognitions[2], 1);
  EXPECT_EQ(recognitions[1], 2);
  // Revisions of changes are consecutive.
  int64_t last = 0;
  for (const auto& u : updates) {
    if (u.op == U::OP_SNAPSHOT || u.op == U::OP_REJECTED) continue;
    EXPECT_EQ(u.revision, last + 1);
    last = u.revision;
  }
  ASSERT_FALSE(summaries.empty());
  EXPECT_EQ(summaries.back().num_stored, 3);
  EXPECT_EQ(summaries.back().landmark_ids, (std::vector<int64_t>{1, 2, 3}));
  EXPECT_EQ(summaries.back().revision, last);
  EXPECT_EQ(summaries.back().database_id, updates[0].database_id);
  fs::remove_all(dir);
}

// A front-end's refined points (OP_REVISED on the proposal channel): stored
// and published as OP_UPDATED with the whole structure, so replicas adopt
// them; a revision from another camera, or with a non-finite point, is
// refused and publishes nothing.
TEST(LandmarkDbStage, RevisedPointsArePublishedWithTheStructure) {
  const fs::path dir = vslam::test::scratchDir("landmark_db_stage_revision");
  const auto stack =
      config::StackConfig::loadFile(fs::path(VSLAM_SOURCE_DIR) / "config/vslam.yaml");
  U revision = proposal("forward", 11, kT0, 1);
  revision.op = U::OP_REVISED;
  revision.landmark.landmark_id = 1;
  for (auto& p : revision.landmark.points) p[0] *= 0.9f;
  {
    bus::LogWriter log(dir / "in.lcmlog");
    log.writeMessage(kT0, "LANDMARK_PROPOSAL", proposal("forward", 11, kT0, 1));
    U stranger = revision;
    stranger.landmark.camera = "backward";
    log.writeMessage(kT0 + 1000, "LANDMARK_PROPOSAL", stranger);
    U malformed = revision;
    malformed.landmark.points[2][1] = NAN;
    log.writeMessage(kT0 + 1500, "LANDMARK_PROPOSAL", malformed);
    log.writeMessage(kT0 + 2000, "LANDMARK_PROPOSAL", revision);
  }
  replayDb(dir, stack);

  std::vector<U> updates;
  for (const auto& e : vslam::test::readLog(dir / "out.lcmlog")) {
    if (e.channel == "LANDMARK_UPDATE") updates.push_back(decode<U>(e));
  }
  ASSERT_EQ(updates.size(), 2u)
      << "created, then one update: the stranger's and the malformed one change nothing";
  EXPECT_EQ(updates[0].op, U::OP_CREATED);
  EXPECT_EQ(updates[1].op, U::OP_UPDATED);
  EXPECT_EQ(updates[1].revision, 2);
  EXPECT_EQ(updates[1].landmark.landmark_id, 1);
  EXPECT_EQ(updates[1].landmark.version, updates[0].landmark.version + 1);
  ASSERT_EQ(updates[1].landmark.num_points, 30);
  EXPECT_EQ(updates[1].landmark.points, revision.landmark.points);
  EXPECT_EQ(updates[1].landmark.descriptors, updates[0].landmark.descriptors);
  fs::remove_all(dir);
}

// The back-end's estimates reach the map file (what a restarted back-end
// resumes from), at the statistics' pace, and a kidnapped one clears it.
TEST(LandmarkDbStage, KeepsTheBackendsNewestEstimateInTheMapFile) {
  const fs::path dir = vslam::test::scratchDir("landmark_db_stage_robot_pose");
  const auto stack =
      config::StackConfig::loadFile(fs::path(VSLAM_SOURCE_DIR) / "config/vslam.yaml");
  auto params = stages::LandmarkDbParams::load(stack.process("landmark_db"), stack.robot);
  auto run = [&](double kidnapped_from_s) {
    fs::remove(dir / "map.vslam-map");
    {
      bus::LogWriter log(dir / "in.lcmlog");
      for (int k = 0; k <= 150; ++k) {  // 3 s at 50 Hz, driving along x
        vslam::pose_estimate_t p{};
        p.utime = kT0 + k * 20'000;
        p.seq = k;
        p.x = 1.0 + 0.01 * k;
        p.y = -2.0;
        p.theta = 0.5;
        p.odom_x = 0.01 * k;
        p.covariance[0] = p.covariance[4] = 0.02 * 0.02;
        p.covariance[8] = 1e-4;
        p.kidnapped = k * 0.02 >= kidnapped_from_s;
        log.writeMessage(p.utime, "POSE_ESTIMATE", p);
      }
    }
    bus::ReplayOptions options;
    options.input = dir / "in.lcmlog";
    options.output = dir / "out.lcmlog";
    bus::LockstepReplay replay(options);
    params.map_file = dir / "map.vslam-map";
    replay.addStage("landmark_db", std::make_unique<stages::LandmarkDbStage>(params));
    replay.run();
    landmark_db::StoreOptions read;
    read.create_if_missing = false;
    read.read_only = true;
    return landmark_db::LandmarkStore(dir / "map.vslam-map", read).robotPose();
  };
  const auto saved = run(1e9);
  ASSERT_TRUE(saved);
  EXPECT_EQ(saved->utime, kT0 + 150 * 20'000) << "the newest, written when the DB stopped";
  EXPECT_DOUBLE_EQ(saved->map_pose.x, 2.5);
  EXPECT_DOUBLE_EQ(saved->map_pose.theta, 0.5);
  EXPECT_DOUBLE_EQ(saved->odom_pose.x, 1.5);
  EXPECT_DOUBLE_EQ(saved->covariance[8], 1e-4);
  EXPECT_FALSE(run(2.0)) << "the robot was kidnapped at 2 s: no pose to resume from";
  fs::remove_all(dir);
}

// Both front-ends and one DB on rendered frames of the apartment.
TEST(LandmarkDbStage, TwoFrontendsShareOneDatabaseOnRenderedFrames) {
  const fs::path dir = vslam::test::scratchDir("landmark_db_shared");
  const fs::path source(VSLAM_SOURCE_DIR);
  const auto stack = config::StackConfig::loadFile(source / "config/vslam.yaml");
  // The forward camera first measures a backward landmark at ~68 s.
  simulateApartment(dir, stack, 80);
  replayFrontendsAndDb(dir, stack, dir / "run.lcmlog");

  std::map<int64_t, std::string> creator;  // global id -> camera
  std::set<std::pair<std::string, int64_t>> proposed, answered;
  std::vector<vslam::visual_measurement_t> measurements;
  for (const auto& e : vslam::test::readLog(dir / "run.lcmlog")) {
    if (e.channel == "LANDMARK_PROPOSAL") {
      const auto u = decode<U>(e);
      // New landmarks (no global id yet), and the refined points of created ones
      // (refine_distance_m; FrontendsReviseTheirLandmarks... checks those).
      if (u.op == U::OP_REVISED) {
        EXPECT_GT(u.landmark.landmark_id, 0);
        continue;
      }
      EXPECT_EQ(u.op, U::OP_PROPOSED);
      EXPECT_EQ(u.landmark.landmark_id, -1);
      proposed.insert({u.landmark.camera, u.landmark.proposal_id});
    }
    if (e.channel == "LANDMARK_UPDATE") {
      const auto u = decode<U>(e);
      if (u.op == U::OP_CREATED) {
        creator[u.landmark.landmark_id] = u.landmark.camera;
        answered.insert({u.landmark.camera, u.landmark.proposal_id});
      }
    }
    if (e.channel == "VISUAL_MEASUREMENT") {
      measurements.push_back(decode<vslam::visual_measurement_t>(e));
    }
  }
  ASSERT_GE(creator.size(), 4u);
  EXPECT_EQ(proposed, answered) << "every proposal gets its global id";
  // Global ids 1..N.
  EXPECT_EQ(creator.begin()->first, 1);
  EXPECT_EQ(creator.rbegin()->first, static_cast<int64_t>(creator.size()));
  ASSERT_GE(measurements.size(), 50u);
  std::map<std::string, int> cross;  // measuring camera -> measurements of the other's landmarks
  for (const auto& m : measurements) {
    ASSERT_TRUE(creator.count(m.landmark_id))
        << "measurement of landmark " << m.landmark_id << " the DB never created";
    if (creator[m.landmark_id] != m.camera) ++cross[m.camera];
  }
  EXPECT_GT(cross["forward"], 0) << "forward camera never measured a backward landmark";
  EXPECT_GT(cross["backward"], 0) << "backward camera never measured a forward landmark";
  RecordProperty("landmarks", static_cast<int>(creator.size()));
  RecordProperty("measurements", static_cast<int>(measurements.size()));
  RecordProperty("cross_forward", cross["forward"]);
  RecordProperty("cross_backward", cross["backward"]);
  // That two replays of both front-ends and the DB give the same bytes is
  // ReplayIsolation's check (tests/framework): a second 80 s replay here
  // doubled the suite's longest test.
  fs::remove_all(dir);
}

// With refine_distance_m (the shipped config's 0.8 m) both front-ends refine
// their landmarks from later views and send the refined points (OP_REVISED,
// with the global id the DB gave); the DB stores them and publishes them with
// the structure, so the replicas adopt them.
TEST(LandmarkDbStage, FrontendsReviseTheirLandmarksAndTheDbPublishesTheRefinedPoints) {
  const fs::path dir = vslam::test::scratchDir("landmark_db_revised");
  const auto stack =
      config::StackConfig::loadFile(fs::path(VSLAM_SOURCE_DIR) / "config/vslam.yaml");
  simulateApartment(dir, stack, 30);
  replayFrontendsAndDb(dir, stack, dir / "run.lcmlog");

  std::map<int64_t, U> created, revised, republished;  // by global id
  for (const auto& e : vslam::test::readLog(dir / "run.lcmlog")) {
    if (e.channel != "LANDMARK_PROPOSAL" && e.channel != "LANDMARK_UPDATE") continue;
    const U u = decode<U>(e);
    if (u.op == U::OP_CREATED) created[u.landmark.landmark_id] = u;
    if (u.op == U::OP_REVISED) revised[u.landmark.landmark_id] = u;
    if (u.op == U::OP_UPDATED && u.landmark.num_points > 0) republished[u.landmark.landmark_id] = u;
  }
  ASSERT_GE(created.size(), 2u);
  ASSERT_GE(revised.size(), 1u) << "no landmark refined in 30 s of the apartment";
  for (const auto& [id, r] : revised) {
    SCOPED_TRACE(id);
    ASSERT_TRUE(created.count(id)) << "a revision of a landmark the DB never created";
    const U& c = created.at(id);
    EXPECT_EQ(r.landmark.camera, c.landmark.camera);
    EXPECT_EQ(r.landmark.proposal_id, c.landmark.proposal_id);
    EXPECT_EQ(r.landmark.descriptors, c.landmark.descriptors) << "only the points move";
    EXPECT_NE(r.landmark.points, c.landmark.points);
    ASSERT_TRUE(republished.count(id)) << "the DB did not publish the refined points";
    EXPECT_EQ(republished.at(id).landmark.points, r.landmark.points);
    EXPECT_GT(republished.at(id).landmark.version, c.landmark.version);
  }
  RecordProperty("landmarks", static_cast<int>(created.size()));
  RecordProperty("revised", static_cast<int>(revised.size()));
  fs::remove_all(dir);
}

// Issue 19: on a full disk the proposals got neither OP_CREATED nor
// OP_REJECTED, so the front-ends were never told. A map file capped at
// 0.25 MiB fills as a full disk would: every proposal is answered, the ones
// that no longer fit are rejected, health says why, and every landmark
// acknowledged as created is still in the file afterwards.
TEST(LandmarkDbStage, RejectsProposalsItCannotStoreAndKeepsTheOthers) {
  const fs::path dir = vslam::test::scratchDir("landmark_db_stage_full");
  const auto stack =
      config::StackConfig::loadFile(fs::path(VSLAM_SOURCE_DIR) / "config/vslam.yaml");
  constexpr int kProposals = 120;
  {
    bus::LogWriter log(dir / "in.lcmlog");
    for (int k = 0; k < kProposals; ++k) {
      const Utime t = kT0 + k * 100000;
      log.writeMessage(t, "LANDMARK_PROPOSAL",
                       proposal("forward", 100 + k, t, static_cast<uint32_t>(k)));
    }
  }
  auto params = dbParams(stack);
  params.map_file = dir / "map.vslam-map";
  params.max_map_file_mb = 0.25;
  bus::ReplayOptions options;
  options.input = dir / "in.lcmlog";
  options.output = dir / "out.lcmlog";
  options.keep_health = true;
  {
    bus::LockstepReplay replay(options);
    replay.addStage("landmark_db", std::make_unique<stages::LandmarkDbStage>(params));
    replay.run();
  }
  std::set<int64_t> answered, created_ids;
  int created = 0, rejected = 0;
  bool failed_health = false;
  for (const auto& e : vslam::test::readLog(dir / "out.lcmlog")) {
    if (e.channel == "LANDMARK_UPDATE") {
      const U u = decode<U>(e);
      if (u.op == U::OP_CREATED) {
        ++created;
        created_ids.insert(u.landmark.landmark_id);
      }
      rejected += u.op == U::OP_REJECTED;
      if (u.op == U::OP_CREATED || u.op == U::OP_REJECTED) answered.insert(u.landmark.proposal_id);
    }
    if (e.channel == "HEALTH") {
      const auto h = decode<vslam::health_t>(e);
      if (h.level == vslam::health_t::LEVEL_ERROR &&
          h.message.find("new landmarks are rejected, stored ones are kept") != std::string::npos)
        failed_health = true;
    }
  }
  EXPECT_EQ(static_cast<int>(answered.size()), kProposals) << "every proposal answered";
  EXPECT_GT(created, 5);
  EXPECT_GT(rejected, 5);
  EXPECT_EQ(created + rejected, kProposals);
  EXPECT_TRUE(failed_health);
  // Nothing acknowledged is lost: the file holds exactly the created landmarks.
  landmark_db::StoreOptions ro;
  ro.read_only = true;
  ro.create_if_missing = false;
  landmark_db::LandmarkStore store(params.map_file, ro);
  std::set<int64_t> stored;
  for (const auto& info : store.loadAllInfo()) stored.insert(info.id);
  EXPECT_EQ(stored, created_ids);
  fs::remove_all(dir);
}
