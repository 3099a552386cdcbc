// vslam-landmark-db as a process over UDP multicast, in a private network
// namespace: kill -9 while proposals stream in loses no acknowledged
// landmark, the file passes SQLite's integrity check, a restarted DB reloads
// it and answers proposals sent again with the same ids; a foreign map file
// stops the process with a clear error and is left untouched; the 39-byte
// request claiming 5e8 ids that once killed it with SIGSEGV is counted
// malformed and the next request is answered.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <csignal>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <vslam/health_t.hpp>
#include <vslam/landmark_request_t.hpp>
#include <vslam/landmark_summary_t.hpp>
#include <vslam/landmark_update_t.hpp>

#include "landmark_db/landmark_database.hpp"
#include "landmark_db_test_util.hpp"
#include "process_harness.hpp"
#include "stages/landmark_db_stage.hpp"

namespace fs = std::filesystem;
namespace tt = vslam::transport_test;
using namespace vslam;
using U = vslam::landmark_update_t;

namespace {

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";
constexpr Utime kT0 = 1767225600LL * kMicrosPerSecond;

class LandmarkDbLive : public tt::NetnsTest {};

void writeConfig(const fs::path& dir, const std::string& map_file) {
  std::ofstream(dir / "vslam.yaml")
      << "robot: " << VSLAM_SOURCE_DIR << "/config/robot/sim_two_camera.yaml\n"
      << "processes:\n"
      << "  landmark_db:\n"
      << "    role: landmark_db\n"
      << "    map_file: " << map_file << "\n"
      << "    allow_new_landmarks: true\n"
      << "    summary_period_s: 0.2\n"
      << "    flush_period_s: 0.2\n"
      << "    prune: {enabled: false, period_s: 30, min_age_s: 120, min_recognitions: 3,\n"
      << "            min_verdicts: 10, min_accepted_ratio: 0.3, duplicate_distance_m: 0.3,\n"
      << "            duplicate_angle_deg: 20, duplicate_min_shared: 0.3}\n"
      << "    segmentation: {region_size_m: 4, active_radius_m: 8, memory_budget_mb: 64,\n"
      << "                   reevaluate_distance_m: 1}\n";
}

tt::Child spawnDb(const fs::path& dir) {
  return tt::Child::spawn(
      {std::string(VSLAM_BIN_DIR) + "/vslam-landmark-db", "--config", (dir / "vslam.yaml").string(),
       "--instance", "landmark_db", "--lcm-url", kUrl},
      {}, (dir / "db.log").string());
}

U proposal(int64_t proposal_id) {
  const auto s = landmark_db::test::syntheticStructure(60, static_cast<uint32_t>(proposal_id));
  landmark_db::LandmarkInfo info;
  info.camera = proposal_id % 2 ? "forward" : "backward";
  info.proposal_id = proposal_id;
  info.created_utime = kT0 + proposal_id * 1000;
  info.created_odom = {0.1 * static_cast<double>(proposal_id), 0, 0};
  U m{};
  m.utime = info.created_utime;
  m.op = U::OP_PROPOSED;
  stages::LandmarkDbStage::fillLandmark(info, &s, &m.landmark);
  m.landmark.landmark_id = -1;
  m.landmark.version = 0;
  return m;
}

struct Listener {
  std::map<int64_t, int64_t> created;   // proposal_id -> global id (OP_CREATED)
  std::map<int64_t, int64_t> answered;  // proposal_id -> global id (OP_CREATED or OP_SNAPSHOT)
  std::set<std::string> snapshot_requesters;
  int summaries = 0;
  int32_t last_stored = -1;
  std::string database_id;
  void attach(tt::TestBus& bus) {
    bus.subscribe("LANDMARK_UPDATE", [this](const std::string&, const uint8_t* d, size_t n) {
      U u{};
      if (u.decode(d, 0, static_cast<int>(n)) != static_cast<int>(n)) return;
      if (u.op == U::OP_CREATED) created[u.landmark.proposal_id] = u.landmark.landmark_id;
      if (u.op == U::OP_CREATED || u.op == U::OP_SNAPSHOT) {
        answered[u.landmark.proposal_id] = u.landmark.landmark_id;
      }
      if (u.op == U::OP_SNAPSHOT) snapshot_requesters.insert(u.requester);
      database_id = u.database_id;
    });
    bus.subscribe("LANDMARK_SUMMARY", [this](const std::string&, const uint8_t* d, size_t n) {
      vslam::landmark_summary_t s{};
      if (s.decode(d, 0, static_cast<int>(n)) != static_cast<int>(n)) return;
      ++summaries;
      last_stored = s.num_stored;
    });
  }
};

}  // namespace

TEST_F(LandmarkDbLive, AcknowledgedLandmarksSurviveKillMinus9AndReloadOnRestart) {
  VSLAM_IN_FRESH_NETNS();
  tt::TempDir tmp;
  const fs::path dir(tmp.path());
  writeConfig(dir, "map.vslam-map");
  tt::TestBus bus(kUrl);
  ASSERT_TRUE(bus.good());
  Listener listener;
  listener.attach(bus);

  tt::Child db = spawnDb(dir);
  ASSERT_TRUE(bus.spinUntil([&] { return listener.summaries > 0; }, 20.0))
      << "no summary from vslam-landmark-db";
  // Stream proposals; kill -9 in the middle of the stream.
  int64_t sent = 0;
  while (listener.created.size() < 150 && sent < 2000) {
    bus.publish("LANDMARK_PROPOSAL", proposal(++sent));
    bus.spinFor(0.004);
  }
  bus.publish("LANDMARK_PROPOSAL", proposal(++sent));
  bus.publish("LANDMARK_PROPOSAL", proposal(++sent));
  db.sendSignal(SIGKILL);
  ASSERT_TRUE(db.waitFor(5.0).has_value());
  bus.spinFor(0.2);  // acknowledgements still in flight count too
  const std::map<int64_t, int64_t> acked = listener.created;
  ASSERT_GE(acked.size(), 100u);
  RecordProperty("sent", static_cast<int>(sent));
  RecordProperty("acknowledged", static_cast<int>(acked.size()));

  {
    landmark_db::StoreOptions so;
    so.create_if_missing = false;
    landmark_db::LandmarkDatabase reopened(
        std::make_unique<landmark_db::LandmarkStore>(dir / "map.vslam-map", so), {});
    EXPECT_EQ(reopened.store().integrityCheck(), "ok");
    EXPECT_EQ(reopened.databaseId(), listener.database_id);
    for (const auto& [pid, id] : acked) {
      const landmark_db::LandmarkInfo* info = reopened.info(id);
      ASSERT_NE(info, nullptr) << "acknowledged landmark " << id << " (proposal " << pid
                               << ") lost";
      EXPECT_EQ(info->proposal_id, pid);
      ASSERT_NE(reopened.structure(id), nullptr);
      EXPECT_EQ(reopened.structure(id)->descriptors,
                landmark_db::test::syntheticStructure(60, static_cast<uint32_t>(pid)).descriptors);
    }
    EXPECT_GE(reopened.numStored(), acked.size());
    EXPECT_LE(reopened.numStored(), static_cast<size_t>(sent));
  }

  // Restart: it reloads the file; proposals sent again get their ids back,
  // the unanswered ones new ids.
  listener.summaries = 0;
  listener.answered.clear();
  tt::Child again = spawnDb(dir);
  ASSERT_TRUE(bus.spinUntil([&] { return listener.summaries > 0; }, 20.0));
  EXPECT_GE(listener.last_stored, static_cast<int32_t>(acked.size()));
  for (int64_t pid = 1; pid <= sent; ++pid) {
    bus.publish("LANDMARK_PROPOSAL", proposal(pid));
    if (pid % 20 == 0) bus.spinFor(0.01);
  }
  ASSERT_TRUE(
      bus.spinUntil([&] { return listener.answered.size() == static_cast<size_t>(sent); }, 30.0))
      << listener.answered.size() << " of " << sent << " answered after the restart";
  for (const auto& [pid, id] : acked) EXPECT_EQ(listener.answered[pid], id) << pid;
  std::set<int64_t> ids;
  for (const auto& [pid, id] : listener.answered) ids.insert(id);
  EXPECT_EQ(ids.size(), static_cast<size_t>(sent)) << "one landmark per proposal";
  again.sendSignal(SIGTERM);
  const auto status = again.waitFor(10.0);
  ASSERT_TRUE(status.has_value());
  EXPECT_TRUE(tt::exitedWith(status, 0)) << tt::describeStatus(*status);
  // A clean stop folds the WAL back: the map is one file.
  EXPECT_FALSE(fs::exists(dir / "map.vslam-map-wal") &&
               fs::file_size(dir / "map.vslam-map-wal") > 0);
}

TEST_F(LandmarkDbLive, AForeignMapFileStopsItWithAClearErrorAndIsLeftUntouched) {
  VSLAM_IN_FRESH_NETNS();
  tt::TempDir tmp;
  const fs::path dir(tmp.path());
  writeConfig(dir, "thesis.sqlite");
  std::ofstream(dir / "thesis.sqlite") << "SQLite format 3 is what this pretends to be, but no\n";
  const std::string before = landmark_db::test::fileBytes(dir / "thesis.sqlite");
  tt::Child db = spawnDb(dir);
  const auto status = db.waitFor(10.0);
  ASSERT_TRUE(status.has_value()) << "it kept running on a foreign file";
  EXPECT_TRUE(tt::exitedWith(status, 1)) << tt::describeStatus(*status);
  const std::string log = landmark_db::test::fileBytes(dir / "db.log");
  EXPECT_NE(log.find("thesis.sqlite"), std::string::npos) << log;
  EXPECT_NE(log.find("left untouched"), std::string::npos) << log;
  EXPECT_EQ(landmark_db::test::fileBytes(dir / "thesis.sqlite"), before);
}

TEST_F(LandmarkDbLive, AHostileRequestIsCountedMalformedAndTheNextOneAnswered) {
  VSLAM_IN_FRESH_NETNS();
  tt::TempDir tmp;
  const fs::path dir(tmp.path());
  writeConfig(dir, "map.vslam-map");
  tt::TestBus bus(kUrl);
  ASSERT_TRUE(bus.good());
  Listener listener;
  listener.attach(bus);
  int64_t malformed = -1;
  bus.subscribe("HEALTH", [&](const std::string&, const uint8_t* d, size_t n) {
    vslam::health_t h{};
    if (h.decode(d, 0, static_cast<int>(n)) != static_cast<int>(n)) return;
    if (h.instance == "landmark_db") malformed = h.messages_malformed;
  });
  tt::Child db = spawnDb(dir);
  ASSERT_TRUE(bus.spinUntil([&] { return listener.summaries > 0; }, 20.0))
      << "no summary from vslam-landmark-db";
  bus.publish("LANDMARK_PROPOSAL", proposal(1));
  ASSERT_TRUE(bus.spinUntil([&] { return listener.created.count(1) > 0; }, 5.0));

  // Issue 19's message: a request with no ids, its count then set to 5e8.
  vslam::landmark_request_t request{};
  request.requester = "a";
  std::vector<uint8_t> hostile(static_cast<size_t>(request.getEncodedSize()));
  request.encode(hostile.data(), 0, static_cast<int>(hostile.size()));
  ASSERT_EQ(hostile.size(), 39u);
  const uint32_t claim = 500000000;
  for (int i = 0; i < 4; ++i) hostile[35 + i] = static_cast<uint8_t>(claim >> (24 - 8 * i));
  bus.publishRaw("LANDMARK_REQUEST", hostile);

  request.requester = "after_the_hostile_one";
  request.num_ids = 1;
  request.landmark_ids = {listener.created[1]};
  bus.publish("LANDMARK_REQUEST", request);
  EXPECT_TRUE(bus.spinUntil(
      [&] { return listener.snapshot_requesters.count(request.requester) > 0 || !db.running(); },
      5.0))
      << "the request after the hostile one was not answered";
  ASSERT_TRUE(db.running()) << "vslam-landmark-db " << tt::describeStatus(*db.status());
  EXPECT_TRUE(bus.spinUntil([&] { return malformed >= 1; }, 5.0))
      << "HEALTH does not count the hostile request (messages_malformed " << malformed << ")";
  EXPECT_EQ(malformed, 1);
  db.sendSignal(SIGTERM);
  const auto status = db.waitFor(10.0);
  ASSERT_TRUE(status.has_value());
  EXPECT_TRUE(tt::exitedWith(status, 0)) << tt::describeStatus(*status);
  const std::string log = landmark_db::test::fileBytes(dir / "db.log");
  EXPECT_NE(log.find("landmark_ids: 500000000 elements claimed"), std::string::npos) << log;
}
