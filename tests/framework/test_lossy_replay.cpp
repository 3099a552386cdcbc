// Lock-step replay with message loss: inputs and stage-to-stage messages lose,
// repeat and swap messages on their way to each stage, the recording keeps
// everything that was sent, a seed reproduces a run, no loss changes nothing,
// and vslam-replay's options refuse bad values.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <vslam/pose_estimate_t.hpp>

#include "bus/checked_decode.hpp"
#include "bus/lockstep_replay.hpp"
#include "stages/deadreckon_stage.hpp"
#include "support/test_logs.hpp"

namespace fs = std::filesystem;
using namespace vslam;
using namespace vslam::bus;
using vslam::test::readLog;

namespace {

// Counts the poses of another stage and publishes each count on COUNT, with
// the seq of the pose in x (a stage-to-stage message consumed by no one,
// recorded).
class PoseCounterStage final : public Stage {
 public:
  void start(StageContext& ctx) override {
    ctx_ = &ctx;
    ctx.bus.subscribe<vslam::pose_estimate_t>(
        "POSE_ODOMETRY", [this](const vslam::pose_estimate_t& p) { onPose(p); });
  }
  std::vector<std::string> outputChannels() const override { return {"COUNT"}; }

 private:
  void onPose(const vslam::pose_estimate_t& p) {
    vslam::pose_estimate_t out{};
    out.utime = p.utime;
    out.seq = ++count_;
    out.x = static_cast<double>(p.seq);  // which pose this count is for
    out.estimator = ctx_->instance;
    ctx_->bus.publish("COUNT", out);
  }
  StageContext* ctx_ = nullptr;
  int64_t count_ = 0;
};

std::unique_ptr<Stage> deadReckon() {
  stages::DeadReckonParams p;
  p.noise = {0.05, 0.05};
  p.odometry_channel = "ODOMETRY";
  p.pose_channel = "POSE_ODOMETRY";
  return std::make_unique<stages::DeadReckonStage>(p);
}

ReplayStats replay(const fs::path& in, const fs::path& out, const LossOptions& loss) {
  ReplayOptions opt;
  opt.input = in;
  opt.output = out;
  opt.loss = loss;
  LockstepReplay r(opt);
  r.addStage("deadreckon", deadReckon());
  r.addStage("counter", std::make_unique<PoseCounterStage>());
  return r.run();
}

int count(const fs::path& log, const std::string& channel) {
  int n = 0;
  for (const auto& e : readLog(log)) n += e.channel == channel;
  return n;
}

LossOptions loss(double drop, double duplicate, double reorder, const std::string& channels,
                 uint64_t seed = 1) {
  LossOptions o;
  o.drop = drop;
  o.duplicate = duplicate;
  o.reorder = reorder;
  o.channels = channels;
  o.seed = seed;
  return o;
}

class LossyReplayTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = vslam::test::scratchDir(::testing::UnitTest::GetInstance()->current_test_info()->name());
    input_ = dir_ / "input.lcmlog";
    vslam::test::writeDrivingLog(input_, 10.0, 0.0);  // 501 odometry, 501 truth
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_, input_;
};

}  // namespace

TEST_F(LossyReplayTest, NoLossIsTheReplayWithoutTheOption) {
  replay(input_, dir_ / "plain.lcmlog", LossOptions{});
  LossOptions zero = loss(0, 0, 0, "ODOMETRY", 99);  // inactive: not installed
  const ReplayStats s = replay(input_, dir_ / "zero.lcmlog", zero);
  EXPECT_EQ(s.loss.offered, 0);
  EXPECT_TRUE(vslam::test::readFileBytes(dir_ / "plain.lcmlog") ==
              vslam::test::readFileBytes(dir_ / "zero.lcmlog"));
}

TEST_F(LossyReplayTest, DroppedInputsAreNotHandledButStillRecorded) {
  const ReplayStats s = replay(input_, dir_ / "out.lcmlog", loss(0.3, 0, 0, "ODOMETRY"));
  EXPECT_EQ(s.loss.offered, 501);  // one receiver of ODOMETRY
  EXPECT_GT(s.loss.dropped, 100);
  EXPECT_LT(s.loss.dropped, 200);
  ASSERT_EQ(s.loss_per_channel.size(), 1u);
  EXPECT_EQ(s.loss_per_channel.at("ODOMETRY").dropped, s.loss.dropped);
  const fs::path out = dir_ / "out.lcmlog";
  EXPECT_EQ(count(out, "ODOMETRY"), 501);  // the recording sees what was sent
  EXPECT_EQ(count(out, "POSE_ODOMETRY"), 501 - s.loss.dropped);
  EXPECT_EQ(count(out, "COUNT"), 501 - s.loss.dropped);  // POSE_ODOMETRY is not lossy here
}

TEST_F(LossyReplayTest, StageToStageMessagesAreLostToo) {
  const ReplayStats s = replay(input_, dir_ / "out.lcmlog", loss(0.5, 0.2, 0, "POSE_ODOMETRY"));
  const fs::path out = dir_ / "out.lcmlog";
  EXPECT_EQ(count(out, "POSE_ODOMETRY"), 501);  // published by deadreckon, all recorded
  EXPECT_EQ(s.loss.offered, 501);
  EXPECT_GT(s.loss.dropped, 180);
  EXPECT_GT(s.loss.duplicated, 20);
  EXPECT_EQ(count(out, "COUNT"), 501 - s.loss.dropped + s.loss.duplicated);
}

TEST_F(LossyReplayTest, ReorderedMessagesArriveSwappedAndTheLastHeldOneAtTheEnd) {
  // Every message that can be held is: each pair arrives swapped, and the
  // last one, held when the log ends, is delivered then: none is lost.
  const ReplayStats s = replay(input_, dir_ / "out.lcmlog", loss(0, 0, 1.0, "POSE_ODOMETRY"));
  EXPECT_EQ(s.loss.reordered, 251);  // 501 poses: 250 swapped pairs and the last one
  std::vector<int> received;         // the pose seqs, in the order the counter got them
  for (const auto& e : readLog(dir_ / "out.lcmlog")) {
    if (e.channel != "COUNT") continue;
    vslam::pose_estimate_t m;
    std::string why;
    ASSERT_TRUE(checkedDecode(m, e.data.data(), e.data.size(), &why)) << why;
    received.push_back(static_cast<int>(m.x));
  }
  ASSERT_EQ(received.size(), 501u);
  for (int i = 0; i + 1 < 501; i += 2) {
    ASSERT_EQ(received[i], i + 1) << "at " << i;
    ASSERT_EQ(received[i + 1], i) << "at " << i;
  }
  EXPECT_EQ(received.back(), 500);
}

TEST_F(LossyReplayTest, ALateOdometryReadingIsIgnoredNotIntegrated) {
  // Dead reckoning drops a reading older than the last one (stale), so with
  // every pair of ODOMETRY swapped only the newer half makes poses.
  replay(input_, dir_ / "out.lcmlog", loss(0, 0, 1.0, "ODOMETRY"));
  EXPECT_EQ(count(dir_ / "out.lcmlog", "POSE_ODOMETRY"), 251);
}

TEST_F(LossyReplayTest, TheSeedReproducesTheRun) {
  const LossOptions o = loss(0.3, 0.1, 0.1, ".*", 5);
  const ReplayStats a = replay(input_, dir_ / "a.lcmlog", o);
  const ReplayStats b = replay(input_, dir_ / "b.lcmlog", o);
  EXPECT_EQ(a.loss.dropped, b.loss.dropped);
  EXPECT_TRUE(vslam::test::readFileBytes(dir_ / "a.lcmlog") ==
              vslam::test::readFileBytes(dir_ / "b.lcmlog"));
  LossOptions other = o;
  other.seed = 6;
  replay(input_, dir_ / "c.lcmlog", other);
  EXPECT_FALSE(vslam::test::readFileBytes(dir_ / "a.lcmlog") ==
               vslam::test::readFileBytes(dir_ / "c.lcmlog"));
}

TEST_F(LossyReplayTest, ReplayProgramRefusesBadLossOptionsAndReportsTheLosses) {
  const std::string bin = std::string(VSLAM_BIN_DIR) + "/vslam-replay";
  // The shipped config: a replay keeps its landmark map in memory.
  const std::string cfg = std::string(VSLAM_SOURCE_DIR) + "/config/vslam.yaml";
  const std::string run = bin + " " + input_.string() + " --config " + cfg +
                          " --stages deadreckon --out " + (dir_ / "r.lcmlog").string() + " ";
  std::string log;
  EXPECT_EQ(vslam::test::runCommand(run + "--drop 1.5", &log), 2);
  EXPECT_NE(log.find("drop probability 1.5 is not in [0, 1]"), std::string::npos) << log;
  log.clear();
  EXPECT_EQ(vslam::test::runCommand(run + "--reorder nan", &log), 2);
  EXPECT_NE(log.find("reorder probability nan is not in [0, 1]"), std::string::npos) << log;
  log.clear();
  EXPECT_EQ(vslam::test::runCommand(run + "--drop 0.1 --loss-channels 'ODO('", &log), 2);
  EXPECT_NE(log.find("channel pattern 'ODO(' is not a regular expression"), std::string::npos)
      << log;
  log.clear();
  ASSERT_EQ(
      vslam::test::runCommand(run + "--drop 0.2 --loss-seed 3 --loss-channels ODOMETRY", &log), 0)
      << log;
  EXPECT_NE(log.find("message loss, all channels: dropped "), std::string::npos) << log;
  EXPECT_NE(log.find("message loss on ODOMETRY: dropped "), std::string::npos) << log;
  EXPECT_LT(count(dir_ / "r.lcmlog", "POSE_ODOMETRY"), 501);
}
