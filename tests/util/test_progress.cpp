// util/progress.hpp: the line a long job shows on a terminal, and log lines
// scrolling above it instead of running into it.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <string>

#include "util/log.hpp"
#include "util/progress.hpp"

using vslam::ProgressMeter;

namespace {

// What `fn` writes to stderr (file descriptor 2).
template <class Fn>
std::string stderrOf(Fn fn) {
  std::fflush(stderr);
  const int saved = dup(STDERR_FILENO);
  std::FILE* capture = std::tmpfile();
  dup2(fileno(capture), STDERR_FILENO);
  fn();
  std::fflush(stderr);
  dup2(saved, STDERR_FILENO);
  close(saved);
  std::string text;
  std::rewind(capture);
  for (int c; (c = std::fgetc(capture)) != EOF;) text += static_cast<char>(c);
  std::fclose(capture);
  return text;
}

}  // namespace

TEST(ProgressMeter, SaysHowFarHowFastAndHowLong) {
  const ProgressMeter bytes("replay", 2e9, ProgressMeter::kBytes, false);
  EXPECT_EQ(bytes.line(5e8, 10, "120 s of log"),
            "replay: 500 MB of 2.00 GB (25%), 50.0 MB/s, 0m30s left, 120 s of log");
  const ProgressMeter seconds("simulate", 7200, ProgressMeter::kSeconds, false);
  EXPECT_EQ(seconds.line(3600, 900, ""),
            "simulate: 3600 s of 7200 s (50%), 4.0x real time, 15m00s left")
      << "robot seconds per wall second is the speed-up";
  const ProgressMeter items("import", 0, ProgressMeter::kItems, false);  // total unknown
  EXPECT_EQ(items.line(40, 8, "images"), "import: 40, 5.0/s, images");
  const ProgressMeter hours("replay", 1e6, ProgressMeter::kItems, false);
  EXPECT_EQ(hours.line(1e5, 500, ""), "replay: 100000 of 1000000 (10%), 200.0/s, 1h15m left");
}

TEST(ProgressMeter, IsSilentUnlessEnabledAndKeepsLogLinesWhole) {
  EXPECT_EQ(stderrOf([] {
              ProgressMeter m("job", 10, ProgressMeter::kItems, false);
              m.update(3);
              m.finish();
            }),
            "");
  const std::string out = stderrOf([] {
    ProgressMeter m("job", 10, ProgressMeter::kItems, true);
    m.update(3);
    vslam::log::info("a log line");
    m.finish();
  });
  const std::string clear = "\r\033[K";
  const size_t shown = out.find("job: 3 of 10 (30%)");
  ASSERT_NE(shown, std::string::npos) << out;
  const size_t logged = out.find("a log line\n");
  ASSERT_NE(logged, std::string::npos) << out;
  // Erased before the log line, drawn again after it, erased at the end.
  EXPECT_NE(out.rfind(clear, logged), std::string::npos) << out;
  EXPECT_GT(out.rfind(clear, logged), shown) << out;
  EXPECT_NE(out.find("job: 3 of 10", logged), std::string::npos) << out;
  EXPECT_EQ(out.substr(out.size() - clear.size()), clear) << out;
}
