// Encode/decode round trip of every vslam LCM type, truncated and mistyped
// buffers, fingerprints, and the Java jar of the types.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <regex>
#include <set>
#include <string>
#include <vector>

#include "message_fill.hpp"

namespace tt = vslam::transport_test;
namespace fs = std::filesystem;

namespace {

// ---- key fields, compared directly (the byte comparison covers the rest) ----

void expectKeyFields(const vslam::image_t& a, const vslam::image_t& b) {
  EXPECT_EQ(a.seq, b.seq);
  EXPECT_EQ(a.camera, b.camera);
  EXPECT_EQ(a.width, b.width);
  EXPECT_EQ(a.height, b.height);
  EXPECT_EQ(a.row_stride, b.row_stride);
  EXPECT_EQ(a.exposure, b.exposure);
  EXPECT_EQ(a.data_size, b.data_size);
  EXPECT_EQ(a.data, b.data);
}
void expectKeyFields(const vslam::camera_calibration_t& a, const vslam::camera_calibration_t& b) {
  EXPECT_EQ(a.image_channel, b.image_channel);
  EXPECT_EQ(a.fx, b.fx);
  EXPECT_EQ(a.cy, b.cy);
  EXPECT_EQ(a.num_distortion, b.num_distortion);
  EXPECT_EQ(a.distortion, b.distortion);
  EXPECT_EQ(a.robot_t_camera[2], b.robot_t_camera[2]);
  EXPECT_EQ(a.robot_q_camera[3], b.robot_q_camera[3]);
}
void expectKeyFields(const vslam::odometry_t& a, const vslam::odometry_t& b) {
  EXPECT_EQ(a.utime, b.utime);
  EXPECT_EQ(a.seq, b.seq);
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.theta, b.theta);
  EXPECT_EQ(a.omega, b.omega);
}
void expectKeyFields(const vslam::visual_measurement_t& a, const vslam::visual_measurement_t& b) {
  EXPECT_EQ(a.landmark_id, b.landmark_id);
  EXPECT_EQ(a.camera, b.camera);
  EXPECT_EQ(a.dtheta, b.dtheta);
  EXPECT_EQ(a.status, b.status);
}
void expectKeyFields(const vslam::landmark_t& a, const vslam::landmark_t& b) {
  EXPECT_EQ(a.landmark_id, b.landmark_id);
  EXPECT_EQ(a.num_points, b.num_points);
  EXPECT_EQ(a.points, b.points);
  EXPECT_EQ(a.keypoints, b.keypoints);
  EXPECT_EQ(a.scales, b.scales);
  EXPECT_EQ(a.orientations, b.orientations);
  EXPECT_EQ(a.descriptor_size, b.descriptor_size);
  EXPECT_EQ(a.descriptors, b.descriptors);
  EXPECT_EQ(a.last_seen_utime, b.last_seen_utime);
}
void expectKeyFields(const vslam::landmark_update_t& a, const vslam::landmark_update_t& b) {
  EXPECT_EQ(a.revision, b.revision);
  EXPECT_EQ(a.op, b.op);
  EXPECT_EQ(a.requester, b.requester);
  expectKeyFields(a.landmark, b.landmark);
}
void expectKeyFields(const vslam::landmark_summary_t& a, const vslam::landmark_summary_t& b) {
  EXPECT_EQ(a.database_id, b.database_id);
  EXPECT_EQ(a.num_landmarks, b.num_landmarks);
  EXPECT_EQ(a.landmark_ids, b.landmark_ids);
  EXPECT_EQ(a.versions, b.versions);
}
void expectKeyFields(const vslam::landmark_request_t& a, const vslam::landmark_request_t& b) {
  EXPECT_EQ(a.requester, b.requester);
  EXPECT_EQ(a.since_revision, b.since_revision);
  EXPECT_EQ(a.landmark_ids, b.landmark_ids);
}
void expectKeyFields(const vslam::pose_estimate_t& a, const vslam::pose_estimate_t& b) {
  EXPECT_EQ(a.estimator, b.estimator);
  EXPECT_EQ(a.x, b.x);
  EXPECT_TRUE(
      std::equal(std::begin(a.covariance), std::end(a.covariance), std::begin(b.covariance)));
  EXPECT_EQ(a.odom_theta, b.odom_theta);
  EXPECT_EQ(a.kidnapped, b.kidnapped);
}
void expectKeyFields(const vslam::landmark_pose_t& a, const vslam::landmark_pose_t& b) {
  EXPECT_EQ(a.landmark_id, b.landmark_id);
  EXPECT_TRUE(
      std::equal(std::begin(a.covariance), std::end(a.covariance), std::begin(b.covariance)));
  EXPECT_EQ(a.num_observations, b.num_observations);
}
void expectKeyFields(const vslam::map_t& a, const vslam::map_t& b) {
  EXPECT_EQ(a.num_landmarks, b.num_landmarks);
  ASSERT_EQ(a.landmarks.size(), b.landmarks.size());
  for (size_t i = 0; i < a.landmarks.size(); ++i) expectKeyFields(a.landmarks[i], b.landmarks[i]);
}
void expectKeyFields(const vslam::particle_t& a, const vslam::particle_t& b) {
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.weight, b.weight);
  EXPECT_EQ(a.kind, b.kind);
}
void expectKeyFields(const vslam::particle_set_t& a, const vslam::particle_set_t& b) {
  EXPECT_EQ(a.effective_sample_size, b.effective_sample_size);
  ASSERT_EQ(a.particles.size(), b.particles.size());
  for (size_t i = 0; i < a.particles.size(); ++i) expectKeyFields(a.particles[i], b.particles[i]);
}
void expectKeyFields(const vslam::appearance_state_t& a, const vslam::appearance_state_t& b) {
  EXPECT_EQ(a.state_id, b.state_id);
  EXPECT_EQ(a.num_cameras, b.num_cameras);
  EXPECT_EQ(a.num_bins, b.num_bins);
  EXPECT_EQ(a.cameras, b.cameras);
  EXPECT_EQ(a.histograms, b.histograms);
}
void expectKeyFields(const vslam::appearance_link_t& a, const vslam::appearance_link_t& b) {
  EXPECT_EQ(a.from_state, b.from_state);
  EXPECT_EQ(a.to_state, b.to_state);
  EXPECT_EQ(a.sigma_rotation, b.sigma_rotation);
}
void expectKeyFields(const vslam::appearance_hypothesis_t& a,
                     const vslam::appearance_hypothesis_t& b) {
  EXPECT_EQ(a.hypothesis_id, b.hypothesis_id);
  EXPECT_EQ(a.is_new_state, b.is_new_state);
  EXPECT_EQ(a.belief, b.belief);
}
void expectKeyFields(const vslam::appearance_hypotheses_t& a,
                     const vslam::appearance_hypotheses_t& b) {
  EXPECT_EQ(a.best_state_id, b.best_state_id);
  ASSERT_EQ(a.hypotheses.size(), b.hypotheses.size());
  for (size_t i = 0; i < a.hypotheses.size(); ++i)
    expectKeyFields(a.hypotheses[i], b.hypotheses[i]);
}
void expectKeyFields(const vslam::appearance_map_t& a, const vslam::appearance_map_t& b) {
  ASSERT_EQ(a.states.size(), b.states.size());
  for (size_t i = 0; i < a.states.size(); ++i) expectKeyFields(a.states[i], b.states[i]);
  ASSERT_EQ(a.links.size(), b.links.size());
  for (size_t i = 0; i < a.links.size(); ++i) expectKeyFields(a.links[i], b.links[i]);
}
void expectKeyFields(const vslam::appearance_event_t& a, const vslam::appearance_event_t& b) {
  EXPECT_EQ(a.event, b.event);
  EXPECT_EQ(a.previous_state_id, b.previous_state_id);
  EXPECT_EQ(a.belief, b.belief);
}
void expectKeyFields(const vslam::health_metric_t& a, const vslam::health_metric_t& b) {
  EXPECT_EQ(a.name, b.name);
  EXPECT_EQ(a.value, b.value);
  EXPECT_EQ(a.unit, b.unit);
}
void expectKeyFields(const vslam::health_t& a, const vslam::health_t& b) {
  EXPECT_EQ(a.process, b.process);
  EXPECT_EQ(a.pid, b.pid);
  EXPECT_EQ(a.level, b.level);
  EXPECT_EQ(a.message, b.message);
  EXPECT_EQ(a.rss_bytes, b.rss_bytes);
  EXPECT_EQ(a.messages_malformed, b.messages_malformed);
  ASSERT_EQ(a.metrics.size(), b.metrics.size());
  for (size_t i = 0; i < a.metrics.size(); ++i) expectKeyFields(a.metrics[i], b.metrics[i]);
}
void expectKeyFields(const vslam::ground_truth_pose_t& a, const vslam::ground_truth_pose_t& b) {
  EXPECT_EQ(a.utime, b.utime);
  EXPECT_EQ(a.x, b.x);
  EXPECT_EQ(a.theta, b.theta);
}
void expectKeyFields(const vslam::view_jump_t& a, const vslam::view_jump_t& b) {
  EXPECT_EQ(a.utime, b.utime);
  EXPECT_EQ(a.previous_utime, b.previous_utime);
  EXPECT_EQ(a.camera, b.camera);
  EXPECT_EQ(a.matched_share, b.matched_share);
  EXPECT_EQ(a.thumbnail_similarity, b.thumbnail_similarity);
}

// ---- typed tests over every type -------------------------------------------------

template <class T>
class MessageRoundTrip : public ::testing::Test {};
using AllMessageTypes = ::testing::Types<VSLAM_TRANSPORT_ALL_TYPES>;
TYPED_TEST_SUITE(MessageRoundTrip, AllMessageTypes);

TYPED_TEST(MessageRoundTrip, EncodeDecodeReencodeIsIdentical) {
  using T = TypeParam;
  for (int seed : {0, 1, 2, 3, 7}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const T original = tt::filled<T>(seed);
    const int size = original.getEncodedSize();
    ASSERT_GT(size, 8);
    std::vector<uint8_t> bytes(static_cast<size_t>(size));
    ASSERT_EQ(original.encode(bytes.data(), 0, size), size);
    // The 8-byte fingerprint leads the message (big-endian).
    int64_t hash = 0;
    for (int i = 0; i < 8; ++i) hash = (hash << 8) | bytes[static_cast<size_t>(i)];
    EXPECT_EQ(hash, T::getHash());

    // Decode into an object holding other values (another seed), so a field
    // that decode leaves untouched cannot pass as decoded.
    T decoded = tt::filled<T>(seed + 1000);
    ASSERT_NE(tt::encodeToBytes(decoded), bytes) << "the two seeds must give different messages";
    ASSERT_EQ(decoded.decode(bytes.data(), 0, size), size);
    EXPECT_EQ(tt::encodeToBytes(decoded), bytes);
    EXPECT_EQ(decoded.getEncodedSize(), size);
    expectKeyFields(original, decoded);

    // At an offset inside a larger buffer as well.
    std::vector<uint8_t> padded(static_cast<size_t>(size) + 13, 0xA5);
    ASSERT_EQ(original.encode(padded.data(), 5, size), size);
    T decoded2 = tt::filled<T>(seed + 2000);
    ASSERT_EQ(decoded2.decode(padded.data(), 5, size), size);
    EXPECT_EQ(tt::encodeToBytes(decoded2), bytes);
  }
}

TYPED_TEST(MessageRoundTrip, TruncatedBufferFailsToDecode) {
  using T = TypeParam;
  const T original = tt::filled<T>(5);
  const std::vector<uint8_t> bytes = tt::encodeToBytes(original);
  ASSERT_FALSE(bytes.empty());
  const int size = static_cast<int>(bytes.size());
  std::set<int> cuts = {0, 1, 7, 8, 9, size / 2, size - 8, size - 2, size - 1};
  for (int cut : cuts) {
    if (cut < 0 || cut >= size) continue;
    SCOPED_TRACE("decoding the first " + std::to_string(cut) + " of " + std::to_string(size) +
                 " bytes");
    // A copy of exactly `cut` bytes, so reading past it would be a heap
    // overflow that the sanitizer build reports.
    std::vector<uint8_t> truncated(bytes.begin(), bytes.begin() + cut);
    T decoded;
    EXPECT_LT(decoded.decode(truncated.data(), 0, cut), 0);
  }
  // Encoding into a buffer one byte too small fails too.
  std::vector<uint8_t> small(static_cast<size_t>(size - 1));
  EXPECT_LT(original.encode(small.data(), 0, size - 1), 0);
}

TYPED_TEST(MessageRoundTrip, CorruptedFingerprintFailsToDecode) {
  using T = TypeParam;
  std::vector<uint8_t> bytes = tt::encodeToBytes(tt::filled<T>(2));
  ASSERT_FALSE(bytes.empty());
  bytes[3] ^= 0x10;
  T decoded;
  EXPECT_LT(decoded.decode(bytes.data(), 0, static_cast<int>(bytes.size())), 0);
}

// ---- across types -----------------------------------------------------------------

TEST(MessageTypes, FingerprintsAndNamesAreDistinct) {
  std::map<int64_t, std::string> by_hash;
  std::set<std::string> names;
  tt::forEachType(tt::AllTypes{}, [&](auto tag) {
    using T = typename decltype(tag)::type;
    const std::string name = T::getTypeName();
    EXPECT_TRUE(names.insert(name).second) << "duplicate type " << name;
    const auto [it, inserted] = by_hash.emplace(T::getHash(), name);
    EXPECT_TRUE(inserted) << name << " has the same fingerprint as " << it->second;
    EXPECT_NE(T::getHash(), 0) << name;
  });
  EXPECT_EQ(by_hash.size(), 23u);
}

TEST(MessageTypes, DecodingAsAnotherTypeFails) {
  // Every type's bytes, decoded as every other type: the fingerprint check
  // must reject it.
  tt::forEachType(tt::AllTypes{}, [&](auto src_tag) {
    using Src = typename decltype(src_tag)::type;
    const std::vector<uint8_t> bytes = tt::encodeToBytes(tt::filled<Src>(3));
    tt::forEachType(tt::AllTypes{}, [&](auto dst_tag) {
      using Dst = typename decltype(dst_tag)::type;
      if constexpr (!std::is_same_v<Src, Dst>) {
        Dst decoded;
        EXPECT_LT(decoded.decode(bytes.data(), 0, static_cast<int>(bytes.size())), 0)
            << Src::getTypeName() << " decoded as " << Dst::getTypeName();
      }
    });
  });
}

// The package and struct declared in every .lcm file of lcmtypes/.
std::set<std::string> lcmFileTypes() {
  std::set<std::string> types;
  const std::regex package_re(R"(\bpackage\s+([A-Za-z_][A-Za-z0-9_]*)\s*;)");
  const std::regex struct_re(R"(\bstruct\s+([A-Za-z_][A-Za-z0-9_]*))");
  for (const auto& entry : fs::directory_iterator(fs::path(VSLAM_SOURCE_DIR) / "lcmtypes")) {
    if (entry.path().extension() != ".lcm") continue;
    std::ifstream in(entry.path());
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    // Drop // comments, which mention struct names in prose.
    text = std::regex_replace(text, std::regex("//[^\n]*"), "");
    std::smatch pkg, st;
    if (!std::regex_search(text, pkg, package_re) || !std::regex_search(text, st, struct_re)) {
      ADD_FAILURE() << entry.path() << ": no package or struct declaration";
      continue;
    }
    types.insert(pkg[1].str() + "." + st[1].str());
  }
  return types;
}

TEST(MessageTypes, EveryLcmFileIsCoveredByTheseTests) {
  std::set<std::string> tested;
  tt::forEachType(tt::AllTypes{}, [&](auto tag) {
    using T = typename decltype(tag)::type;
    tested.insert(std::string("vslam.") + T::getTypeName());
  });
  const std::set<std::string> declared = lcmFileTypes();
  EXPECT_EQ(declared, tested)
      << "lcmtypes/*.lcm and VSLAM_TRANSPORT_ALL_TYPES (tests/transport/message_fill.hpp) differ: "
         "add a fill() and the type to the list for every new message";
}

// ---- the Java jar -------------------------------------------------------------------

struct ZipEntry {
  std::string name;
  uint32_t uncompressed_size = 0;
};

uint16_t le16(const std::vector<uint8_t>& b, size_t at) {
  return static_cast<uint16_t>(b[at] | (b[at + 1] << 8));
}
uint32_t le32(const std::vector<uint8_t>& b, size_t at) {
  return static_cast<uint32_t>(b[at]) | (static_cast<uint32_t>(b[at + 1]) << 8) |
         (static_cast<uint32_t>(b[at + 2]) << 16) | (static_cast<uint32_t>(b[at + 3]) << 24);
}

// Lists a zip (jar) from its central directory; `error` is set when malformed.
std::vector<ZipEntry> listZip(const std::string& path, std::string* error) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<uint8_t> b((std::istreambuf_iterator<char>(in)),
                               std::istreambuf_iterator<char>());
  std::vector<ZipEntry> entries;
  if (b.size() < 22) {
    *error = "file too short for a zip (" + std::to_string(b.size()) + " bytes)";
    return entries;
  }
  // End of central directory: signature PK\5\6, within the last 64 KiB + 22 bytes.
  size_t eocd = std::string::npos;
  const size_t lowest = b.size() > 22 + 65535 ? b.size() - 22 - 65535 : 0;
  for (size_t i = b.size() - 22 + 1; i-- > lowest;) {
    if (le32(b, i) == 0x06054b50u) {
      eocd = i;
      break;
    }
  }
  if (eocd == std::string::npos) {
    *error = "no end-of-central-directory record";
    return entries;
  }
  const uint16_t count = le16(b, eocd + 10);
  size_t at = le32(b, eocd + 16);
  for (uint16_t i = 0; i < count; ++i) {
    if (at + 46 > b.size() || le32(b, at) != 0x02014b50u) {
      *error = "central directory entry " + std::to_string(i) + " is malformed";
      return entries;
    }
    const uint16_t name_len = le16(b, at + 28);
    const uint16_t extra_len = le16(b, at + 30);
    const uint16_t comment_len = le16(b, at + 32);
    const uint32_t local = le32(b, at + 42);
    if (at + 46 + name_len > b.size() || local + 4 > b.size() || le32(b, local) != 0x04034b50u) {
      *error = "central directory entry " + std::to_string(i) + " points nowhere";
      return entries;
    }
    entries.push_back(
        {std::string(reinterpret_cast<const char*>(&b[at + 46]), name_len), le32(b, at + 24)});
    at += 46 + name_len + extra_len + comment_len;
  }
  return entries;
}

TEST(MessageTypes, JavaJarHoldsAClassForEveryLcmFile) {
  const std::string jar = VSLAM_TYPES_JAR;
  ASSERT_TRUE(fs::is_regular_file(jar)) << jar << " was not built (target vslam_lcmtypes_java)";
  std::string error;
  const std::vector<ZipEntry> entries = listZip(jar, &error);
  ASSERT_TRUE(error.empty()) << jar << ": " << error;
  std::map<std::string, uint32_t> sizes;
  for (const auto& e : entries) sizes[e.name] = e.uncompressed_size;

  const std::set<std::string> types = lcmFileTypes();
  ASSERT_FALSE(types.empty());
  for (const std::string& type : types) {
    std::string cls = type;
    std::replace(cls.begin(), cls.end(), '.', '/');
    cls += ".class";
    const auto it = sizes.find(cls);
    ASSERT_NE(it, sizes.end()) << jar << " lacks " << cls;
    EXPECT_GT(it->second, 0u) << cls << " is empty";
  }
}

}  // namespace
