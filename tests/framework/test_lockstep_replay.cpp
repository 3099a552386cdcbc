// Lock-step replay with small stages: ordering, determinism, and bad input.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <utility>
#include <vector>
#include <vslam/image_t.hpp>
#include <vslam/odometry_t.hpp>
#include <vslam/particle_set_t.hpp>
#include <vslam/pose_estimate_t.hpp>

#include "bus/latest_worker.hpp"
#include "bus/lockstep_replay.hpp"
#include "stages/deadreckon_stage.hpp"
#include "support/test_logs.hpp"

namespace fs = std::filesystem;
using namespace vslam;
using vslam::test::runCommand;
using namespace vslam::bus;
using vslam::test::readLog;
using vslam::test::RecordedEvent;

namespace {

// Downsamples each camera image 4x on a LatestWinsWorker and republishes it.
class ThumbnailStage final : public Stage {
 public:
  void start(StageContext& ctx) override {
    ctx_ = &ctx;
    worker_ = std::make_unique<LatestWinsWorker<vslam::image_t>>(
        ctx.mode, [this](vslam::image_t& img) { process(img); });
    ctx.bus.subscribe<vslam::image_t>(
        "CAM_FORWARD_IMAGE", [this](const vslam::image_t& img) { worker_->post(img); }, 2);
  }
  void drain() override { worker_->drain(); }
  void stop() override { worker_->stop(); }
  std::vector<std::string> outputChannels() const override { return {"CAM_FORWARD_THUMB"}; }

 private:
  void process(const vslam::image_t& img) {
    vslam::image_t out = img;
    out.width = img.width / 4;
    out.height = img.height / 4;
    out.row_stride = out.width;
    out.data.assign(static_cast<size_t>(out.width * out.height), 0);
    for (int y = 0; y < out.height; ++y) {
      for (int x = 0; x < out.width; ++x) {
        out.data[y * out.width + x] = img.data[(4 * y) * img.row_stride + 4 * x];
      }
    }
    out.data_size = static_cast<int32_t>(out.data.size());
    ctx_->bus.publish("CAM_FORWARD_THUMB", out);
  }
  StageContext* ctx_ = nullptr;
  std::unique_ptr<LatestWinsWorker<vslam::image_t>> worker_;
};

// Consumes another stage's output: every 25 poses, publishes the last 10 as a trail.
class PoseTrailStage final : public Stage {
 public:
  void start(StageContext& ctx) override {
    ctx_ = &ctx;
    ctx.bus.subscribe<vslam::pose_estimate_t>(
        "POSE_ODOMETRY", [this](const vslam::pose_estimate_t& p) { onPose(p); });
  }
  std::vector<std::string> outputChannels() const override { return {"TRAIL"}; }

 private:
  void onPose(const vslam::pose_estimate_t& p) {
    vslam::particle_t q{};
    q.x = p.x;
    q.y = p.y;
    q.theta = p.theta;
    q.weight = 0.1;
    trail_.push_back(q);
    if (trail_.size() > 10) trail_.erase(trail_.begin());
    if (++count_ % 25 != 0) return;
    vslam::particle_set_t out{};
    out.utime = p.utime;
    out.seq = count_ / 25;
    out.estimator = ctx_->instance;
    out.particles = trail_;
    out.num_particles = static_cast<int32_t>(trail_.size());
    ctx_->bus.publish("TRAIL", out);
  }
  StageContext* ctx_ = nullptr;
  std::vector<vslam::particle_t> trail_;
  int64_t count_ = 0;
};

std::unique_ptr<Stage> deadReckon() {
  stages::DeadReckonParams p;
  p.noise = {0.05, 0.05};
  p.odometry_channel = "ODOMETRY";
  p.pose_channel = "POSE_ODOMETRY";
  return std::make_unique<stages::DeadReckonStage>(p);
}

ReplayStats replayWithTestStages(const fs::path& in, const fs::path& out,
                                 bool keep_health = false) {
  ReplayOptions opt;
  opt.input = in;
  opt.output = out;
  opt.keep_health = keep_health;
  LockstepReplay replay(opt);
  replay.addStage("deadreckon", deadReckon());
  replay.addStage("thumbnail", std::make_unique<ThumbnailStage>());
  replay.addStage("trail", std::make_unique<PoseTrailStage>());
  return replay.run();
}

template <class Msg>
Msg decode(const RecordedEvent& e) {
  Msg m;
  EXPECT_EQ(m.decode(e.data.data(), 0, static_cast<int>(e.data.size())),
            static_cast<int>(e.data.size()));
  return m;
}

class LockstepReplayTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = vslam::test::scratchDir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    input_ = dir_ / "input.lcmlog";
    vslam::test::writeDrivingLog(input_, 10.0, 10.0);  // 501 odometry, 501 truth, 101 images
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_, input_;
};

}  // namespace

TEST_F(LockstepReplayTest, EveryStageFinishesEachEventBeforeTheNext) {
  const ReplayStats stats = replayWithTestStages(input_, dir_ / "out.lcmlog");
  EXPECT_FALSE(stats.input_truncated);
  EXPECT_EQ(stats.events_read, 501 + 501 + 101);
  EXPECT_EQ(stats.events_fed, stats.events_read);
  const auto out = readLog(dir_ / "out.lcmlog");

  int odometry = 0, poses = 0, thumbs = 0, trails = 0;
  for (size_t i = 0; i < out.size(); ++i) {
    const auto& e = out[i];
    if (e.channel == "HEALTH") ADD_FAILURE() << "health is not recorded by default";
    if (e.channel == "ODOMETRY") {
      const auto odo = decode<vslam::odometry_t>(e);
      ++odometry;
      // Its pose follows immediately, before the next input.
      ASSERT_LT(i + 1, out.size());
      ASSERT_EQ(out[i + 1].channel, "POSE_ODOMETRY") << "after odometry seq " << odo.seq;
      const auto pose = decode<vslam::pose_estimate_t>(out[i + 1]);
      EXPECT_EQ(pose.utime, odo.utime);
      EXPECT_NEAR(pose.x, odo.x, 1e-9);
      EXPECT_NEAR(pose.y, odo.y, 1e-9);
      EXPECT_EQ(out[i + 1].timestamp, e.timestamp);  // output stamped with the input's log time
    } else if (e.channel == "POSE_ODOMETRY") {
      ++poses;
      // The 25th, 50th, ... pose is followed by the second stage's trail.
      if (poses % 25 == 0) {
        ASSERT_EQ(out[i + 1].channel, "TRAIL");
        const auto trail = decode<vslam::particle_set_t>(out[i + 1]);
        EXPECT_EQ(trail.seq, poses / 25);
        EXPECT_EQ(trail.num_particles, 10);
        EXPECT_NEAR(trail.particles.back().x, decode<vslam::pose_estimate_t>(e).x, 1e-12);
      }
    } else if (e.channel == "CAM_FORWARD_IMAGE") {
      ASSERT_EQ(out[i + 1].channel, "CAM_FORWARD_THUMB");
      const auto img = decode<vslam::image_t>(e);
      const auto thumb = decode<vslam::image_t>(out[i + 1]);
      EXPECT_EQ(thumb.seq, img.seq);  // no frame dropped in lock-step
      EXPECT_EQ(thumb.width, 80);
      EXPECT_EQ(thumb.data[81], img.data[4 * 320 + 4]);
      ++thumbs;
    } else if (e.channel == "TRAIL") {
      ++trails;
    }
  }
  EXPECT_EQ(odometry, 501);
  EXPECT_EQ(poses, 501);
  EXPECT_EQ(thumbs, 101);
  EXPECT_EQ(trails, 20);
}

TEST_F(LockstepReplayTest, TwoRunsGiveByteIdenticalOutput) {
  replayWithTestStages(input_, dir_ / "a.lcmlog");
  replayWithTestStages(input_, dir_ / "b.lcmlog");
  const std::string a = vslam::test::readFileBytes(dir_ / "a.lcmlog");
  const std::string b = vslam::test::readFileBytes(dir_ / "b.lcmlog");
  ASSERT_GT(a.size(), 100000u);
  EXPECT_TRUE(a == b) << "replay output differs between two runs";
}

TEST_F(LockstepReplayTest, HealthIsRecordedOnlyWhenAsked) {
  replayWithTestStages(input_, dir_ / "h.lcmlog", /*keep_health=*/true);
  int health = 0;
  for (const auto& e : readLog(dir_ / "h.lcmlog")) health += e.channel == "HEALTH";
  // 3 stages x (10 s of log at 1 Hz + a last one on stop).
  EXPECT_GE(health, 3 * 10);
  EXPECT_LE(health, 3 * 12);
}

TEST_F(LockstepReplayTest, RecordedStageOutputsAreReplacedNotFed) {
  // A log that already holds POSE_ODOMETRY (from a live run): replay drops it
  // from the input, so the output holds only the newly computed poses.
  fs::path with_poses = dir_ / "with_poses.lcmlog";
  replayWithTestStages(input_, with_poses);
  const ReplayStats stats = replayWithTestStages(with_poses, dir_ / "again.lcmlog");
  EXPECT_GT(stats.events_dropped, 500);
  int poses = 0;
  for (const auto& e : readLog(dir_ / "again.lcmlog")) poses += e.channel == "POSE_ODOMETRY";
  EXPECT_EQ(poses, 501);
}

TEST_F(LockstepReplayTest, TruncatedLogIsReplayedUpToTheDamageAndReported) {
  const std::string bytes = vslam::test::readFileBytes(input_);
  const fs::path cut = dir_ / "cut.lcmlog";
  std::ofstream(cut, std::ios::binary)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size() / 2));
  const ReplayStats stats = replayWithTestStages(cut, dir_ / "out.lcmlog");
  EXPECT_TRUE(stats.input_truncated);
  EXPECT_GT(stats.input_bytes_unread, 0);
  EXPECT_GT(stats.events_read, 100);
  EXPECT_LT(stats.events_read, 1103);
  EXPECT_FALSE(readLog(dir_ / "out.lcmlog").empty());
}

TEST_F(LockstepReplayTest, DamagedEventInTheMiddleIsSkippedAndCounted) {
  std::string bytes = vslam::test::readFileBytes(input_);
  // Damage the header of an event in the middle: its sync word and lengths.
  // (LCM logs carry no checksum, so damage inside a payload is invisible here;
  // the message decoder catches what breaks a message's structure.)
  const std::string sync("\xED\xA1\xDA\x01", 4);
  const size_t at = bytes.find(sync, bytes.size() / 2);
  ASSERT_NE(at, std::string::npos);
  for (size_t i = at; i < at + 24; ++i) bytes[i] = '\x5a';
  const fs::path damaged = dir_ / "damaged.lcmlog";
  std::ofstream(damaged, std::ios::binary)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  const ReplayStats stats = replayWithTestStages(damaged, dir_ / "out.lcmlog");
  EXPECT_GE(stats.events_missing, 1);
  EXPECT_EQ(stats.events_read + stats.events_missing, 1103);  // everything else was replayed
  EXPECT_FALSE(stats.input_truncated);
}

TEST_F(LockstepReplayTest, ReplayProgramIsDeterministicAndReportsBadLogs) {
  const std::string bin = std::string(VSLAM_BIN_DIR) + "/vslam-replay";
  // The shipped config: a replay keeps its landmark map in memory.
  const std::string cfg = std::string(VSLAM_SOURCE_DIR) + "/config/vslam.yaml";
  std::string log1, log2;
  ASSERT_EQ(runCommand(bin + " " + input_.string() + " --config " + cfg + " --out " +
                           (dir_ / "r1.lcmlog").string(),
                       &log1),
            0)
      << log1;
  ASSERT_EQ(runCommand(bin + " " + input_.string() + " --config " + cfg + " --out " +
                           (dir_ / "r2.lcmlog").string(),
                       &log2),
            0)
      << log2;
  EXPECT_NE(log1.find("stage deadreckon"), std::string::npos) << log1;
  const std::string a = vslam::test::readFileBytes(dir_ / "r1.lcmlog");
  EXPECT_TRUE(a == vslam::test::readFileBytes(dir_ / "r2.lcmlog"));
  int poses = 0;
  for (const auto& e : readLog(dir_ / "r1.lcmlog")) poses += e.channel == "POSE_ODOMETRY";
  EXPECT_EQ(poses, 501);

  std::string err;
  EXPECT_EQ(runCommand(bin + " /nonexistent.lcmlog --config " + cfg + " --out " +
                           (dir_ / "x.lcmlog").string(),
                       &err),
            1);
  EXPECT_NE(err.find("cannot open input log /nonexistent.lcmlog"), std::string::npos) << err;

  const std::string bytes = vslam::test::readFileBytes(input_);
  std::ofstream(dir_ / "cut.lcmlog", std::ios::binary)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size() * 3 / 4));
  err.clear();
  EXPECT_EQ(runCommand(bin + " " + (dir_ / "cut.lcmlog").string() + " --config " + cfg + " --out " +
                           (dir_ / "cut_out.lcmlog").string(),
                       &err),
            1);
  EXPECT_NE(err.find("not a complete event"), std::string::npos) << err;
  EXPECT_FALSE(readLog(dir_ / "cut_out.lcmlog").empty());  // what was replayed is kept
}

// The two-camera config over a one-camera robot: the default replay leaves
// out the instances whose camera the robot file lacks, says so, and runs.
TEST_F(LockstepReplayTest, DefaultReplayLeavesOutStagesOfAnAbsentCamera) {
  std::string text = vslam::test::readFileBytes(fs::path(VSLAM_SOURCE_DIR) / "config/vslam.yaml");
  for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
           {"robot: robot/sim_two_camera.yaml",
            "robot: " + std::string(VSLAM_SOURCE_DIR) + "/config/robot/one_camera.yaml"}}) {
    const size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
  }
  const std::string cfg = (dir_ / "one_camera.yaml").string();
  std::ofstream(cfg) << text;
  std::string log;
  ASSERT_EQ(runCommand(std::string(VSLAM_BIN_DIR) + "/vslam-replay " + input_.string() +
                           " --config " + cfg + " --out " + (dir_ / "one.lcmlog").string(),
                       &log),
            0)
      << log;
  EXPECT_NE(log.find("frontend_backward left out: its camera 'backward'"), std::string::npos)
      << log;
  EXPECT_NE(log.find("stage frontend_forward"), std::string::npos) << log;
  EXPECT_NE(log.find("stage backend"), std::string::npos) << log;
  EXPECT_EQ(log.find("stage frontend_backward"), std::string::npos) << log;
}

// Replays are isolated: with the shipped config, whose landmark map lives in
// the user's data folder, two replays of one rendered log are byte-identical
// and nothing is written there. A map only carries over when named: the
// second replay on a --map file starts from the first one's landmarks.
TEST(ReplayIsolation, TwoReplaysOfALogAreIdenticalAndAMapCarriesOverOnlyWhenNamed) {
  const fs::path dir = vslam::test::scratchDir("replay_isolation");
  const std::string bin(VSLAM_BIN_DIR);
  const std::string cfg = std::string(VSLAM_SOURCE_DIR) + "/config/vslam.yaml";
  const fs::path data = dir / "data";  // $XDG_DATA_HOME: the live stack's map would go here
  const std::string env = "env XDG_DATA_HOME=" + data.string() + " ";
  std::string out;
  ASSERT_EQ(
      runCommand(env + bin + "/vslam-sim --config " + cfg +
                     " --scenario apartment --duration 15 --out " + (dir / "sim.lcmlog").string(),
                 &out),
      0)
      << out;
  const auto replay = [&](const std::string& name, const std::string& options) {
    std::string log;
    EXPECT_EQ(runCommand(env + bin + "/vslam-replay " + (dir / "sim.lcmlog").string() +
                             " --config " + cfg + " --out " + (dir / name).string() + " " + options,
                         &log),
              0)
        << log;
    return log;
  };
  const std::string first = replay("r1.lcmlog", "");
  EXPECT_NE(first.find("fresh, in memory"), std::string::npos) << first;
  replay("r2.lcmlog", "");
  const std::string a = vslam::test::readFileBytes(dir / "r1.lcmlog");
  EXPECT_TRUE(a == vslam::test::readFileBytes(dir / "r2.lcmlog")) << "two replays differ";
  int landmark_updates = 0;
  for (const auto& e : readLog(dir / "r1.lcmlog"))
    landmark_updates += e.channel == "LANDMARK_UPDATE";
  EXPECT_GT(landmark_updates, 0) << "no landmark in 15 s: the replays compared nothing";
  EXPECT_FALSE(fs::exists(data)) << "a replay wrote into the user's data folder";

  const fs::path map = dir / "named.vslam-map";
  replay("m1.lcmlog", "--map " + map.string());
  ASSERT_TRUE(fs::exists(map));
  const std::string again = replay("m2.lcmlog", "--map " + map.string());
  EXPECT_EQ(again.find(", 0 landmarks stored"), std::string::npos) << again;
  EXPECT_NE(again.find(" landmarks stored"), std::string::npos) << again;
  EXPECT_FALSE(fs::exists(data));
  fs::remove_all(dir);
}

// --print-config lists what the process read: its own block and the stack
// blocks it shares (the pre-filter for the back-end and the front-ends; not
// for a process that does not read it).
TEST(PrintConfig, ListsTheSharedBlocksAProcessReads) {
  const std::string cfg = std::string(VSLAM_SOURCE_DIR) + "/config/vslam.yaml";
  const auto printed = [&](const std::string& program, const std::string& instance) {
    std::string out;
    EXPECT_EQ(runCommand(std::string(VSLAM_BIN_DIR) + "/" + program + " --config " + cfg +
                             " --instance " + instance + " --print-config",
                         &out),
              0)
        << out;
    return out;
  };
  const std::string backend = printed("vslam-backend", "backend");
  EXPECT_NE(backend.find("processes.backend.num_particles"), std::string::npos) << backend;
  EXPECT_NE(backend.find("prefilter.min_num_points = 10"), std::string::npos) << backend;
  const std::string frontend = printed("vslam-frontend", "frontend_forward");
  EXPECT_NE(frontend.find("prefilter.max_slope = 0.1"), std::string::npos) << frontend;
  const std::string appearance = printed("vslam-appearance", "appearance");
  EXPECT_EQ(appearance.find("prefilter."), std::string::npos) << appearance;
}

// A process names itself as it is installed (roles are snake_case, programs
// kebab-case): `vslam-landmark-db --help`, not "vslam-landmark_db".
TEST(ProcessUsage, NamesTheProgramAsItIsInstalled) {
  for (const std::string program : {"vslam-landmark-db", "vslam-odometry-bridge"}) {
    std::string out;
    EXPECT_EQ(runCommand(std::string(VSLAM_BIN_DIR) + "/" + program + " --help", &out), 0) << out;
    EXPECT_NE(out.find(program), std::string::npos) << out;
    EXPECT_EQ(out.find("_db"), std::string::npos) << out;
    EXPECT_EQ(out.find("odometry_bridge"), std::string::npos) << out;
  }
}
