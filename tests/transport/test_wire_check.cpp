// The wire check generated from lcmtypes/*.lcm (cmake/lcm_wire_check.py),
// through bus::checkedDecode, the one way the stack decodes outside bytes:
//  - for every count that sizes an array, a hand-built message claiming a
//    huge or negative count with no data after it (the 39-byte
//    landmark_request_t claiming 5e8 ids that killed vslam-landmark-db) is
//    rejected, naming the field, with no allocation larger than a few KB;
//  - every message the transport fillers make passes and round-trips;
//  - every truncation of a valid encoding, and every byte of trailing
//    garbage, is rejected; random corruption never allocates more than a
//    small multiple of the message's size;
//  - end to end: the hostile message sent over UDP multicast (in a private
//    network namespace) to a real bus::Bus is counted malformed, and the
//    next valid message is still delivered.

#include <gtest/gtest.h>

#include <atomic>
#include <climits>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <lcm/lcm-cpp.hpp>
#include <new>
#include <random>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "bus/bus.hpp"
#include "bus/checked_decode.hpp"
#include "message_fill.hpp"
#include "process_harness.hpp"
#include "util/time.hpp"

// ---- the largest single allocation, to show the check allocates nothing ----
//
// Replaces the global operator new of this test program. The plain and the
// array forms meet here (the default new[] calls new); the aligned forms are
// not used by the decoders. Out of line, so that GCC does not see free() on a
// pointer from new at the call sites (-Wmismatched-new-delete).
namespace {
std::atomic<size_t> g_largest_allocation{0};
}  // namespace

[[gnu::noinline]] void* operator new(size_t n) {
  size_t seen = g_largest_allocation.load(std::memory_order_relaxed);
  while (n > seen && !g_largest_allocation.compare_exchange_weak(seen, n)) {
  }
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}
[[gnu::noinline]] void operator delete(void* p) noexcept { std::free(p); }
[[gnu::noinline]] void operator delete(void* p, size_t) noexcept { std::free(p); }

namespace tt = vslam::transport_test;
namespace fs = std::filesystem;
using vslam::bus::checkedDecode;

namespace {

// The largest single allocation while f() runs.
size_t largestAllocationDuring(const std::function<void()>& f) {
  g_largest_allocation = 0;
  f();
  return g_largest_allocation.load();
}

// ---- hand-built encodings -----------------------------------------------------

// Bytes as LCM lays them out: big-endian integers, strings as an int32
// length counting the NUL, then the bytes and the NUL.
class Wire {
 public:
  template <class Msg>
  static Wire of() {
    Wire w;
    w.be(Msg::getHash(), 8);
    return w;
  }
  Wire& i8(int64_t v) { return be(static_cast<uint64_t>(v), 1); }
  Wire& i16(int64_t v) { return be(static_cast<uint64_t>(v), 2); }
  Wire& i32(int64_t v) { return be(static_cast<uint64_t>(v), 4); }
  Wire& i64(int64_t v) { return be(static_cast<uint64_t>(v), 8); }
  Wire& f32(int n = 1) { return zeros(4 * n); }
  Wire& f64(int n = 1) { return zeros(8 * n); }
  Wire& str(const std::string& s) {
    i32(static_cast<int64_t>(s.size()) + 1);
    bytes_.insert(bytes_.end(), s.begin(), s.end());
    bytes_.push_back(0);
    return *this;
  }
  // A count of `width` bytes (the type of the count member).
  Wire& count(int width, int64_t v) { return be(static_cast<uint64_t>(v), width); }
  const std::vector<uint8_t>& bytes() const { return bytes_; }

 private:
  Wire& be(uint64_t v, int n) {
    for (int i = n - 1; i >= 0; --i) bytes_.push_back(static_cast<uint8_t>(v >> (8 * i)));
    return *this;
  }
  Wire& zeros(int n) {
    bytes_.insert(bytes_.end(), static_cast<size_t>(n), 0);
    return *this;
  }
  std::vector<uint8_t> bytes_;
};

// A message whose count member `count` claims `claim` elements and ends
// right after the count (or where noted), as a hostile sender would send it.
struct HostileCase {
  std::string type;   // struct name, e.g. "landmark_request_t"
  std::string count;  // the count member, as in the .lcm file; "" for a nested one
  std::string field;  // the array the rejection must name, e.g. "landmark_ids"
  int width;          // bytes of the count member
  std::function<std::vector<uint8_t>(int64_t claim)> build;
  std::function<bool(const std::vector<uint8_t>&, std::string*)> decode;
};

template <class Msg>
std::function<bool(const std::vector<uint8_t>&, std::string*)> decoderOf() {
  return [](const std::vector<uint8_t>& bytes, std::string* why) {
    Msg msg{};
    return checkedDecode(msg, bytes.data(), bytes.size(), why);
  };
}

// The fields of landmark_t up to num_points.
Wire& landmarkHead(Wire& w) {
  return w.i64(-1).i64(7).i32(0).str("forward").i64(1700000000000000LL).f64(3);
}
// The fields of appearance_state_t up to num_cameras.
Wire& stateHead(Wire& w) { return w.i64(3).i64(1700000000000000LL).f64(3); }

std::vector<HostileCase> hostileCases() {
  using namespace vslam;
  std::vector<HostileCase> cases;
  auto add = [&](std::string type, std::string count, std::string field, int width, auto build,
                 auto decode) {
    cases.push_back({std::move(type), std::move(count), std::move(field), width, build, decode});
  };
  // The message of issue 19: 39 bytes, 5e8 ids claimed.
  add(
      "landmark_request_t", "num_ids", "landmark_ids", 4,
      [](int64_t n) {
        return Wire::of<landmark_request_t>()
            .i64(1700000000000000LL)
            .str("a")
            .str("")
            .i64(0)
            .i32(n)
            .bytes();
      },
      decoderOf<landmark_request_t>());
  add(
      "landmark_summary_t", "num_landmarks", "landmark_ids", 4,
      [](int64_t n) {
        return Wire::of<landmark_summary_t>().i64(1).str("db").i64(2).i32(3).i32(n).bytes();
      },
      decoderOf<landmark_summary_t>());
  add(
      "image_t", "data_size", "data", 4,
      [](int64_t n) {
        return Wire::of<image_t>()
            .i64(1)
            .i64(2)
            .str("forward")
            .i32(640)
            .i32(480)
            .i32(640)
            .i8(0)
            .f32()
            .i32(n)
            .bytes();
      },
      decoderOf<image_t>());
  add(
      "camera_calibration_t", "num_distortion", "distortion", 1,
      [](int64_t n) {
        return Wire::of<camera_calibration_t>()
            .i64(1)
            .str("forward")
            .str("CAM_FORWARD_IMAGE")
            .i32(640)
            .i32(480)
            .f64(5)
            .i8(n)
            .bytes();
      },
      decoderOf<camera_calibration_t>());
  add(
      "landmark_t", "num_points", "points", 4,
      [](int64_t n) {
        Wire w = Wire::of<landmark_t>();
        return landmarkHead(w).i32(n).bytes();
      },
      decoderOf<landmark_t>());
  add(
      "landmark_t", "descriptor_size", "descriptors", 2,
      [](int64_t n) {
        Wire w = Wire::of<landmark_t>();
        // One point: points, keypoints, scales, orientations; then the claim.
        return landmarkHead(w).i32(1).f32(3).f32(2).f32().f32().i16(n).bytes();
      },
      decoderOf<landmark_t>());
  add(
      "landmark_update_t", "", "landmark.points", 4,
      [](int64_t n) {
        Wire w = Wire::of<landmark_update_t>();
        w.i64(1).str("db").i64(2).i8(landmark_update_t::OP_PROPOSED).str("");
        return landmarkHead(w).i32(n).bytes();
      },
      decoderOf<landmark_update_t>());
  add(
      "map_t", "num_landmarks", "landmarks", 4,
      [](int64_t n) {
        return Wire::of<map_t>().i64(1).i64(2).str("backend").str("db").i32(n).bytes();
      },
      decoderOf<map_t>());
  add(
      "particle_set_t", "num_particles", "particles", 4,
      [](int64_t n) {
        return Wire::of<particle_set_t>().i64(1).i64(2).str("backend").f64(2).i32(n).bytes();
      },
      decoderOf<particle_set_t>());
  add(
      "appearance_state_t", "num_cameras", "cameras", 2,
      [](int64_t n) {
        Wire w = Wire::of<appearance_state_t>();
        return stateHead(w).i16(n).i16(8).bytes();
      },
      decoderOf<appearance_state_t>());
  add(
      "appearance_state_t", "num_bins", "histograms", 2,
      [](int64_t n) {
        Wire w = Wire::of<appearance_state_t>();
        return stateHead(w).i16(1).i16(n).str("forward").bytes();
      },
      decoderOf<appearance_state_t>());
  add(
      "appearance_hypotheses_t", "num_hypotheses", "hypotheses", 4,
      [](int64_t n) {
        return Wire::of<appearance_hypotheses_t>().i64(1).i64(2).i64(3).f64(2).i32(n).bytes();
      },
      decoderOf<appearance_hypotheses_t>());
  add(
      "appearance_map_t", "num_states", "states", 4,
      [](int64_t n) { return Wire::of<appearance_map_t>().i64(1).i64(2).i32(n).bytes(); },
      decoderOf<appearance_map_t>());
  add(
      "appearance_map_t", "num_links", "links", 4,
      [](int64_t n) { return Wire::of<appearance_map_t>().i64(1).i64(2).i32(0).i32(n).bytes(); },
      decoderOf<appearance_map_t>());
  add(
      "appearance_map_t", "", "states[0].cameras", 2,
      [](int64_t n) {
        Wire w = Wire::of<appearance_map_t>();
        w.i64(1).i64(2).i32(1);
        return stateHead(w).i16(n).i16(8).bytes();
      },
      decoderOf<appearance_map_t>());
  add(
      "health_t", "num_metrics", "metrics", 4,
      [](int64_t n) {
        return Wire::of<health_t>()
            .i64(1)
            .str("vslam-frontend")
            .str("frontend_forward")
            .str("robot")
            .i32(4242)
            .f64()
            .i8(health_t::LEVEL_OK)
            .str("")
            .f64()
            .i64(1)
            .i64(2)
            .i64(3)
            .i64(4)
            .i64(5)
            .f64()
            .i32(n)
            .bytes();
      },
      decoderOf<health_t>());
  return cases;
}

// The claims tried for a count of `width` bytes: the issue's (5e8 ids, 3e8
// landmarks, 1e8 below the int overflow), the extremes, and negatives.
std::vector<int64_t> claimsFor(int width) {
  switch (width) {
    case 1:
      return {127, 14, -1, -128};
    case 2:
      return {INT16_MAX, 1000, -1, INT16_MIN};
    default:
      return {500000000, 300000000, 100000000, INT32_MAX, 1000000, -1, INT32_MIN};
  }
}

// (type, count member) for every array sized by a member, read from the
// .lcm files: the hostile cases must cover each.
std::set<std::string> variableArraysOfTheLcmFiles() {
  std::set<std::string> out;
  const std::regex strukt(R"(struct\s+(\w+))");
  const std::regex dim(R"(\[\s*([A-Za-z_]\w*)\s*\])");
  for (const auto& entry : fs::directory_iterator(fs::path(VSLAM_SOURCE_DIR) / "lcmtypes")) {
    if (entry.path().extension() != ".lcm") continue;
    std::ifstream in(entry.path());
    std::string type, line;
    while (std::getline(in, line)) {
      line = line.substr(0, line.find("//"));
      std::smatch m;
      if (std::regex_search(line, m, strukt)) type = m[1];
      for (auto it = std::sregex_iterator(line.begin(), line.end(), dim);
           it != std::sregex_iterator(); ++it) {
        out.insert(type + "." + (*it)[1].str());
      }
    }
  }
  return out;
}

TEST(WireCheck, HostileCasesCoverEveryCountOfTheLcmFiles) {
  std::set<std::string> covered;
  for (const auto& c : hostileCases()) {
    if (!c.count.empty()) covered.insert(c.type + "." + c.count);
  }
  const std::set<std::string> counts = variableArraysOfTheLcmFiles();
  ASSERT_GE(counts.size(), 10u) << "lcmtypes/ not read?";
  for (const auto& c : counts) EXPECT_TRUE(covered.count(c)) << c << " has no hostile case";
  for (const auto& c : covered) EXPECT_TRUE(counts.count(c)) << c << " is not in lcmtypes/";
}

TEST(WireCheck, TheIssueMessageIs39Bytes) {
  const HostileCase c = hostileCases().front();
  ASSERT_EQ(c.type, "landmark_request_t");
  EXPECT_EQ(c.build(500000000).size(), 39u);
}

TEST(WireCheck, HugeAndNegativeCountsAreRejectedWithoutAllocating) {
  int tried = 0;
  for (const auto& c : hostileCases()) {
    for (const int64_t claim : claimsFor(c.width)) {
      SCOPED_TRACE(c.type + " " + (c.count.empty() ? c.field : c.count) + " = " +
                   std::to_string(claim));
      const std::vector<uint8_t> bytes = c.build(claim);
      std::string why;
      bool ok = true;
      const size_t largest = largestAllocationDuring([&] { ok = c.decode(bytes, &why); });
      EXPECT_FALSE(ok);
      EXPECT_NE(why.find(": " + c.field + ":"), std::string::npos) << why;
      EXPECT_LT(largest, 4096u) << why;
      ++tried;
    }
  }
  RecordProperty("hostile_messages", tried);
  EXPECT_GE(tried, 80);
}

TEST(WireCheck, TheReasonNamesTypeFieldAndCounts) {
  const auto c = hostileCases().front();
  std::string why;
  EXPECT_FALSE(c.decode(c.build(500000000), &why));
  EXPECT_EQ(why,
            "vslam.landmark_request_t: landmark_ids: 500000000 elements claimed in a message of "
            "39 bytes");
  EXPECT_FALSE(c.decode(c.build(-1), &why));
  EXPECT_EQ(why, "vslam.landmark_request_t: landmark_ids: count num_ids = -1 is negative");
  EXPECT_FALSE(c.decode(c.build(5), &why));
  EXPECT_EQ(why,
            "vslam.landmark_request_t: landmark_ids: 5 elements of >= 8 bytes need >= 40 bytes, "
            "0 left");
}

TEST(WireCheck, BadStringLengthsAreRejected) {
  using vslam::landmark_request_t;
  // requester's length: 0 (the decoder would assign length - 1 characters),
  // negative, and more than the bytes left.
  for (const int64_t length : {0LL, -1LL, -100LL, 1000LL, static_cast<long long>(INT32_MAX)}) {
    SCOPED_TRACE(length);
    const auto bytes =
        Wire::of<landmark_request_t>().i64(1).i32(length).str("").i64(0).i32(0).bytes();
    landmark_request_t m{};
    std::string why;
    EXPECT_FALSE(checkedDecode(m, bytes.data(), bytes.size(), &why));
    EXPECT_NE(why.find("requester:"), std::string::npos) << why;
  }
}

// A string is a C string: found by fuzzing (tests/fuzz/fuzz_messages), a
// NUL inside decoded to a std::string that encoded again to other bytes
// (the encoder writes up to the first NUL, its size counts them all).
TEST(WireCheck, StringsWithANulInsideOrNoneAtTheEndAreRejected) {
  using vslam::landmark_request_t;
  for (const std::string& body : {std::string("fro\0nt", 6), std::string("front")}) {
    SCOPED_TRACE(body.size());
    auto wire = Wire::of<landmark_request_t>().i64(1);
    if (body.size() == 6) {
      wire.str(body);  // "fro\0nt" then the NUL
    } else {
      wire.i32(5).i8('f').i8('r').i8('o').i8('n').i8('t');  // no NUL at the end
    }
    const auto bytes = wire.i64(0).i32(0).bytes();
    landmark_request_t m{};
    std::string why;
    EXPECT_FALSE(checkedDecode(m, bytes.data(), bytes.size(), &why));
    EXPECT_NE(why.find("requester: not a C string"), std::string::npos) << why;
  }
}

TEST(WireCheck, AnotherTypesFingerprintIsRejected) {
  const auto bytes = tt::encodeToBytes(tt::filled<vslam::landmark_request_t>(1));
  vslam::landmark_summary_t m{};
  std::string why;
  EXPECT_FALSE(checkedDecode(m, bytes.data(), bytes.size(), &why));
  EXPECT_EQ(why, "vslam.landmark_summary_t: fingerprint is not vslam.landmark_summary_t's");
}

TEST(WireCheck, EveryFilledMessagePassesAndRoundTrips) {
  tt::forEachType(tt::AllTypes{}, [](auto tag) {
    using T = typename decltype(tag)::type;
    for (int seed = 0; seed < 4; ++seed) {
      SCOPED_TRACE(std::string(vslam::wire::Walker<T>::kName) + " seed " + std::to_string(seed));
      const std::vector<uint8_t> bytes = tt::encodeToBytes(tt::filled<T>(seed));
      ASSERT_FALSE(bytes.empty());
      std::string why;
      EXPECT_TRUE(vslam::wire::check<T>(bytes.data(), bytes.size(), &why)) << why;
      T decoded{};
      ASSERT_TRUE(checkedDecode(decoded, bytes.data(), bytes.size(), &why)) << why;
      EXPECT_EQ(tt::encodeToBytes(decoded), bytes);
    }
  });
}

TEST(WireCheck, MinimumSizesAgreeWithTheEncoder) {
  // An all-zero message (empty strings and arrays) is the smallest encoding.
  tt::forEachType(tt::AllTypes{}, [](auto tag) {
    using T = typename decltype(tag)::type;
    const T empty{};
    EXPECT_EQ(empty.getEncodedSize(), 8 + vslam::wire::Walker<T>::kMinSize)
        << vslam::wire::Walker<T>::kName;
    const std::vector<uint8_t> bytes = tt::encodeToBytes(empty);
    std::string why;
    EXPECT_TRUE(vslam::wire::check<T>(bytes.data(), bytes.size(), &why)) << why;
  });
}

TEST(WireCheck, EveryTruncationAndTrailingByteIsRejected) {
  int cuts = 0;
  tt::forEachType(tt::AllTypes{}, [&](auto tag) {
    using T = typename decltype(tag)::type;
    for (int seed = 0; seed < 2; ++seed) {
      const std::vector<uint8_t> bytes = tt::encodeToBytes(tt::filled<T>(seed));
      for (size_t cut = 0; cut < bytes.size(); ++cut) {
        // A buffer of exactly `cut` bytes, so AddressSanitizer sees any read past it.
        const std::vector<uint8_t> part(bytes.begin(), bytes.begin() + static_cast<long>(cut));
        T m{};
        std::string why;
        EXPECT_FALSE(checkedDecode(m, part.data(), part.size(), &why))
            << vslam::wire::Walker<T>::kName << " cut at " << cut << " of " << bytes.size();
        EXPECT_FALSE(why.empty());
        ++cuts;
      }
      std::vector<uint8_t> longer = bytes;
      longer.push_back(0);
      T m{};
      std::string why;
      EXPECT_FALSE(checkedDecode(m, longer.data(), longer.size(), &why));
      EXPECT_NE(why.find("1 bytes after the end"), std::string::npos) << why;
    }
  });
  RecordProperty("truncations", cuts);
}

TEST(WireCheck, RandomCorruptionNeverAllocatesMoreThanTheMessageWarrants) {
  // Bytes overwritten at random in valid encodings: whatever passes the check
  // decodes with no allocation beyond a small multiple of the message size
  // (an element count is never above the message's size; a decoded element
  // costs at most a 24-byte container).
  std::mt19937 rng(19);
  int passed = 0, rejected = 0;
  tt::forEachType(tt::AllTypes{}, [&](auto tag) {
    using T = typename decltype(tag)::type;
    const std::vector<uint8_t> valid = tt::encodeToBytes(tt::filled<T>(1));
    for (int round = 0; round < 3000; ++round) {
      std::vector<uint8_t> bytes = valid;
      const int flips = 1 + static_cast<int>(rng() % 4);
      for (int f = 0; f < flips; ++f) {
        // Never the fingerprint: a corrupted one only tests the first check.
        const size_t at = 8 + rng() % (bytes.size() - 8);
        bytes[at] = static_cast<uint8_t>(rng() % 3 == 0 ? 0xff : rng());
      }
      T m{};
      bool ok = false;
      const size_t largest = largestAllocationDuring(
          [&] { ok = checkedDecode(m, bytes.data(), bytes.size(), nullptr); });
      (ok ? passed : rejected)++;
      ASSERT_LE(largest, 32 * bytes.size() + 4096)
          << vslam::wire::Walker<T>::kName << " round " << round << (ok ? " (passed)" : "");
    }
  });
  RecordProperty("passed", passed);
  RecordProperty("rejected", rejected);
  EXPECT_GT(rejected, 0);
}

// ---- end to end: the hostile message over UDP multicast to a real Bus --------

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0&recv_buf_size=8388608";

class WireCheckNetns : public tt::NetnsTest {};

TEST_F(WireCheckNetns, BusCountsTheHostileMessageMalformedAndKeepsReceiving) {
  VSLAM_IN_FRESH_NETNS();
  lcm::LCM lcm(kUrl);
  ASSERT_TRUE(lcm.good()) << "cannot open LCM at " << kUrl;
  vslam::WallClock clock;
  vslam::bus::Bus bus(lcm, clock, "test_wire_check");
  std::vector<vslam::landmark_request_t> requests;
  std::vector<vslam::landmark_summary_t> summaries;
  bus.subscribe<vslam::landmark_request_t>(
      "TEST_LANDMARK_REQUEST", [&](const vslam::landmark_request_t& m) { requests.push_back(m); });
  bus.subscribe<vslam::landmark_summary_t>(
      "TEST_LANDMARK_SUMMARY", [&](const vslam::landmark_summary_t& m) { summaries.push_back(m); });

  // Another socket, as another host's process would send them.
  tt::TestBus sender(kUrl);
  ASSERT_TRUE(sender.good());
  const std::vector<HostileCase> cases = hostileCases();
  const HostileCase& request = cases[0];
  const HostileCase& summary = cases[1];
  ASSERT_EQ(summary.type, "landmark_summary_t");
  sender.publishRaw("TEST_LANDMARK_REQUEST", request.build(500000000));
  sender.publishRaw("TEST_LANDMARK_SUMMARY", summary.build(300000000));
  const auto valid_request = tt::filled<vslam::landmark_request_t>(2);
  const auto valid_summary = tt::filled<vslam::landmark_summary_t>(3);
  sender.publish("TEST_LANDMARK_REQUEST", valid_request);
  sender.publish("TEST_LANDMARK_SUMMARY", valid_summary);

  const vslam::Utime deadline = vslam::monotonicUtime() + 5 * vslam::kMicrosPerSecond;
  while ((requests.empty() || summaries.empty()) && vslam::monotonicUtime() < deadline) {
    lcm.handleTimeout(50);
  }
  EXPECT_EQ(bus.counters().received.load(), 4);
  EXPECT_EQ(bus.counters().malformed.load(), 2);
  EXPECT_EQ(bus.counters().handler_errors.load(), 0);
  ASSERT_EQ(requests.size(), 1u) << "the valid request after the hostile one was not delivered";
  EXPECT_EQ(tt::encodeToBytes(requests[0]), tt::encodeToBytes(valid_request));
  ASSERT_EQ(summaries.size(), 1u) << "the valid summary after the hostile one was not delivered";
  EXPECT_EQ(tt::encodeToBytes(summaries[0]), tt::encodeToBytes(valid_summary));
}

}  // namespace
