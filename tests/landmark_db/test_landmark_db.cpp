// The landmark database library (no LCM): the map file (ids, persistence,
// foreign and damaged files), proposals, pruning and segmentation policies.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>

#include "landmark_db/landmark_database.hpp"
#include "landmark_db/map_tool.hpp"
#include "landmark_db_test_util.hpp"
#include "support/test_logs.hpp"

namespace fs = std::filesystem;
using namespace vslam;
using namespace vslam::landmark_db;
using landmark_db::test::syntheticInfo;
using landmark_db::test::syntheticStructure;

namespace {

constexpr Utime kT0 = 1767225600LL * kMicrosPerSecond;

std::unique_ptr<LandmarkDatabase> openDb(const fs::path& file, DatabaseParams p = {},
                                         bool power_safe = true) {
  StoreOptions so;
  so.new_database_id = "test-db";
  so.power_safe = power_safe;
  return std::make_unique<LandmarkDatabase>(std::make_unique<LandmarkStore>(file, so), p);
}

class LandmarkDbTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = vslam::test::scratchDir("landmark_db"); }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

}  // namespace

TEST_F(LandmarkDbTest, AssignsStableIdsAndReloadsEverythingFromTheFile) {
  const fs::path file = dir_ / "map.vslam-map";
  std::vector<int64_t> ids;
  {
    auto db = openDb(file);
    EXPECT_EQ(db->databaseId(), "test-db");
    for (int k = 0; k < 5; ++k) {
      auto r = db->propose(
          syntheticInfo(k % 2 ? "backward" : "forward", 100 + k, kT0 + k, {k * 1.0, 0, 0}),
          syntheticStructure(40 + k, k));
      ASSERT_EQ(r.outcome, ProposalOutcome::kCreated) << r.reason;
      ASSERT_EQ(r.changes.size(), 1u);
      EXPECT_EQ(r.changes[0].op, ChangeOp::kCreated);
      EXPECT_EQ(r.changes[0].revision, k + 1);
      ids.push_back(r.id);
    }
    EXPECT_EQ(ids, (std::vector<int64_t>{1, 2, 3, 4, 5}));
    // The same proposal again (its answer was lost): the same id, no change.
    auto again =
        db->propose(syntheticInfo("backward", 101, kT0 + 1, {1, 0, 0}), syntheticStructure(41, 1));
    EXPECT_EQ(again.outcome, ProposalOutcome::kAlreadyKnown);
    EXPECT_EQ(again.id, 2);
    EXPECT_EQ(db->revision(), 5);
    // The same proposal id with other content (another run): a new landmark.
    auto other =
        db->propose(syntheticInfo("backward", 101, kT0 + 9, {1, 0, 0}), syntheticStructure(41, 77));
    EXPECT_EQ(other.outcome, ProposalOutcome::kCreated);
    EXPECT_EQ(other.id, 6);
    EXPECT_TRUE(db->recordMeasurement(3, kT0 + 50));
    EXPECT_TRUE(db->recordVerdict(3, true, kT0 + 50));
    EXPECT_FALSE(db->recordMeasurement(99, kT0));
    const auto updated = db->flush();
    ASSERT_EQ(updated.size(), 1u);
    EXPECT_TRUE(updated[0].stats_only);
  }
  auto db = openDb(file);
  EXPECT_EQ(db->databaseId(), "test-db");
  EXPECT_EQ(db->numStored(), 6u);
  EXPECT_EQ(db->revision(), 7);
  const LandmarkInfo* i3 = db->info(3);
  ASSERT_NE(i3, nullptr);
  EXPECT_EQ(i3->camera, "forward");
  EXPECT_EQ(i3->proposal_id, 102);
  EXPECT_EQ(i3->stats.num_recognitions, 1);
  EXPECT_EQ(i3->stats.num_accepted, 1);
  EXPECT_EQ(i3->version, 2);
  EXPECT_DOUBLE_EQ(i3->created_odom.x, 2.0);
  const auto st = db->structure(3);
  ASSERT_NE(st, nullptr);
  const auto expected = syntheticStructure(42, 2);
  EXPECT_EQ(st->descriptors, expected.descriptors);
  EXPECT_EQ(st->points, expected.points);
  // Ids continue after the highest ever given.
  auto r = db->propose(syntheticInfo("forward", 500, kT0, {}), syntheticStructure(30, 9));
  EXPECT_EQ(r.id, 7);
  EXPECT_EQ(db->store().integrityCheck(), "ok");
}

// A front-end's refinement of its landmark (OP_REVISED): the points change,
// durably, with a new version and a kUpdated change that carries the
// structure; the descriptors and everything else stay; a revision from
// another camera, of an unknown landmark or with another number of points is
// refused and changes nothing.
TEST_F(LandmarkDbTest, ARevisionFromItsProposerReplacesThePointsDurably) {
  const fs::path file = dir_ / "map.vslam-map";
  const auto original = syntheticStructure(40, 3);
  std::vector<float> refined = original.points;
  for (float& v : refined) v *= 0.95f;
  {
    auto db = openDb(file);
    const auto created = db->propose(syntheticInfo("forward", 100, kT0, {}), original);
    ASSERT_EQ(created.outcome, ProposalOutcome::kCreated) << created.reason;
    const int64_t id = created.id;
    const int32_t version = db->info(id)->version;

    EXPECT_NE(db->revise(id, "backward", 100, refined).reason, "");
    EXPECT_NE(db->revise(id, "forward", 101, refined).reason, "");
    EXPECT_NE(db->revise(id + 1, "forward", 100, refined).reason, "");
    EXPECT_NE(db->revise(id, "forward", 100, std::vector<float>(refined.begin(), refined.end() - 3))
                  .reason,
              "");
    std::vector<float> not_finite = refined;
    not_finite[4] = NAN;
    EXPECT_NE(db->revise(id, "forward", 100, not_finite).reason, "");
    EXPECT_EQ(db->revision(), 1) << "nothing changed";
    EXPECT_EQ(db->structure(id)->points, original.points);

    const auto r = db->revise(id, "forward", 100, refined);
    ASSERT_EQ(r.reason, "");
    ASSERT_EQ(r.changes.size(), 1u);
    EXPECT_EQ(r.changes[0].op, ChangeOp::kUpdated);
    EXPECT_FALSE(r.changes[0].stats_only) << "the structure changed";
    EXPECT_EQ(r.changes[0].revision, 2);
    EXPECT_EQ(db->info(id)->version, version + 1);
    EXPECT_EQ(db->structure(id)->points, refined);
    EXPECT_EQ(db->structure(id)->descriptors, original.descriptors);
  }
  DatabaseParams localization;
  localization.allow_new_landmarks = false;
  auto frozen = openDb(file, localization);
  EXPECT_NE(frozen->revise(1, "forward", 100, original.points).reason, "")
      << "a map opened for localization only stays as it is";
  frozen.reset();
  auto db = openDb(file);
  ASSERT_NE(db->structure(1), nullptr);
  EXPECT_EQ(db->structure(1)->points, refined);
  EXPECT_EQ(db->structure(1)->keypoints, original.keypoints);
  EXPECT_EQ(db->revision(), 2);
  EXPECT_EQ(db->store().integrityCheck(), "ok");
}

TEST_F(LandmarkDbTest, AClosedMapIsOneFileThatAReadOnlyLookLeavesAlone) {
  const fs::path file = dir_ / "map.vslam-map";
  {
    auto db = openDb(file);
    ASSERT_EQ(db->propose(syntheticInfo("forward", 1, kT0, {}), syntheticStructure(30, 1)).outcome,
              ProposalOutcome::kCreated);
    EXPECT_TRUE(fs::exists(file.string() + "-wal")) << "open, the map writes ahead";
  }
  EXPECT_FALSE(fs::exists(file.string() + "-wal")) << "closed: one file";
  EXPECT_FALSE(fs::exists(file.string() + "-shm"));
  {
    StoreOptions read_only;
    read_only.read_only = true;
    LandmarkStore store(file, read_only);  // as vslam-map list opens it
    EXPECT_EQ(store.loadAllInfo().size(), 1u);
  }
  EXPECT_FALSE(fs::exists(file.string() + "-wal")) << "a read-only look creates nothing";
  EXPECT_FALSE(fs::exists(file.string() + "-shm"));
  EXPECT_EQ(openDb(file)->numStored(), 1u) << "and it opens for writing again";
}

TEST_F(LandmarkDbTest, InvalidProposalsAreRefusedAndNothingIsStored) {
  auto db = openDb(dir_ / "map.vslam-map");
  auto bad = syntheticStructure(20, 1);
  bad.points[4] = NAN;
  EXPECT_EQ(db->propose(syntheticInfo("forward", 1, kT0, {}), bad).outcome,
            ProposalOutcome::kInvalid);
  auto short_desc = syntheticStructure(20, 1);
  short_desc.descriptors.resize(100);
  EXPECT_EQ(db->propose(syntheticInfo("forward", 1, kT0, {}), short_desc).outcome,
            ProposalOutcome::kInvalid);
  EXPECT_EQ(db->propose(syntheticInfo("", 1, kT0, {}), syntheticStructure(20, 1)).outcome,
            ProposalOutcome::kInvalid);
  // Issue 19: a 100,000-point proposal was stored (3.9 MB) and copied into every replica.
  const auto huge = db->propose(syntheticInfo("forward", 2, kT0, {}),
                                syntheticStructure(kMaxLandmarkPoints + 1, 1));
  EXPECT_EQ(huge.outcome, ProposalOutcome::kInvalid);
  EXPECT_NE(huge.reason.find("more than the 2048"), std::string::npos) << huge.reason;

  EXPECT_EQ(
      db->propose(syntheticInfo("forward", 1, kT0, {NAN, 0, 0}), syntheticStructure(20, 1)).outcome,
      ProposalOutcome::kInvalid);
  EXPECT_EQ(db->numStored(), 0u);
  EXPECT_EQ(db->revision(), 0);
}

TEST_F(LandmarkDbTest, ALandmarkOfTheMostPointsAllowedIsStored) {
  auto db = openDb(dir_ / "map.vslam-map");
  EXPECT_EQ(
      db->propose(syntheticInfo("forward", 1, kT0, {}), syntheticStructure(kMaxLandmarkPoints, 1))
          .outcome,
      ProposalOutcome::kCreated);
  EXPECT_EQ(db->numStored(), 1u);
}

TEST_F(LandmarkDbTest, LocalizationOnlyMapRefusesNewLandmarks) {
  const fs::path file = dir_ / "map.vslam-map";
  { openDb(file)->propose(syntheticInfo("forward", 1, kT0, {}), syntheticStructure(20, 1)); }
  DatabaseParams p;
  p.allow_new_landmarks = false;
  auto db = openDb(file, p);
  EXPECT_EQ(db->numStored(), 1u);
  const auto r = db->propose(syntheticInfo("forward", 2, kT0, {}), syntheticStructure(20, 2));
  EXPECT_EQ(r.outcome, ProposalOutcome::kRefused);
  EXPECT_EQ(db->numStored(), 1u);
  EXPECT_TRUE(db->recordMeasurement(1, kT0));  // statistics still kept
}

TEST_F(LandmarkDbTest, ForeignAndDamagedFilesGiveAClearErrorAndAreLeftUntouched) {
  // Not SQLite at all.
  const fs::path text = dir_ / "notes.txt";
  std::ofstream(text) << "these are not the landmarks you are looking for\n";
  // Empty.
  const fs::path empty = dir_ / "empty.vslam-map";
  std::ofstream{empty};
  // Another application's SQLite database.
  const fs::path foreign = dir_ / "foreign.sqlite";
  {
    sqlite3* db = nullptr;
    ASSERT_EQ(sqlite3_open(foreign.c_str(), &db), SQLITE_OK);
    sqlite3_exec(db, "CREATE TABLE landmarks(x); INSERT INTO landmarks VALUES (1);", nullptr,
                 nullptr, nullptr);
    sqlite3_close(db);
  }
  // A landmark map damaged in the middle (a b-tree page overwritten).
  const fs::path damaged = dir_ / "damaged.vslam-map";
  {
    auto db = openDb(damaged);
    for (int k = 0; k < 30; ++k) {
      db->propose(syntheticInfo("forward", k, kT0, {}), syntheticStructure(60, k));
    }
  }
  {
    std::fstream f(damaged, std::ios::in | std::ios::out | std::ios::binary);
    ASSERT_TRUE(f.good());
    f.seekp(4096 + 16);  // inside page 2: the landmarks table's root
    const std::string junk(3000, '\x5a');
    f.write(junk.data(), static_cast<std::streamsize>(junk.size()));
  }
  // A landmark map cut to half its size (a copy interrupted; issue 19: it
  // was refused, but new -wal and -shm files were left beside it).
  const fs::path truncated = dir_ / "truncated.vslam-map";
  {
    auto db = openDb(truncated);
    for (int k = 0; k < 30; ++k) {
      db->propose(syntheticInfo("forward", k, kT0, {}), syntheticStructure(60, k));
    }
  }
  fs::resize_file(truncated, fs::file_size(truncated) / 2);
  const std::pair<fs::path, std::string> cases[] = {{text, "not an SQLite database"},
                                                    {empty, "empty file"},
                                                    {foreign, "not a vslam landmark map"},
                                                    {damaged, "damaged"},
                                                    {truncated, "malformed"}};
  for (const auto& [file, expected] : cases) {
    const std::string before = landmark_db::test::fileBytes(file);
    try {
      openDb(file);
      ADD_FAILURE() << file << " was accepted";
    } catch (const MapFileError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos)
          << file << ": " << e.what();
      EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
    }
    EXPECT_EQ(landmark_db::test::fileBytes(file), before) << file << " was modified";
    EXPECT_FALSE(fs::exists(file.string() + "-wal")) << file;
    EXPECT_FALSE(fs::exists(file.string() + "-shm")) << file;
    // And read-only, as vslam-map opens it.
    StoreOptions read_only;
    read_only.read_only = true;
    read_only.create_if_missing = false;
    EXPECT_THROW(LandmarkStore(file, read_only), MapFileError) << file;
    EXPECT_EQ(landmark_db::test::fileBytes(file), before) << file << " was modified";
    EXPECT_FALSE(fs::exists(file.string() + "-wal")) << file << " (read-only)";
    EXPECT_FALSE(fs::exists(file.string() + "-shm")) << file << " (read-only)";
  }
}

TEST_F(LandmarkDbTest, PrunesRarelyRecognizedPoorAndDuplicateLandmarks) {
  DatabaseParams p;
  p.prune.min_age_s = 60;
  p.prune.min_recognitions = 3;
  p.prune.min_verdicts = 10;
  p.prune.min_accepted_ratio = 0.3;
  p.prune.duplicate_distance_m = 0.3;
  p.prune.duplicate_angle_deg = 20;
  p.prune.duplicate_min_shared = 0.3;
  p.camera_yaw = {{"forward", 0.0}, {"backward", M_PI}};
  auto db = openDb(dir_ / "map.vslam-map", p);
  const auto add = [&](const std::string& cam, int64_t pid, Utime t, Pose2 pose, uint32_t seed) {
    auto r = db->propose(syntheticInfo(cam, pid, t, pose), syntheticStructure(50, seed));
    EXPECT_EQ(r.outcome, ProposalOutcome::kCreated);
    return r.id;
  };
  const auto use = [&](int64_t id, int n, int accepted) {
    for (int k = 0; k < n; ++k) {
      db->recordMeasurement(id, kT0);
      db->recordVerdict(id, k < accepted, kT0);
    }
  };
  const int64_t good = add("forward", 1, kT0, {0, 0, 0}, 1);
  use(good, 20, 18);
  const int64_t rare = add("forward", 2, kT0, {5, 0, 0}, 2);
  use(rare, 2, 2);
  const int64_t poor = add("forward", 3, kT0, {10, 0, 0}, 3);
  use(poor, 20, 4);
  const int64_t young =
      add("forward", 4, kT0 + fromSeconds(100), {15, 0, 0}, 4);  // never seen, but young
  // A second landmark of good's place (same descriptors, 10 cm away, same heading), less used.
  const int64_t dup = add("forward", 5, kT0, {0.1, 0, 0.05}, 1);
  use(dup, 5, 4);
  // Backward camera at good's place but turned round: looks the same way, same descriptors.
  const int64_t dup_turned = add("backward", 6, kT0, {0.0, 0.1, M_PI}, 1);
  use(dup_turned, 5, 5);
  // Same place, other descriptors: not a duplicate.
  const int64_t neighbour = add("forward", 7, kT0, {0.05, 0.05, 0}, 70);
  use(neighbour, 5, 5);
  // Same descriptors, other direction (forward camera turned round): not a duplicate.
  const int64_t opposite = add("forward", 8, kT0, {0.0, 0.0, M_PI}, 1);
  use(opposite, 5, 5);
  db->flush();

  const Utime now = kT0 + fromSeconds(120);
  const auto dry = db->prune(now, true);
  EXPECT_EQ(db->numStored(), 8u) << "a dry run removes nothing";
  const auto removed = db->prune(now);
  ASSERT_EQ(dry.size(), removed.size());
  std::map<int64_t, std::string> why;
  for (const auto& c : removed) {
    EXPECT_EQ(c.op, ChangeOp::kRemoved);
    why[c.id] = c.reason;
  }
  EXPECT_EQ(why.size(), 4u);
  EXPECT_EQ(why[rare], "rarely recognized");
  EXPECT_EQ(why[poor], "poor accepted ratio");
  EXPECT_EQ(why[dup], "duplicate");
  EXPECT_EQ(why[dup_turned], "duplicate");
  for (int64_t kept : {good, young, neighbour, opposite}) {
    EXPECT_NE(db->info(kept), nullptr) << kept;
    EXPECT_EQ(why.count(kept), 0u) << kept << " " << why[kept];
  }
  // Revisions: one per removal, contiguous.
  for (size_t k = 1; k < removed.size(); ++k) {
    EXPECT_EQ(removed[k].revision, removed[k - 1].revision + 1);
  }
  EXPECT_EQ(db->store().integrityCheck(), "ok");
  // Removed for good: a reopened file does not have them.
  auto reopened = openDb(dir_ / "map.vslam-map", p);
  EXPECT_EQ(reopened->numStored(), 4u);
  EXPECT_EQ(reopened->info(rare), nullptr);
}

TEST(LandmarkDbSharedDescriptors, CountsRatioTestMatches) {
  const auto a = syntheticStructure(40, 5);
  const auto b = syntheticStructure(60, 6);
  EXPECT_NEAR(sharedDescriptorFraction(a, a, 0.8), 1.0, 1e-9);
  EXPECT_LT(sharedDescriptorFraction(a, b, 0.8), 0.1);
}

// A long synthetic run: the robot drives a 300 m loop-free path creating a
// landmark every 0.5 m, then drives back. The active set never exceeds the
// budget, holds what is near the robot, evicts what is far, and reloads it
// from the file when the robot returns.
TEST_F(LandmarkDbTest, MemoryStaysUnderTheBudgetAndFarRegionsReloadOnReturn) {
  DatabaseParams p;
  p.segmentation.region_size_m = 4.0;
  p.segmentation.active_radius_m = 10.0;
  p.segmentation.memory_budget_mb = 1.5;
  p.segmentation.reevaluate_distance_m = 1.0;
  auto db = openDb(dir_ / "map.vslam-map", p, false);
  const size_t budget = db->budgetBytes();
  const auto pathPose = [](double s) { return Pose2{s, 0.5 * std::sin(s / 7.0), 0}; };
  size_t max_active = 0, max_held = 0;
  int evicted = 0, loaded = 0;
  std::map<int64_t, double> along;
  int64_t pid = 0;
  for (double s = 0; s <= 300.0; s += 0.5) {
    const Pose2 robot = pathPose(s);
    db->setRobotPose(robot);
    for (const auto& c : db->updateActiveSet()) {
      evicted += c.op == ChangeOp::kEvicted;
      loaded += c.op == ChangeOp::kLoaded;
    }
    ++pid;
    const auto r = db->propose(syntheticInfo("forward", pid, kT0 + fromSeconds(s), robot),
                               syntheticStructure(150, static_cast<uint32_t>(pid)), Pose2{});
    ASSERT_EQ(r.outcome, ProposalOutcome::kCreated);
    for (const auto& c : r.changes) evicted += c.op == ChangeOp::kEvicted;
    along[r.id] = s;
    EXPECT_TRUE(db->isActive(r.id)) << "a new landmark is where the robot is";
    max_active = std::max(max_active, db->activeReplicaBytes());
    max_held = std::max(max_held, db->heldBytes());
    ASSERT_LE(db->activeReplicaBytes(), budget) << "at s = " << s;
  }
  EXPECT_EQ(db->numStored(), 601u);
  EXPECT_GT(evicted, 400);
  EXPECT_GT(max_active, budget / 2) << "the budget is used";
  // What the DB process itself holds: the structures of the active set plus
  // a small record per stored landmark.
  EXPECT_LT(max_held, budget + 601 * 256);
  // Far from the start: nothing near s = 0 is in memory.
  for (const auto& [id, s] : along) {
    if (s < 250) {
      EXPECT_FALSE(db->isActive(id)) << id;
    }
  }
  // Back to the start: those regions load again.
  for (double s = 300.0; s >= 0; s -= 0.5) {
    db->setRobotPose(pathPose(s));
    for (const auto& c : db->updateActiveSet()) loaded += c.op == ChangeOp::kLoaded;
    ASSERT_LE(db->activeReplicaBytes(), budget);
  }
  EXPECT_GT(loaded, 100);
  for (const auto& [id, s] : along) {
    if (s <= 4.0) {
      EXPECT_TRUE(db->isActive(id)) << id << " at s = " << s;
      ASSERT_NE(db->structure(id), nullptr);
      EXPECT_EQ(db->structure(id)->descriptors,
                syntheticStructure(150, static_cast<uint32_t>(id)).descriptors);
    }
    if (s > 20.0) {
      EXPECT_FALSE(db->isActive(id));
    }
  }
  RecordProperty("max_active_bytes", static_cast<int>(max_active));
  RecordProperty("max_held_bytes", static_cast<int>(max_held));
}

TEST_F(LandmarkDbTest, MapPosesFromTheBackendMoveLandmarksBetweenRegions) {
  DatabaseParams p;
  p.segmentation.region_size_m = 2.0;
  auto db = openDb(dir_ / "map.vslam-map", p);
  const auto r =
      db->propose(syntheticInfo("forward", 1, kT0, {0.5, 0.5, 0}), syntheticStructure(20, 1),
                  Pose2{10, 0, 0});  // map_T_odom: odometry frame shifted 10 m
  const LandmarkInfo* i = db->info(r.id);
  EXPECT_EQ(i->pose_source, PoseSource::kProvisional);
  EXPECT_NEAR(i->position().x, 10.5, 1e-9);
  EXPECT_EQ(db->regionOf(i->position()).ix, 5);
  EXPECT_EQ(db->setMapPoses({{r.id, {-3.0, 1.0, 0.2}}, {42, {0, 0, 0}}}), 1);
  EXPECT_EQ(i->pose_source, PoseSource::kMap);
  EXPECT_EQ(db->regionOf(i->position()).ix, -2);
  EXPECT_TRUE(db->flush().empty()) << "a position is stored, not published";
  auto reopened = openDb(dir_ / "map.vslam-map", p);
  EXPECT_EQ(reopened->info(r.id)->pose_source, PoseSource::kMap);
  EXPECT_NEAR(reopened->info(r.id)->map_pose.x, -3.0, 1e-12);
}

// A restarted back-end resumes where the robot was: the DB keeps the
// back-end's newest estimate in the map file, written with the statistics,
// and forgets it while the back-end believes the robot kidnapped.
TEST_F(LandmarkDbTest, KeepsTheRobotsLastPoseUntilTheRobotIsKidnapped) {
  const fs::path file = dir_ / "map.vslam-map";
  RobotPoseRecord estimate{kT0 + 5'000'000, {1.5, -2.0, 0.7}, {0.3, 0.1, -0.2}, {}};
  estimate.covariance = {0.01, 0.001, 0, 0.001, 0.02, 0, 0, 0, 0.003};
  {
    auto db = openDb(file);
    EXPECT_FALSE(db->store().robotPose()) << "a new map has no robot pose";
    db->noteRobotEstimate(estimate, false);
    EXPECT_FALSE(db->store().robotPose()) << "written with the statistics, not at once";
    db->flush();
  }
  {
    auto db = openDb(file);
    const auto& saved = db->store().robotPose();
    ASSERT_TRUE(saved);
    EXPECT_EQ(saved->utime, estimate.utime);
    EXPECT_EQ(saved->map_pose.x, 1.5);
    EXPECT_EQ(saved->map_pose.theta, 0.7);
    EXPECT_EQ(saved->odom_pose.y, 0.1);
    EXPECT_EQ(saved->covariance, estimate.covariance) << "written to full precision";
    estimate.utime += 1'000'000;
    db->noteRobotEstimate(estimate, true);  // the back-end lost the robot
    db->flush();
    EXPECT_FALSE(db->store().robotPose());
  }
  EXPECT_FALSE(openDb(file)->store().robotPose()) << "a kidnapped robot's pose is not resumed";

  // A damaged value is no robot pose, not a damaged map.
  {
    auto db = openDb(file);
    db->noteRobotEstimate(estimate, false);
    db->flush();
  }
  sqlite3* raw = nullptr;
  ASSERT_EQ(sqlite3_open(file.c_str(), &raw), SQLITE_OK);
  ASSERT_EQ(sqlite3_exec(raw, "UPDATE meta SET value = '12 1.0 nan' WHERE key = 'robot_pose'",
                         nullptr, nullptr, nullptr),
            SQLITE_OK);
  sqlite3_close(raw);
  auto db = openDb(file);
  EXPECT_FALSE(db->store().robotPose());
  EXPECT_EQ(db->numStored(), 0u);
}

// vslam-map's command line: option values after the option or as
// --key=value, the stack config from --config or $VSLAM_CONFIG.
TEST_F(LandmarkDbTest, MapToolReadsOptionsAndTheConfigFromTheEnvironment) {
  const fs::path file = dir_ / "map.vslam-map";
  { openDb(file)->propose(syntheticInfo("forward", 1, kT0, {}), syntheticStructure(20, 1)); }
  const std::string config = std::string(VSLAM_SOURCE_DIR) + "/config/vslam.yaml";
  ::unsetenv("VSLAM_CONFIG");
  EXPECT_EQ(runMapTool({"check", file.string(), "--config", config}), 0);
  EXPECT_EQ(runMapTool({"check", file.string(), "--config=" + config}), 0);
  EXPECT_EQ(runMapTool({"info", file.string(), "--config=" + config, "--instance=landmark_db"}), 0);
  EXPECT_EQ(runMapTool({"check", file.string(), "--config=/nonexistent/vslam.yaml"}), 2);
  ::setenv("VSLAM_CONFIG", "/nonexistent/vslam.yaml", 1);
  EXPECT_EQ(runMapTool({"check", file.string()}), 2);
  ::setenv("VSLAM_CONFIG", config.c_str(), 1);
  EXPECT_EQ(runMapTool({"check", file.string()}), 0);
  ::unsetenv("VSLAM_CONFIG");
  EXPECT_EQ(runMapTool({"bogus", file.string(), "--config=" + config}), 2);
  EXPECT_EQ(runMapTool({"plot", file.string(), "--config=" + config}), 2);  // needs --out
  EXPECT_EQ(runMapTool({"prune", file.string(), "--now-utime=soon", "--config=" + config}), 2);
}
