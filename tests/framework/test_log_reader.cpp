// bus::LogReader: the one reader of LCM logs, strict for the tools and
// skipping for the replay, against damage LCM's own reader cannot survive.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <vector>

#include "bus/log_reader.hpp"
#include "bus/log_writer.hpp"
#include "support/test_logs.hpp"

namespace fs = std::filesystem;
using vslam::bus::LogDamage;
using vslam::bus::LogError;
using vslam::bus::LogReader;

namespace {

fs::path tempLog(const std::string& name) {
  static const fs::path dir = vslam::test::scratchDir("test_log_reader");
  return dir / name;
}

// An event (lcm_eventlog format) numbered `eventnum` on channel "EVIL"
// whose header claims `claimed` data bytes, followed by `data`.
void appendEvent(const fs::path& log, int64_t eventnum, int32_t claimed, const std::string& data) {
  std::ofstream out(log, std::ios::binary | std::ios::app);
  auto be = [&](uint64_t v, int bytes) {
    for (int i = bytes - 1; i >= 0; --i) out.put(static_cast<char>((v >> (8 * i)) & 0xff));
  };
  be(0xEDA1DA01, 4);  // sync
  be(static_cast<uint64_t>(eventnum), 8);
  be(1700000000000000ULL, 8);
  be(4, 4);  // channel length
  be(static_cast<uint32_t>(claimed), 4);
  out << "EVIL" << data;
}

// An event header whose data length is `claimed`, followed by no data.
void appendHeaderClaiming(const fs::path& log, int32_t claimed) {
  appendEvent(log, 2, claimed, "");
}

}  // namespace

// Found by fuzzing (tests/fuzz/fuzz_log): LCM 1.3.1 allocates the claimed
// length + 1 in int, so 2^31 - 1 overflows, the allocation fails and it
// reads into it: a crash of every tool on one damaged header.
TEST(LogReader, AnEventClaimingMoreThanTheFileHoldsIsDamageNotACrash) {
  const fs::path log = tempLog("oversized.lcmlog");
  {
    vslam::bus::LogWriter writer(log);
    writer.write(1, "A", std::vector<uint8_t>{1, 2, 3});
    writer.write(2, "B", std::vector<uint8_t>{4, 5});
  }
  appendHeaderClaiming(log, INT32_MAX);
  {  // and one good event after the damage
    std::ofstream out(log, std::ios::binary | std::ios::app);
    const fs::path good = tempLog("good.lcmlog");
    {
      vslam::bus::LogWriter writer(good);
      writer.write(3, "C", std::vector<uint8_t>{6});
    }
    std::ifstream in(good, std::ios::binary);
    out << in.rdbuf();
  }

  LogReader strict(log, LogDamage::kThrow);
  ASSERT_NE(strict.next(), nullptr);
  ASSERT_NE(strict.next(), nullptr);
  try {
    strict.next();
    FAIL() << "no LogError";
  } catch (const LogError& e) {
    EXPECT_NE(std::string(e.what()).find("claims 2147483647 data bytes"), std::string::npos)
        << e.what();
  }

  LogReader skipping(log, LogDamage::kSkip);
  std::vector<std::string> channels;
  while (const lcm::LogEvent* e = skipping.next()) channels.push_back(e->channel);
  EXPECT_EQ(channels, (std::vector<std::string>{"A", "B", "C"}));
  EXPECT_GT(skipping.stats().bytes_skipped, 0);
}

// Found by fuzzing (tests/fuzz/fuzz_log, UBSan): the event numbers are the
// file's word, and the gap between two far apart (INT64_MIN, then 21)
// overflowed int64 counting the events lost to damage.
TEST(LogReader, EventNumbersFarApartAreAGapNotAnOverflow) {
  const fs::path log = tempLog("far-apart.lcmlog");
  fs::remove(log);
  appendEvent(log, std::numeric_limits<int64_t>::min(), 1, "a");
  appendEvent(log, 21, 1, "b");
  appendEvent(log, std::numeric_limits<int64_t>::max(), 1, "c");
  appendEvent(log, std::numeric_limits<int64_t>::max(), 1, "d");  // no step: no gap
  LogReader skipping(log, LogDamage::kSkip);
  int events = 0;
  while (skipping.next() != nullptr) ++events;
  EXPECT_EQ(events, 4);
  EXPECT_EQ(skipping.stats().events_missing, std::numeric_limits<int64_t>::max())
      << "the gaps, added up to the most an int64 holds";
}

// A recording cut short (power loss): kCutTail reads the complete events and
// counts the tail; garbage after the last event, or damage before it, is
// still an error, as with kThrow.
TEST(LogReader, ACutLastEventIsReadPastOnlyWhereAskedAndOnlyAtTheEnd) {
  const fs::path whole = tempLog("whole.lcmlog");
  {
    vslam::bus::LogWriter writer(whole);
    for (int i = 0; i < 3; ++i) writer.write(i + 1, "A", std::vector<uint8_t>(100, 7));
  }
  std::string bytes;
  {
    std::ifstream in(whole, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  const auto write = [](const fs::path& f, const std::string& b) {
    std::ofstream(f, std::ios::binary | std::ios::trunc).write(b.data(), std::streamsize(b.size()));
  };
  const auto count = [](const fs::path& f, LogDamage mode, int64_t* tail = nullptr) {
    LogReader reader(f, mode);
    int n = 0;
    while (reader.next()) ++n;
    if (tail) *tail = reader.stats().tail_bytes;
    return n;
  };
  const fs::path cut = tempLog("cut.lcmlog");
  write(cut, bytes.substr(0, bytes.size() - 40));
  int64_t tail = 0;
  EXPECT_EQ(count(cut, LogDamage::kCutTail, &tail), 2);
  EXPECT_EQ(tail, static_cast<int64_t>(bytes.size() / 3 - 40));
  EXPECT_THROW(count(cut, LogDamage::kThrow), LogError);

  const fs::path junk_tail = tempLog("junk_tail.lcmlog");
  write(junk_tail, bytes + "JUNKJUNKJUNK");
  EXPECT_THROW(count(junk_tail, LogDamage::kCutTail), LogError);
  const fs::path junk_inside = tempLog("junk_inside.lcmlog");
  write(junk_inside, bytes.substr(0, bytes.size() / 3) + "JUNK" + bytes.substr(bytes.size() / 3));
  EXPECT_THROW(count(junk_inside, LogDamage::kCutTail), LogError);
  fs::remove_all(whole.parent_path());
}
