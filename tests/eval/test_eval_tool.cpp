// vslam-eval end to end: trajectories from LCM logs (defaults, explicit
// channels, raw odometry), TUM files, the printed table and the JSON, TUM
// copies, plots, and every kind of bad input with its exit code.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sstream>
#include <vector>
#include <vslam/appearance_hypotheses_t.hpp>
#include <vslam/appearance_map_t.hpp>
#include <vslam/camera_calibration_t.hpp>
#include <vslam/ground_truth_pose_t.hpp>
#include <vslam/map_t.hpp>
#include <vslam/odometry_t.hpp>
#include <vslam/pose_estimate_t.hpp>

#include "eval/appearance_eval.hpp"
#include "eval/eval_cli.hpp"
#include "eval/tum_file.hpp"
#include "eval_test_util.hpp"

namespace fs = std::filesystem;
using vslam::test::contains;
using vslam::test::runProgram;

namespace {

constexpr int64_t kT0 = 1700000000000000;  // utime of the first message

struct DriveLog {
  bool pose_estimate = false;     // POSE_ESTIMATE: ground truth + (0, 0.05)
  bool pose_odometry = true;      // POSE_ODOMETRY: ground truth + (0.1, 0)
  bool odometry = true;           // ODOMETRY: ground truth exactly
  bool map = false;               // MAP with 5 landmarks
  int64_t odometry_delay_us = 0;  // POSE_ODOMETRY stamps later than ground truth
  int seconds = 10;
};

// A robot driving a circle of radius 1.5 m at 0.3 m/s; messages at 50 Hz.
void writeDriveLog(const fs::path& file, const DriveLog& d) {
  vslam::bus::LogWriter log(file);
  const double v = 0.3, r = 1.5;
  for (int i = 0; i <= d.seconds * 50; ++i) {
    const int64_t t = kT0 + i * 20000;
    const double s = i * 0.02, th = v / r * s;
    const double x = r * std::sin(th), y = r * (1 - std::cos(th)),
                 heading = std::remainder(th, 2 * M_PI);
    vslam::ground_truth_pose_t gt{};
    gt.utime = t;
    gt.seq = i;
    gt.x = x;
    gt.y = y;
    gt.theta = heading;
    log.writeMessage(t + 100, "GROUND_TRUTH", gt);
    if (d.odometry) {
      vslam::odometry_t o{};
      o.utime = t;
      o.seq = i;
      o.x = x;
      o.y = y;
      o.theta = heading;
      o.distance = v * s;
      log.writeMessage(t + 50, "ODOMETRY", o);
    }
    auto estimate = [&](double dx, double dy, int64_t delay) {
      vslam::pose_estimate_t e{};
      e.utime = t + delay;
      e.seq = i;
      e.estimator = "test";
      e.x = x + dx;
      e.y = y + dy;
      e.theta = heading;
      return e;
    };
    if (d.pose_odometry) {
      log.writeMessage(t + 200, "POSE_ODOMETRY", estimate(0.1, 0.0, d.odometry_delay_us));
    }
    if (d.pose_estimate) log.writeMessage(t + 300, "POSE_ESTIMATE", estimate(0.0, 0.05, 0));
    if (d.map && i % 50 == 0) {
      vslam::map_t m{};
      m.utime = t;
      m.seq = i / 50;
      m.estimator = "test";
      m.database_id = "db";
      for (int k = 0; k < 5; ++k) {
        vslam::landmark_pose_t l{};
        l.landmark_id = k;
        l.x = 2.0 * std::cos(k);
        l.y = 1.5 + 2.0 * std::sin(k);
        m.landmarks.push_back(l);
      }
      m.num_landmarks = static_cast<int32_t>(m.landmarks.size());
      log.writeMessage(t + 400, "MAP", m);
    }
  }
}

struct CliResult {
  int code;
  std::string out, err;
};

CliResult runCli(const std::vector<std::string>& args) {
  std::ostringstream out, err;
  const int code = vslam::eval::runEvalCli(args, out, err);
  return {code, out.str(), err.str()};
}

// Parsing throws on any syntax error: this also checks that the JSON is valid.
nlohmann::json readJson(const fs::path& file) {
  return nlohmann::json::parse(vslam::test::fileBytes(file));
}

// The keys of an object in the order the file has them.
std::vector<std::string> keysInOrder(const nlohmann::ordered_json& object) {
  std::vector<std::string> keys;
  for (const auto& item : object.items()) keys.push_back(item.key());
  return keys;
}

// The value of a table row for the (first) estimate column.
std::string tableValue(const std::string& table, const std::string& row) {
  std::istringstream in(table);
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(row, 0) == 0) {
      std::istringstream fields(line.substr(row.size()));
      std::string v;
      fields >> v;
      return v;
    }
  }
  return "<no row " + row + ">";
}

class EvalTool : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = vslam::test::freshDir(std::string("eval_tool_") +
                                 ::testing::UnitTest::GetInstance()->current_test_info()->name());
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

void writeText(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

}  // namespace

TEST_F(EvalTool, LogOdometryOnlyPathWithDefaults) {
  const fs::path log = dir_ / "run.lcmlog", json = dir_ / "out.json";
  writeDriveLog(log, {});
  const auto r = runCli({log.string(), "--align", "none", "--json", json.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  // Defaults: POSE_ODOMETRY is present, so raw ODOMETRY is not evaluated.
  const nlohmann::json j = readJson(json);
  ASSERT_EQ(j.at("estimates").size(), 1u);
  const nlohmann::json& e = j.at("estimates").at(0);
  EXPECT_EQ(e.at("name").get<std::string>(), "POSE_ODOMETRY");
  EXPECT_EQ(e.at("kind").get<std::string>(), "odometry");
  EXPECT_EQ(e.at("source").get<std::string>(), "vslam.pose_estimate_t");
  EXPECT_EQ(j.at("reference").at("name").get<std::string>(), "GROUND_TRUTH");
  EXPECT_EQ(j.at("reference").at("poses").get<int>(), 501);
  EXPECT_EQ(e.at("ate").at("pairs").get<int>(), 501);
  EXPECT_NEAR(e.at("ate").at("translation_m").at("rmse").get<double>(), 0.1, 1e-9);
  EXPECT_NEAR(e.at("ate").at("translation_m").at("median").get<double>(), 0.1, 1e-9);
  EXPECT_NEAR(e.at("ate").at("translation_m").at("std").get<double>(), 0.0, 1e-9);
  // A constant offset does not change relative motion: RPE 0. 1 s pairs at
  // 50 Hz over 10 s: i = 0..449.
  EXPECT_EQ(e.at("rpe").at("pairs").get<int>(), 450);
  EXPECT_LT(e.at("rpe").at("translation_m").at("max").get<double>(), 1e-6);
  EXPECT_EQ(j.at("parameters").at("align").get<std::string>(), "none");
  EXPECT_NEAR(j.at("parameters").at("max_diff_s").get<double>(), 0.02, 1e-12);
  // The table says the same.
  EXPECT_TRUE(contains(r.out, "POSE_ODOMETRY")) << r.out;
  EXPECT_EQ(tableValue(r.out, "ATE rmse [m]"), "0.100000") << r.out;
  EXPECT_EQ(tableValue(r.out, "ATE pairs"), "501") << r.out;
  EXPECT_EQ(tableValue(r.out, "RPE pairs"), "450") << r.out;

  // With se2 alignment the offset is removed.
  const auto aligned = runCli({log.string(), "--align", "se2", "--json", json.string()});
  ASSERT_EQ(aligned.code, 0) << aligned.err;
  EXPECT_LT(
      readJson(json).at("estimates").at(0).at("ate").at("translation_m").at("max").get<double>(),
      1e-6);
}

TEST_F(EvalTool, LogRawOdometryWhenNoPoseOdometry) {
  const fs::path log = dir_ / "run.lcmlog", json = dir_ / "out.json";
  writeDriveLog(log, {false, false, true});
  const auto r = runCli({log.string(), "--align", "none", "--json", json.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json j = readJson(json);
  ASSERT_EQ(j.at("estimates").size(), 1u);
  EXPECT_EQ(j.at("estimates").at(0).at("name").get<std::string>(), "ODOMETRY");
  EXPECT_EQ(j.at("estimates").at(0).at("source").get<std::string>(), "vslam.odometry_t");
  EXPECT_LT(j.at("estimates").at(0).at("ate").at("translation_m").at("max").get<double>(), 1e-9);
}

TEST_F(EvalTool, LogExplicitChannelsInOrder) {
  const fs::path log = dir_ / "run.lcmlog", json = dir_ / "out.json";
  writeDriveLog(log, {true, true, true});
  auto r = runCli({log.string(), "--est-channel", "POSE_ESTIMATE", "--odom-channel", "ODOMETRY",
                   "--align", "none", "--json", json.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  const nlohmann::json j = readJson(json);
  ASSERT_EQ(j.at("estimates").size(), 2u);
  EXPECT_EQ(j.at("estimates").at(0).at("name").get<std::string>(), "POSE_ESTIMATE");
  EXPECT_EQ(j.at("estimates").at(0).at("kind").get<std::string>(), "estimate");
  EXPECT_NEAR(j.at("estimates").at(0).at("ate").at("translation_m").at("rmse").get<double>(), 0.05,
              1e-9);
  EXPECT_EQ(j.at("estimates").at(1).at("name").get<std::string>(), "ODOMETRY");
  EXPECT_EQ(j.at("estimates").at(1).at("kind").get<std::string>(), "odometry");
  // Defaults with everything present: POSE_ESTIMATE and POSE_ODOMETRY.
  r = runCli({log.string(), "--json", json.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  ASSERT_EQ(readJson(json).at("estimates").size(), 2u);
  EXPECT_EQ(readJson(json).at("estimates").at(1).at("name").get<std::string>(), "POSE_ODOMETRY");
  EXPECT_EQ(readJson(json).at("parameters").at("align").get<std::string>(), "se3");  // the default
  // An explicit channel that is not there is an error naming it.
  r = runCli({log.string(), "--est-channel", "POSE_BACKEND"});
  EXPECT_EQ(r.code, 1);
  EXPECT_TRUE(contains(r.err, "no messages on channel POSE_BACKEND")) << r.err;
  EXPECT_TRUE(contains(r.err, "POSE_ODOMETRY (501)")) << r.err;  // lists what is there
}

TEST_F(EvalTool, MaxDiffAndOffsetControlAssociation) {
  // POSE_ODOMETRY stamped 7 ms late; ground truth every 20 ms, so each
  // estimate is 7 ms from its own reference pose and 13 ms from the next.
  const fs::path log = dir_ / "run.lcmlog", json = dir_ / "out.json";
  DriveLog d;
  d.odometry_delay_us = 7000;
  writeDriveLog(log, d);
  auto r = runCli({log.string(), "--align", "none", "--json", json.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(readJson(json).at("estimates").at(0).at("ate").at("pairs").get<int>(), 501);
  EXPECT_NEAR(
      readJson(json).at("estimates").at(0).at("ate").at("translation_m").at("rmse").get<double>(),
      0.1, 1e-9);
  r = runCli({log.string(), "--max-diff", "0.005"});
  EXPECT_EQ(r.code, 1);
  EXPECT_TRUE(contains(r.err, "no associated poses")) << r.err;
  EXPECT_TRUE(contains(r.err, "POSE_ODOMETRY")) << r.err;
  r = runCli({log.string(), "--max-diff", "0.005", "--offset", "-0.007", "--align", "none",
              "--json", json.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(readJson(json).at("estimates").at(0).at("ate").at("pairs").get<int>(), 501);
  EXPECT_NEAR(
      readJson(json).at("estimates").at(0).at("ate").at("translation_m").at("rmse").get<double>(),
      0.1, 1e-9);
  // 15 ms late: the nearest reference pose is the next one (5 ms), so every
  // estimate pairs with the pose 20 ms after its own and the last has none.
  d.odometry_delay_us = 15000;
  writeDriveLog(log, d);
  r = runCli({log.string(), "--align", "none", "--json", json.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(readJson(json).at("estimates").at(0).at("ate").at("pairs").get<int>(), 500);
}

TEST_F(EvalTool, PlotsAreWrittenWithTheRightSizeAndColours) {
  const fs::path log = dir_ / "run.lcmlog", plots = dir_ / "plots" / "sub";
  writeDriveLog(log, {true, true, false, true});
  const auto r = runCli({log.string(), "--plot-dir", plots.string(), "--plot-size", "640x480"});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.out, "map: 5 landmarks")) << r.out;
  auto countColour = [](const cv::Mat& img, const cv::Vec3b& lo, const cv::Vec3b& hi) {
    cv::Mat mask;
    cv::inRange(img, lo, hi, mask);
    return cv::countNonZero(mask);
  };
  for (const char* name : {"trajectory.png", "error.png"}) {
    const fs::path p = plots / name;
    ASSERT_TRUE(fs::exists(p)) << p;
    EXPECT_GT(fs::file_size(p), 1000u);
    const cv::Mat img = cv::imread(p.string(), cv::IMREAD_COLOR);
    ASSERT_FALSE(img.empty()) << p;
    EXPECT_EQ(img.cols, 640);
    EXPECT_EQ(img.rows, 480);
    // Red estimate and green odometry are drawn.
    EXPECT_GT(countColour(img, {0, 0, 180}, {60, 60, 255}), 50) << name;
    EXPECT_GT(countColour(img, {0, 130, 0}, {60, 210, 60}), 50) << name;
  }
  const cv::Mat traj = cv::imread((plots / "trajectory.png").string(), cv::IMREAD_COLOR);
  EXPECT_GT(countColour(traj, {180, 0, 0}, {255, 100, 60}), 30);  // blue landmarks
  EXPECT_GT(countColour(traj, {0, 0, 0}, {40, 40, 40}), 200);     // black reference, text
  // Too small a plot is a usage error.
  EXPECT_EQ(runCli({log.string(), "--plot-dir", plots.string(), "--plot-size", "100x80"}).code, 2);
}

TEST_F(EvalTool, WritesEstimatesAndReferenceAsTum) {
  // Into folders that do not exist yet: they are made.
  const fs::path log = dir_ / "run.lcmlog", tum = dir_ / "new" / "est.txt",
                 ref = dir_ / "other" / "gt.txt";
  writeDriveLog(log, {});
  auto r = runCli({log.string(), "--write-tum", tum.string(), "--write-tum-ref", ref.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  const auto est = vslam::eval::readTumFile(tum);
  ASSERT_EQ(est.size(), 501u);
  EXPECT_NEAR(est.poses[0].t, kT0 * 1e-6, 1e-6);
  EXPECT_NEAR(est.poses[0].position.x(), 0.1, 1e-9);
  EXPECT_EQ(vslam::eval::readTumFile(ref).size(), 501u);
  // Several estimates: one file each, named after the channel.
  writeDriveLog(log, {true, true, true});
  r = runCli({log.string(), "--write-tum", tum.string()});
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(vslam::eval::readTumFile(dir_ / "new" / "est.POSE_ESTIMATE.txt").size(), 501u);
  EXPECT_EQ(vslam::eval::readTumFile(dir_ / "new" / "est.POSE_ODOMETRY.txt").size(), 501u);
}

TEST_F(EvalTool, TumFilesThroughTheProgram) {
  // Reference: 1 m square path; estimate rotated 90 degrees and shifted.
  std::ostringstream ref, est;
  for (int i = 0; i < 40; ++i) {
    const int edge = i / 10;
    const double s = (i % 10) * 0.1;
    const double x = edge == 0 ? s : edge == 1 ? 1 : edge == 2 ? 1 - s : 0;
    const double y = edge == 0 ? 0 : edge == 1 ? s : edge == 2 ? 1 : 1 - s;
    ref << 10 + 0.1 * i << " " << x << " " << y << " 0 0 0 0 1\n";
    est << 10 + 0.1 * i + 0.005 << " " << 5 - y << " " << x << " 0 0 0 0.7071067811865476 "
        << "0.7071067811865476\n";
  }
  writeText(dir_ / "ref.txt", "# timestamp tx ty tz qx qy qz qw\n" + ref.str());
  writeText(dir_ / "est.txt", est.str());
  const fs::path json = dir_ / "o.json";
  auto r = runProgram("vslam-eval",
                      {"--trajectory", "--ref", (dir_ / "ref.txt").string(), "--est",
                       (dir_ / "est.txt").string(), "--align", "se2", "--json", json.string()});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "ATE rmse [m]")) << r.output;
  const nlohmann::json j = readJson(json);
  EXPECT_EQ(j.at("estimates").at(0).at("ate").at("pairs").get<int>(), 40);
  EXPECT_LT(j.at("estimates").at(0).at("ate").at("translation_m").at("max").get<double>(), 1e-6);
  EXPECT_NEAR(j.at("estimates").at(0).at("alignment").at("yaw_deg").get<double>(), -90.0, 1e-6);
  r = runProgram("vslam-eval",
                 {"--ref", (dir_ / "ref.txt").string(), "--est", (dir_ / "est.txt").string(),
                  "--align", "none", "--json", json.string()});
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_GT(
      readJson(json).at("estimates").at(0).at("ate").at("translation_m").at("min").get<double>(),
      2.9);
}

TEST_F(EvalTool, OptionValuesMayFollowAnEqualsSign) {
  const fs::path log = dir_ / "run.lcmlog";
  writeDriveLog(log, {});
  const fs::path spaced = dir_ / "spaced.json", joined = dir_ / "joined.json";
  ASSERT_EQ(
      runCli({log.string(), "--align", "none", "--delta", "2", "--json", spaced.string()}).code, 0);
  ASSERT_EQ(runCli({log.string(), "--align=none", "--delta=2", "--json=" + joined.string()}).code,
            0);
  EXPECT_EQ(vslam::test::fileBytes(spaced), vslam::test::fileBytes(joined));
  // The value is checked as when it follows the option.
  const auto bad = runCli({log.string(), "--max-diff=0"});
  EXPECT_EQ(bad.code, 2);
  EXPECT_TRUE(contains(bad.err, "--max-diff")) << bad.err;
  EXPECT_EQ(runCli({"--appearance", log.string(), "--action-length=-1"}).code, 2);
  EXPECT_EQ(runCli({"--measurements", log.string(), "--max-gap=x"}).code, 2);
}

TEST_F(EvalTool, UsageErrorsExitWithCode2) {
  const fs::path log = dir_ / "run.lcmlog";
  writeDriveLog(log, {});
  const std::vector<std::vector<std::string>> cases = {
      {},
      {log.string(), "--bogus"},
      {log.string(), "--align", "se4"},
      {log.string(), "--delta-unit", "rad"},
      {log.string(), "--max-diff", "0"},
      {log.string(), "--max-diff", "abc"},
      {log.string(), "--delta"},
      {log.string(), log.string()},
      {log.string(), "--ref", "a.txt", "--est", "b.txt"},
      {"--ref", "a.txt"},
      {"--est", "b.txt"},
      {"--ref", "a.txt", "--est", "b.txt", "--ref-channel", "GT"},
  };
  for (const auto& args : cases) {
    const auto r = runProgram("vslam-eval", args);
    std::string joined;
    for (const auto& a : args) joined += a + " ";
    EXPECT_EQ(r.exit_code, 2) << joined << "\n" << r.output;
    EXPECT_TRUE(contains(r.output, "vslam-eval: ")) << r.output;
  }
  const auto help = runProgram("vslam-eval", {"--help"});
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_TRUE(contains(help.output, "--trajectory")) << help.output;
}

TEST_F(EvalTool, DataErrorsExitWithCode1AndSayWhatIsWrong) {
  const fs::path good = dir_ / "good.lcmlog";
  writeDriveLog(good, {});
  const std::string bytes = vslam::test::fileBytes(good);

  // A log cut in the middle of its last event.
  const fs::path cut = dir_ / "cut.lcmlog";
  writeText(cut, bytes.substr(0, bytes.size() - 10));
  // Garbage between two events.
  const fs::path first = dir_ / "first.lcmlog", garbage = dir_ / "garbage.lcmlog";
  DriveLog short_log;
  short_log.seconds = 1;
  writeDriveLog(first, short_log);
  writeText(garbage, vslam::test::fileBytes(first) + "JUNKJUNK" + bytes);
  // Not a log at all.
  const fs::path text = dir_ / "text.lcmlog";
  writeText(text, "this is not an LCM log\n");
  // A log without estimates, one without the reference.
  const fs::path no_est = dir_ / "noest.lcmlog";
  writeDriveLog(no_est, {false, false, false});
  // TUM files: malformed, empty.
  writeText(dir_ / "ref.txt", "1 0 0 0 0 0 0 1\n2 1 0 0 0 0 0 1\n3 2 0 0 0 0 0 1\n");
  writeText(dir_ / "bad.txt", "# estimate\n1 0 0 0 0 0 0 1\n2 1 0 0 0 0 1\n");
  writeText(dir_ / "empty.txt", "# nothing\n");
  writeText(dir_ / "late.txt", "101 0 0 0 0 0 0 1\n102 1 0 0 0 0 0 1\n103 2 0 0 0 0 0 1\n");

  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{(dir_ / "missing.lcmlog").string()}, "missing.lcmlog: no such file"},
      {{garbage.string()}, "garbage.lcmlog is damaged"},
      {{text.string()}, "not an LCM log"},
      {{good.string(), "--ref-channel", "GT"}, "no messages on channel GT"},
      {{no_est.string()}, "no estimate to evaluate"},
      {{good.string(), "--ref-channel", "ODOMETRY", "--odom-channel", "GROUND_TRUTH", "--offset",
        "100"},
       "no associated poses"},
      {{"--ref", (dir_ / "ref.txt").string(), "--est", (dir_ / "bad.txt").string()},
       "bad.txt:3: expected 8 fields"},
      {{"--ref", (dir_ / "ref.txt").string(), "--est", (dir_ / "empty.txt").string()},
       "empty.txt: no poses"},
      {{"--ref", (dir_ / "ref.txt").string(), "--est", (dir_ / "nope.txt").string()},
       "nope.txt: no such file"},
      {{"--ref", (dir_ / "ref.txt").string(), "--est", (dir_ / "late.txt").string()},
       "no associated poses"},
  };
  for (const auto& [args, message] : cases) {
    const auto r = runProgram("vslam-eval", args);
    EXPECT_EQ(r.exit_code, 1) << args[0] << "\n" << r.output;
    EXPECT_TRUE(contains(r.output, message)) << "expected '" << message << "' in:\n" << r.output;
  }
  // A recording cut short (a power loss) is evaluated up to its last complete
  // event, as vslam-replay reads it, with a warning naming what was lost.
  const auto r = runProgram("vslam-eval", {cut.string()});
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(contains(r.output, "cut.lcmlog ends with")) << r.output;
  EXPECT_TRUE(contains(r.output, "ATE")) << r.output;
}

TEST_F(EvalTool, WrongMessageTypeOnAChannelIsNamed) {
  const fs::path log = dir_ / "run.lcmlog";
  writeDriveLog(log, {true, true, false, true});
  const auto r = runCli({log.string(), "--ref-channel", "MAP"});
  EXPECT_EQ(r.code, 1);
  EXPECT_TRUE(contains(r.err, "channel MAP")) << r.err;
  EXPECT_TRUE(contains(r.err, "not vslam.ground_truth_pose_t")) << r.err;
  const auto r2 =
      runCli({log.string(), "--map-channel", "POSE_ESTIMATE", "--est-channel", "POSE_ODOMETRY"});
  EXPECT_EQ(r2.code, 1);
  EXPECT_TRUE(contains(r2.err, "is not vslam.map_t")) << r2.err;
}

// scripts/accuracy, scripts/benchmark-homes and docs/evaluation.md show the
// report in this order; a reordering would show as a changed file.
TEST_F(EvalTool, JsonKeysKeepTheirOrder) {
  const fs::path log = dir_ / "run.lcmlog", json = dir_ / "out.json";
  writeDriveLog(log, {});
  ASSERT_EQ(runCli({log.string(), "--json", json.string()}).code, 0);
  const auto j = nlohmann::ordered_json::parse(vslam::test::fileBytes(json));
  EXPECT_EQ(keysInOrder(j), (std::vector<std::string>{"tool", "mode", "input", "parameters",
                                                      "reference", "estimates", "landmarks"}));
  EXPECT_EQ(
      keysInOrder(j.at("parameters")),
      (std::vector<std::string>{"max_diff_s", "offset_s", "align", "rpe_delta", "rpe_delta_unit"}));
  const auto& e = j.at("estimates").at(0);
  EXPECT_EQ(keysInOrder(e),
            (std::vector<std::string>{"name", "kind", "source", "poses", "duration_s",
                                      "path_length_m", "alignment", "ate", "rpe"}));
  EXPECT_EQ(keysInOrder(e.at("rpe")),
            (std::vector<std::string>{"pairs", "reference_max_time_diff_s", "translation_m",
                                      "rotation_deg"}));
  EXPECT_EQ(keysInOrder(e.at("ate").at("translation_m")),
            (std::vector<std::string>{"count", "rmse", "mean", "median", "std", "min", "max"}));
  EXPECT_EQ(e.at("alignment").at("rotation_rowmajor").size(), 9u);
}

// No value (NaN, a step of -1) is null, not a number; strings from outside
// are escaped; the keys keep the order the scripts read.
TEST_F(EvalTool, AppearanceJsonWritesNullForNoValue) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  vslam::eval::AppearanceReport report;
  report.input = dir_.string() + "/a \"quoted\"\\run.lcmlog";
  report.steps.resize(3);
  report.map_states = 4;
  report.mean_hypotheses = 2.5;
  report.mean_position_error = nan;
  report.max_position_error = std::numeric_limits<double>::infinity();
  vslam::eval::AppearanceKidnap kidnap;
  kidnap.step = 7;
  kidnap.t = 1.5;
  kidnap.first_mapped_step = 9;
  report.kidnaps.push_back(kidnap);
  vslam::eval::AppearanceRelocalization reloc;
  reloc.step = 12;
  reloc.state_id = 3;
  reloc.belief = 0.25;
  reloc.position_error = nan;
  report.relocalizations.push_back(reloc);
  const fs::path json = dir_ / "appearance.json";
  vslam::eval::writeAppearanceJson(json, report);

  const auto j = nlohmann::ordered_json::parse(vslam::test::fileBytes(json));
  EXPECT_EQ(j.at("input").get<std::string>(), report.input);
  EXPECT_EQ(j.at("steps").get<int>(), 3);
  EXPECT_TRUE(j.at("steps").is_number_integer());
  EXPECT_EQ(j.at("map_states").get<int>(), 4);
  EXPECT_EQ(j.at("map_links").get<int>(), -1);  // no map message: -1, as the struct says
  EXPECT_DOUBLE_EQ(j.at("mean_hypotheses").get<double>(), 2.5);
  EXPECT_TRUE(j.at("mean_position_error_m").is_null());
  EXPECT_TRUE(j.at("max_position_error_m").is_null());
  const auto& k = j.at("kidnaps").at(0);
  EXPECT_EQ(keysInOrder(k),
            (std::vector<std::string>{"kind", "step", "t", "status", "first_mapped_step",
                                      "first_correct_step", "steps_to_relocalize"}));
  EXPECT_EQ(k.at("kind").get<std::string>(), "carry");
  EXPECT_EQ(k.at("status").get<std::string>(), "no mapped place reached");
  EXPECT_EQ(k.at("first_mapped_step").get<int>(), 9);
  EXPECT_TRUE(k.at("first_correct_step").is_null());
  EXPECT_TRUE(k.at("steps_to_relocalize").is_null());
  const auto& rl = j.at("relocalizations").at(0);
  EXPECT_EQ(keysInOrder(rl),
            (std::vector<std::string>{"step", "t", "state_id", "previous_state_id", "belief",
                                      "position_error_m", "heading_error_rad", "correct"}));
  EXPECT_EQ(rl.at("previous_state_id").get<int>(), -1);
  EXPECT_TRUE(rl.at("position_error_m").is_null());
  EXPECT_FALSE(rl.at("correct").get<bool>());
  EXPECT_EQ(keysInOrder(j), (std::vector<std::string>{"input",
                                                      "steps",
                                                      "states_created",
                                                      "map_states",
                                                      "map_links",
                                                      "mean_hypotheses",
                                                      "max_hypotheses",
                                                      "revisit_hypotheses",
                                                      "mean_position_error_m",
                                                      "weighted_position_error_m",
                                                      "weighted_nearest_state_distance_m",
                                                      "median_position_error_m",
                                                      "max_position_error_m",
                                                      "mean_abs_heading_error_rad",
                                                      "fraction_within_action",
                                                      "steps_best_revisit",
                                                      "mean_best_position_error_m",
                                                      "mean_nearest_state_distance_m",
                                                      "states_either_way",
                                                      "mean_step_seconds",
                                                      "revisit_steps",
                                                      "revisit_steps_recognized",
                                                      "wrong_revisit_steps",
                                                      "relocalizations_correct",
                                                      "relocalizations_wrong",
                                                      "kidnaps",
                                                      "relocalizations"}));
}

// The appearance evaluation counts a state as mapped facing either way when
// the process's cameras (its map message) face opposite ways (their
// calibration messages). A robot drives 4 m east, turns and drives back:
// the way back passes the first states turned around. Cameras forward and
// backward: the way back is at mapped places; forward and left: it is not;
// the backward camera's calibration damaged: named, skipped, not either way.
TEST_F(EvalTool, AppearanceStatesCountEitherWayWithCamerasFacingOpposite) {
  enum class Second { kBackward, kLeft, kDamaged };
  const auto evaluate = [&](Second second) {
    const fs::path log_file = dir_ / "appearance.lcmlog";
    {
      vslam::bus::LogWriter log(log_file);
      const auto calibration = [&](const std::string& name, double yaw) {
        vslam::camera_calibration_t c{};
        c.utime = kT0;
        c.camera = name;
        c.image_channel = "CAM_" + name;
        c.width = 320;
        c.height = 240;
        c.fx = c.fy = 250;
        c.cx = 160;
        c.cy = 120;
        // Optical axis along the robot's heading turned by yaw: camera z =
        // (cos, sin, 0), x = (sin, -cos, 0), y = (0, 0, -1).
        Eigen::Matrix3d r;
        r.col(0) = Eigen::Vector3d(std::sin(yaw), -std::cos(yaw), 0);
        r.col(1) = Eigen::Vector3d(0, 0, -1);
        r.col(2) = Eigen::Vector3d(std::cos(yaw), std::sin(yaw), 0);
        const Eigen::Quaterniond q(r);
        c.robot_q_camera[0] = q.w();
        c.robot_q_camera[1] = q.x();
        c.robot_q_camera[2] = q.y();
        c.robot_q_camera[3] = q.z();
        return c;
      };
      log.writeMessage(kT0, "CAM_FORWARD_CALIBRATION", calibration("forward", 0));
      if (second == Second::kDamaged) {
        std::vector<uint8_t> data(
            static_cast<size_t>(calibration("backward", M_PI).getEncodedSize()));
        calibration("backward", M_PI).encode(data.data(), 0, static_cast<int>(data.size()));
        data.resize(20);  // the fingerprint and a few bytes
        log.write(kT0, "CAM_BACKWARD_CALIBRATION", data);
      } else {
        const bool left = second == Second::kLeft;
        log.writeMessage(kT0, left ? "CAM_LEFT_CALIBRATION" : "CAM_BACKWARD_CALIBRATION",
                         calibration(left ? "left" : "backward", left ? M_PI / 2 : M_PI));
      }
      const std::string other = second == Second::kLeft ? "left" : "backward";
      // Steps 0-4 at x = 0..4 facing east, 5-9 at x = 4..0 facing west; each a new state.
      vslam::appearance_map_t map{};
      for (int k = 0; k < 10; ++k) {
        const int64_t t = kT0 + 1000000LL * (k + 1);
        const bool back = k >= 5;
        vslam::ground_truth_pose_t gt{};
        gt.utime = t;
        gt.x = back ? 9 - k : k;
        gt.theta = back ? M_PI : 0;
        log.writeMessage(t, "GROUND_TRUTH", gt);
        log.writeMessage(t + 1, "GROUND_TRUTH", gt);
        vslam::appearance_hypotheses_t h{};
        h.utime = t;
        h.step = k;
        h.best_state_id = k;
        h.best_belief = 1;
        vslam::appearance_hypothesis_t leaf{};
        leaf.hypothesis_id = k;
        leaf.parent_id = k - 1;
        leaf.state_id = k;
        leaf.is_new_state = true;
        leaf.belief = 1;
        leaf.path_length = k + 1;
        h.hypotheses.push_back(leaf);
        h.num_hypotheses = 1;
        log.writeMessage(t, "APPEARANCE_HYPOTHESES", h);
        vslam::appearance_state_t st{};
        st.state_id = k;
        st.utime = t;
        st.num_cameras = 2;
        st.num_bins = 1;
        st.cameras = {"forward", other};
        st.histograms = {{1.f}, {1.f}};
        map.states.push_back(st);
      }
      map.utime = kT0 + 11000000;
      map.num_states = static_cast<int32_t>(map.states.size());
      log.writeMessage(map.utime, "APPEARANCE_MAP", map);
    }
    return vslam::eval::evaluateAppearanceLog(log_file, {});
  };
  const auto opposite = evaluate(Second::kBackward);
  EXPECT_TRUE(opposite.states_either_way);
  EXPECT_EQ(opposite.either_way_cameras, "forward/backward");
  // The way back (steps 6-9; 5 is at the turn, beside state 4 made just before)
  // passes states 3..0 turned around: mapped places.
  EXPECT_EQ(opposite.revisit_steps, 4);
  for (const Second other : {Second::kLeft, Second::kDamaged}) {
    const auto r = evaluate(other);
    EXPECT_FALSE(r.states_either_way);
    EXPECT_EQ(r.revisit_steps, 0) << "a state passed the other way is not a mapped place";
  }
}
