// vslam-sim's command line (common/sim/sim_cli.cpp): options in both spellings,
// bad options and bad values exit 2 naming the option, $VSLAM_CONFIG is read.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

#include "support/test_logs.hpp"

namespace fs = std::filesystem;
using vslam::test::runCommand;

namespace {

const fs::path kSource(VSLAM_SOURCE_DIR);
const std::string kSim = std::string(VSLAM_BIN_DIR) + "/vslam-sim";

class SimCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = vslam::test::scratchDir(::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(SimCliTest, KeyEqualsValueOptionsAreRead) {
  const fs::path log = dir_ / "run.lcmlog";
  std::string out;
  ASSERT_EQ(runCommand(
                kSim + " --config=" + (kSource / "config/vslam.yaml").string() +
                    " --scenario=living_room --duration=0.2 --start-time=100 --out=" + log.string(),
                &out),
            0)
      << out;
  int frames = 0;
  int64_t first = -1;
  for (const auto& e : vslam::test::readLog(log)) {
    if (first < 0) first = e.timestamp;
    frames += e.channel == "CAM_FORWARD_IMAGE";
  }
  EXPECT_EQ(frames, 3);         // t = 0, 0.1, 0.2: --duration=0.2, not the scenario's 300 s
  EXPECT_EQ(first, 100000000);  // --start-time=100
}

TEST_F(SimCliTest, UnknownOptionExits2NamingIt) {
  std::string out;
  EXPECT_EQ(runCommand(kSim + " --scenario living_room --colour red", &out), 2);
  EXPECT_NE(out.find("--colour"), std::string::npos) << out;
}

TEST_F(SimCliTest, BadNumberExits2NamingTheOptionAndValue) {
  std::string out;
  EXPECT_EQ(runCommand(kSim + " --scenario living_room --speed=-3", &out), 2);
  EXPECT_NE(out.find("--speed"), std::string::npos) << out;
  EXPECT_NE(out.find("-3"), std::string::npos) << out;
  EXPECT_EQ(runCommand(kSim + " --duration", &out), 2);  // no value
  EXPECT_NE(out.find("--duration"), std::string::npos) << out;
}

TEST_F(SimCliTest, HelpListsEveryOption) {
  std::string out;
  ASSERT_EQ(runCommand(kSim + " --help", &out), 0) << out;
  for (const char* option :
       {"--scenario", "--out", "--speed", "--duration", "--start-time", "--config", "--instance",
        "--lcm-url", "--wait-for", "--wait-timeout"}) {
    EXPECT_NE(out.find(option), std::string::npos) << option << " missing from\n" << out;
  }
}

TEST_F(SimCliTest, ReadsTheStackConfigFromVslamConfig) {
  const fs::path missing = dir_ / "no-such-config.yaml";
  std::string out;
  EXPECT_EQ(runCommand("VSLAM_CONFIG=" + missing.string() + " " + kSim +
                           " --scenario living_room --out " + (dir_ / "x.lcmlog").string(),
                       &out),
            2);
  EXPECT_NE(out.find(missing.string()), std::string::npos) << out;
}

}  // namespace
