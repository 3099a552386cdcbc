#pragma once
// Deterministic, non-trivial content for every vslam LCM type, shared by the
// round-trip test, the multicast tests and the transport peer process.
//
// fill(msg, seed) sets every field (array sizes consistent with their size
// fields, nested types filled); different seeds give different values and
// different array lengths, so a decoder that skips a field or mixes up sizes
// shows up as a byte difference.

#include <cstdint>
#include <string>
#include <vector>
#include <vslam/appearance_event_t.hpp>
#include <vslam/appearance_hypotheses_t.hpp>
#include <vslam/appearance_hypothesis_t.hpp>
#include <vslam/appearance_link_t.hpp>
#include <vslam/appearance_map_t.hpp>
#include <vslam/appearance_state_t.hpp>
#include <vslam/camera_calibration_t.hpp>
#include <vslam/ground_truth_pose_t.hpp>
#include <vslam/health_metric_t.hpp>
#include <vslam/health_t.hpp>
#include <vslam/image_t.hpp>
#include <vslam/landmark_pose_t.hpp>
#include <vslam/landmark_request_t.hpp>
#include <vslam/landmark_summary_t.hpp>
#include <vslam/landmark_t.hpp>
#include <vslam/landmark_update_t.hpp>
#include <vslam/map_t.hpp>
#include <vslam/odometry_t.hpp>
#include <vslam/particle_set_t.hpp>
#include <vslam/particle_t.hpp>
#include <vslam/pose_estimate_t.hpp>
#include <vslam/view_jump_t.hpp>
#include <vslam/visual_measurement_t.hpp>

namespace vslam::transport_test {

// Every generated vslam type; keep in sync with lcmtypes/ (the round-trip test
// checks that this list and the .lcm files name the same types).
#define VSLAM_TRANSPORT_ALL_TYPES                                                                  \
  vslam::image_t, vslam::camera_calibration_t, vslam::odometry_t, vslam::visual_measurement_t,     \
      vslam::landmark_t, vslam::landmark_update_t, vslam::landmark_summary_t,                      \
      vslam::landmark_request_t, vslam::pose_estimate_t, vslam::landmark_pose_t, vslam::map_t,     \
      vslam::particle_t, vslam::particle_set_t, vslam::appearance_state_t,                         \
      vslam::appearance_link_t, vslam::appearance_hypothesis_t, vslam::appearance_hypotheses_t,    \
      vslam::appearance_map_t, vslam::appearance_event_t, vslam::health_metric_t, vslam::health_t, \
      vslam::ground_truth_pose_t, vslam::view_jump_t

template <class... Ts>
struct TypeList {};
using AllTypes = TypeList<VSLAM_TRANSPORT_ALL_TYPES>;

template <class T>
struct Tag {
  using type = T;
};
// Calls f(Tag<T>{}) for every type of the list, in order.
template <class F, class... Ts>
void forEachType(TypeList<Ts...>, F&& f) {
  (f(Tag<Ts>{}), ...);
}

// ---- value generators ------------------------------------------------------

inline double dv(int seed, int k) { return (seed + 1) * 1.5 + k * 0.25 - 7.0 / (k + 3); }
inline float fv(int seed, int k) { return static_cast<float>(dv(seed, k) * 0.5); }
inline int64_t tv(int seed, int k) { return 1700000000000000LL + seed * 1000003LL + k * 17; }
inline std::string sv(const char* base, int seed) {
  return std::string(base) + "_" + std::to_string(seed);
}
inline uint8_t bv(int seed, int k) { return static_cast<uint8_t>(k * 31 + seed * 7 + 3); }
// An array length that depends on the seed, never 0.
inline int nv(int seed, int base) { return base + seed % 4; }

// ---- one fill per type -------------------------------------------------------

inline void fill(vslam::image_t& m, int s) {
  m.utime = tv(s, 0);
  m.seq = 1000 + s;
  m.camera = sv("forward", s);
  m.width = 16 + s % 3;
  m.height = 9 + s % 2;
  m.row_stride = m.width + 3;
  m.encoding = vslam::image_t::ENCODING_GRAY8;
  m.exposure = 0.75f + 0.125f * static_cast<float>(s);
  m.data_size = m.row_stride * m.height;
  m.data.resize(static_cast<size_t>(m.data_size));
  for (int i = 0; i < m.data_size; ++i) m.data[static_cast<size_t>(i)] = bv(s, i);
}

inline void fill(vslam::camera_calibration_t& m, int s) {
  m.utime = tv(s, 1);
  m.camera = sv("backward", s);
  m.image_channel = sv("CAM_BACKWARD_IMAGE", s);
  m.width = 320 + s;
  m.height = 240 + s;
  m.frame_rate = 10.0 + s;
  m.fx = 250.5 + s;
  m.fy = 251.25 + s;
  m.cx = 160.125 + s;
  m.cy = 120.0625 + s;
  m.num_distortion = static_cast<int8_t>(s % 2 == 0 ? 5 : 8);
  m.distortion.resize(static_cast<size_t>(m.num_distortion));
  for (int i = 0; i < m.num_distortion; ++i) m.distortion[static_cast<size_t>(i)] = dv(s, i) * 1e-3;
  for (int i = 0; i < 3; ++i) m.robot_t_camera[i] = dv(s, 10 + i);
  for (int i = 0; i < 4; ++i) m.robot_q_camera[i] = dv(s, 20 + i);
}

inline void fill(vslam::odometry_t& m, int s) {
  m.utime = tv(s, 2);
  m.seq = 2000 + s;
  m.x = dv(s, 0);
  m.y = -dv(s, 1);
  m.theta = 0.125 * s - 1.0;
  m.distance = dv(s, 3) + 10;
  m.rotation = dv(s, 4) + 2;
  m.v = 0.5 + s * 0.01;
  m.omega = -0.25 + s * 0.02;
}

inline void fill(vslam::visual_measurement_t& m, int s) {
  m.utime = tv(s, 3);
  m.seq = 3000 + s;
  m.camera = sv("forward", s);
  m.image_seq = 3100 + s;
  m.landmark_id = 3200 + s;
  m.dx = dv(s, 0);
  m.dy = dv(s, 1);
  m.dtheta = -0.5 + 0.01 * s;
  m.proj_err_rms = 0.75 + s;
  m.num_points = 40 + s;
  m.slope = 2.5 + s;
  m.status = vslam::visual_measurement_t::STATUS_REJECTED_SLOPE;
}

inline void fill(vslam::landmark_t& m, int s) {
  m.landmark_id = 4000 + s;
  m.proposal_id = 4100 + s;
  m.version = 3 + s;
  m.camera = sv("forward", s);
  m.created_utime = tv(s, 4);
  m.created_odom_x = dv(s, 0);
  m.created_odom_y = dv(s, 1);
  m.created_odom_theta = 0.3 + 0.01 * s;
  m.num_points = nv(s, 5);
  m.descriptor_size = static_cast<int16_t>(128);
  const auto n = static_cast<size_t>(m.num_points);
  m.points.assign(n, std::vector<float>(3));
  m.keypoints.assign(n, std::vector<float>(2));
  m.scales.resize(n);
  m.orientations.resize(n);
  m.descriptors.assign(n, std::vector<uint8_t>(static_cast<size_t>(m.descriptor_size)));
  for (size_t i = 0; i < n; ++i) {
    const int k = static_cast<int>(i);
    for (int j = 0; j < 3; ++j) m.points[i][static_cast<size_t>(j)] = fv(s, 10 * k + j);
    for (int j = 0; j < 2; ++j)
      m.keypoints[i][static_cast<size_t>(j)] = fv(s, 10 * k + 5 + j) * 0.01f;
    m.scales[i] = 1.5f + static_cast<float>(k);
    m.orientations[i] = -3.0f + 0.25f * static_cast<float>(k);
    for (size_t j = 0; j < m.descriptors[i].size(); ++j) {
      m.descriptors[i][j] = bv(s, 128 * k + static_cast<int>(j));
    }
  }
  m.num_recognitions = 7 + s;
  m.num_accepted = 5 + s;
  m.num_rejected = 2 + s;
  m.last_seen_utime = tv(s, 40);
}

inline void fill(vslam::landmark_update_t& m, int s) {
  m.utime = tv(s, 5);
  m.database_id = sv("db", s);
  m.revision = 5000 + s;
  m.op = vslam::landmark_update_t::OP_SNAPSHOT;
  m.requester = sv("frontend_forward", s);
  fill(m.landmark, s + 11);
}

inline void fill(vslam::landmark_summary_t& m, int s) {
  m.utime = tv(s, 6);
  m.database_id = sv("db", s);
  m.revision = 6000 + s;
  m.num_stored = 7000 + s;
  m.num_landmarks = nv(s, 6);
  m.landmark_ids.resize(static_cast<size_t>(m.num_landmarks));
  m.versions.resize(static_cast<size_t>(m.num_landmarks));
  for (int i = 0; i < m.num_landmarks; ++i) {
    m.landmark_ids[static_cast<size_t>(i)] = 100 * s + 3 * i;
    m.versions[static_cast<size_t>(i)] = 1 + i + s;
  }
}

inline void fill(vslam::landmark_request_t& m, int s) {
  m.utime = tv(s, 7);
  m.requester = sv("backend", s);
  m.database_id = sv("db", s);
  m.since_revision = 7000 + s;
  m.num_ids = nv(s, 3);
  m.landmark_ids.resize(static_cast<size_t>(m.num_ids));
  for (int i = 0; i < m.num_ids; ++i) m.landmark_ids[static_cast<size_t>(i)] = 7100 + 11 * i + s;
}

inline void fill(vslam::pose_estimate_t& m, int s) {
  m.utime = tv(s, 8);
  m.seq = 8000 + s;
  m.estimator = sv("backend", s);
  m.x = dv(s, 0);
  m.y = dv(s, 1);
  m.theta = 0.5 - 0.01 * s;
  for (int i = 0; i < 9; ++i) m.covariance[i] = dv(s, 10 + i) * 1e-2;
  m.odom_x = dv(s, 2);
  m.odom_y = dv(s, 3);
  m.odom_theta = -0.25 + 0.01 * s;
  m.num_particles = 1000 + s;
  m.effective_sample_size = 512.5 + s;
  m.kidnapped = static_cast<int8_t>(s % 2 == 0);
}

inline void fill(vslam::landmark_pose_t& m, int s) {
  m.landmark_id = 9000 + s;
  m.x = dv(s, 0);
  m.y = dv(s, 1);
  m.theta = 1.0 - 0.01 * s;
  for (int i = 0; i < 9; ++i) m.covariance[i] = dv(s, 20 + i) * 1e-3;
  m.num_observations = 12 + s;
}

inline void fill(vslam::map_t& m, int s) {
  m.utime = tv(s, 9);
  m.seq = 9100 + s;
  m.estimator = sv("backend", s);
  m.database_id = sv("db", s);
  m.num_landmarks = nv(s, 4);
  m.landmarks.resize(static_cast<size_t>(m.num_landmarks));
  for (int i = 0; i < m.num_landmarks; ++i) fill(m.landmarks[static_cast<size_t>(i)], s * 10 + i);
}

inline void fill(vslam::particle_t& m, int s) {
  m.x = dv(s, 0);
  m.y = dv(s, 1);
  m.theta = 0.75 - 0.01 * s;
  m.weight = 1.0 / (s + 3);
  m.kind = vslam::particle_t::KIND_DUAL;
}

inline void fill(vslam::particle_set_t& m, int s) {
  m.utime = tv(s, 10);
  m.seq = 10100 + s;
  m.estimator = sv("backend", s);
  m.effective_sample_size = 33.25 + s;
  m.dual_ratio = 0.125;
  m.num_particles = nv(s, 20);
  m.particles.resize(static_cast<size_t>(m.num_particles));
  for (int i = 0; i < m.num_particles; ++i) {
    fill(m.particles[static_cast<size_t>(i)], s * 100 + i);
    m.particles[static_cast<size_t>(i)].kind = static_cast<int8_t>(i % 2);
  }
}

inline void fill(vslam::appearance_state_t& m, int s) {
  m.state_id = 11000 + s;
  m.utime = tv(s, 11);
  m.odom_x = dv(s, 0);
  m.odom_y = dv(s, 1);
  m.odom_theta = -1.0 + 0.01 * s;
  m.num_cameras = static_cast<int16_t>(2 + s % 2);
  m.num_bins = static_cast<int16_t>(nv(s, 8));
  m.cameras.resize(static_cast<size_t>(m.num_cameras));
  m.histograms.assign(static_cast<size_t>(m.num_cameras),
                      std::vector<float>(static_cast<size_t>(m.num_bins)));
  for (int c = 0; c < m.num_cameras; ++c) {
    m.cameras[static_cast<size_t>(c)] = sv(c == 0 ? "forward" : "backward", s + c);
    for (int b = 0; b < m.num_bins; ++b) {
      m.histograms[static_cast<size_t>(c)][static_cast<size_t>(b)] = fv(s, 50 * c + b) * 0.01f;
    }
  }
}

inline void fill(vslam::appearance_link_t& m, int s) {
  m.from_state = 12000 + s;
  m.to_state = 12001 + s;
  m.dx = dv(s, 0);
  m.dy = dv(s, 1);
  m.dtheta = 0.2 + 0.01 * s;
  m.sigma_translation = 0.03;
  m.sigma_rotation = 0.05 + 0.001 * s;
  m.sigma_translation_sqrt = 0.02;
  m.sigma_rotation_sqrt = 0.03 + 0.001 * s;
}

inline void fill(vslam::appearance_hypothesis_t& m, int s) {
  m.hypothesis_id = 13000 + s;
  m.parent_id = 12999 + s;
  m.state_id = 13100 + s;
  m.is_new_state = static_cast<int8_t>(s % 2);
  m.belief = 1.0 / (s + 2);
  m.path_length = 4 + s;
}

inline void fill(vslam::appearance_hypotheses_t& m, int s) {
  m.utime = tv(s, 14);
  m.step = 14000 + s;
  m.best_state_id = 14100 + s;
  m.best_belief = 0.625;
  m.step_seconds = 0.0125 * (s + 1);
  m.num_hypotheses = nv(s, 5);
  m.hypotheses.resize(static_cast<size_t>(m.num_hypotheses));
  for (int i = 0; i < m.num_hypotheses; ++i) fill(m.hypotheses[static_cast<size_t>(i)], s * 10 + i);
}

inline void fill(vslam::appearance_map_t& m, int s) {
  m.utime = tv(s, 15);
  m.seq = 15000 + s;
  m.num_states = nv(s, 3);
  m.states.resize(static_cast<size_t>(m.num_states));
  for (int i = 0; i < m.num_states; ++i) fill(m.states[static_cast<size_t>(i)], s * 10 + i);
  m.num_links = nv(s, 2);
  m.links.resize(static_cast<size_t>(m.num_links));
  for (int i = 0; i < m.num_links; ++i) fill(m.links[static_cast<size_t>(i)], s * 10 + i);
}

inline void fill(vslam::appearance_event_t& m, int s) {
  m.utime = tv(s, 16);
  m.step = 16000 + s;
  m.event = vslam::appearance_event_t::EVENT_RELOCALIZED;
  m.state_id = 16100 + s;
  m.previous_state_id = 16050 + s;
  m.belief = 0.875 - 0.001 * s;
}

inline void fill(vslam::health_metric_t& m, int s) {
  m.name = sv("frames_per_second", s);
  m.value = dv(s, 0);
  m.unit = s % 2 == 0 ? "Hz" : "ms";
}

inline void fill(vslam::health_t& m, int s) {
  m.utime = tv(s, 17);
  m.process = sv("vslam-frontend", s);
  m.instance = sv("frontend_forward", s);
  m.pid = 4242 + s;
  m.uptime = 12.5 + s;
  m.level = vslam::health_t::LEVEL_WARN;
  m.message = sv("camera stopped", s);
  m.cpu_seconds = 3.25 + s;
  m.rss_bytes = (64LL << 20) + s;
  m.messages_received = 17000 + s;
  m.messages_published = 17100 + s;
  m.messages_dropped = 17 + s;
  m.messages_malformed = 1 + s;
  m.handler_latency_ms = 4.5 + s;
  m.num_metrics = nv(s, 3);
  m.metrics.resize(static_cast<size_t>(m.num_metrics));
  for (int i = 0; i < m.num_metrics; ++i) fill(m.metrics[static_cast<size_t>(i)], s * 10 + i);
}

inline void fill(vslam::ground_truth_pose_t& m, int s) {
  m.utime = tv(s, 18);
  m.seq = 18000 + s;
  m.x = dv(s, 0);
  m.y = dv(s, 1);
  m.z = 0.0;
  m.theta = 2.5 - 0.01 * s;
}

inline void fill(vslam::view_jump_t& m, int s) {
  m.utime = tv(s, 19);
  m.previous_utime = tv(s, 19) - 100000;
  m.camera = sv("forward", s);
  m.matched_share = 0.01 * (s % 5);
  m.max_matched_share = 0.05;
  m.thumbnail_similarity = 0.1 * (s % 7);
  m.min_thumbnail_similarity = 0.5;
}

template <class T>
T filled(int seed) {
  T m;
  fill(m, seed);
  return m;
}

template <class T>
std::vector<uint8_t> encodeToBytes(const T& m) {
  std::vector<uint8_t> out(static_cast<size_t>(m.getEncodedSize()));
  const int n = m.encode(out.data(), 0, static_cast<int>(out.size()));
  if (n != static_cast<int>(out.size())) out.clear();  // callers check for the expected size
  return out;
}

}  // namespace vslam::transport_test
