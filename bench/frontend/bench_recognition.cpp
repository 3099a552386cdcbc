// Recognition of one frame against 10 to 10,000 landmarks (issue 5, item 3):
// query time, recall of the exact per-landmark ratio-test matches, and memory
// per landmark. Two kinds of data:
//  - BM_RecognizeSynthetic: SIFT-like descriptors (tests/support), landmarks
//    of 30-70 points, one in ten sharing half its points with the next (as
//    landmarks created near each other do); each query frame has 600
//    features: ~70% of one landmark's points, ~40% of a second's, ~25% of a
//    third's (near the 10-match threshold), the rest unrelated.
//  - BM_RecognizeRendered: real SIFT of rendered apartment views (the
//    simulator's renderer and camera, 320x240): each landmark is 30-70
//    features of a view at a random pose along the tour route (random
//    heading); each query is the full frame rendered 10 cm / 8 degrees from
//    a landmark's view.
// Counters: recall_% = matches found / matches of the exact search (every
// landmark verified, same ratio test and min_matches), over all queries;
// lm_recall_% the same for recognized landmarks; precision_% = found matches
// that the exact search also finds; kB_per_lm = LandmarkIndex::memoryBytes()
// / landmarks; heap_kB_per_lm = the process heap (mallinfo2) grown by
// building the index / landmarks; build_s = adding all landmarks (vocabulary
// trainings included). One core.
//
//   build-rec/bin/bench_recognition [--benchmark_filter=Synthetic]
#include <benchmark/benchmark.h>
#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <opencv2/calib3d.hpp>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "config/robot_config.hpp"
#include "frontend/features.hpp"
#include "frontend/landmark_creation.hpp"
#include "frontend/landmark_index.hpp"
#include "support/synthetic_descriptors.hpp"
#include "world/renderer.hpp"
#include "world/world.hpp"

namespace {

namespace fs = std::filesystem;
using namespace vslam;
using namespace vslam::frontend;

const fs::path kSource = VSLAM_SOURCE_DIR;
constexpr int kQueries = 8;

// Which matches of a recognition are genuine (the same physical point).
using GenuineFn = std::function<std::vector<bool>(size_t query, const Recognition&)>;

struct Dataset {
  std::vector<LandmarkModel> landmarks;
  std::vector<Features> queries;
  GenuineFn genuine;
};

Features frameOf(const cv::Mat& descriptors) {
  Features f;
  f.descriptors = descriptors;
  f.keypoints.resize(static_cast<size_t>(descriptors.rows));
  for (int i = 0; i < descriptors.rows; ++i) f.normalized.emplace_back(0.001 * i, 0.0);
  return f;
}

LandmarkModel modelOf(int64_t id, const cv::Mat& descriptors) {
  LandmarkModel lm;
  lm.id = id;
  lm.descriptors = descriptors;
  for (int i = 0; i < descriptors.rows; ++i) lm.points_robot.emplace_back(1.0, 0.01 * i, 0.0);
  return lm;
}

// ---- synthetic ----

Dataset syntheticDataset(int num_landmarks) {
  test::SiftLikeGenerator gen(7);
  std::mt19937& rng = gen.rng();
  // The landmarks the queries see: (landmark, fraction of its points seen).
  std::map<int, std::vector<std::pair<int, double>>> seen_by;  // landmark -> (query, fraction)
  std::uniform_int_distribution<int> any(0, num_landmarks - 1);
  for (int q = 0; q < kQueries; ++q) {
    const double fractions[] = {0.7, 0.4, 0.25};
    std::set<int> used;
    for (double fr : fractions) {
      int l = any(rng);
      while (used.count(l)) l = any(rng);
      used.insert(l);
      seen_by[l].emplace_back(q, fr);
    }
  }
  Dataset d;
  std::vector<cv::Mat> query_rows(kQueries);
  auto physical =
      std::make_shared<std::vector<std::vector<int>>>();  // (landmark, point) -> point id
  auto query_physical =
      std::make_shared<std::vector<std::vector<int>>>(kQueries);  // -1: distractor
  int next_physical = 0;
  std::vector<test::SiftLikeGenerator::Patch> shared;  // half of the previous landmark's patches
  std::vector<int> shared_ids;
  std::uniform_int_distribution<int> points(30, 70);
  for (int l = 0; l < num_landmarks; ++l) {
    const int n = points(rng);
    std::vector<test::SiftLikeGenerator::Patch> patches;
    std::vector<int> ids = shared_ids;
    for (const auto& p : shared) patches.push_back(gen.observe(p));
    shared.clear();
    shared_ids.clear();
    while (static_cast<int>(patches.size()) < n) {
      patches.push_back(gen.patch());
      ids.push_back(next_physical++);
    }
    cv::Mat desc(0, 128, CV_32F);
    for (const auto& p : patches) desc.push_back(test::SiftLikeGenerator::describe(p));
    if (l % 10 == 0) {
      shared.assign(patches.begin(), patches.begin() + n / 2);
      shared_ids.assign(ids.begin(), ids.begin() + n / 2);
    }
    const auto it = seen_by.find(l);
    if (it != seen_by.end()) {
      for (const auto& [q, fraction] : it->second) {
        std::vector<size_t> order(patches.size());
        for (size_t i = 0; i < order.size(); ++i) order[i] = i;
        std::shuffle(order.begin(), order.end(), rng);
        const size_t k = static_cast<size_t>(std::lround(fraction * static_cast<double>(n)));
        for (size_t i = 0; i < k; ++i) {
          query_rows[static_cast<size_t>(q)].push_back(
              test::SiftLikeGenerator::describe(gen.observe(patches[order[i]])));
          (*query_physical)[static_cast<size_t>(q)].push_back(ids[order[i]]);
        }
      }
    }
    d.landmarks.push_back(modelOf(l, desc));
    physical->push_back(std::move(ids));
  }
  for (size_t q = 0; q < query_rows.size(); ++q) {
    cv::Mat& rows = query_rows[q];
    rows.push_back(gen.descriptors(600 - rows.rows));
    std::vector<int>& ids = (*query_physical)[q];
    ids.resize(static_cast<size_t>(rows.rows), -1);
    std::vector<int> order(static_cast<size_t>(rows.rows));
    for (int i = 0; i < rows.rows; ++i) order[static_cast<size_t>(i)] = i;
    std::shuffle(order.begin(), order.end(), rng);
    cv::Mat shuffled(rows.rows, 128, CV_32F);
    std::vector<int> shuffled_ids(ids.size());
    for (int i = 0; i < rows.rows; ++i) {
      rows.row(order[static_cast<size_t>(i)]).copyTo(shuffled.row(i));
      shuffled_ids[static_cast<size_t>(i)] =
          ids[static_cast<size_t>(order[static_cast<size_t>(i)])];
    }
    ids = shuffled_ids;
    d.queries.push_back(frameOf(shuffled));
  }
  d.genuine = [physical, query_physical](size_t q, const Recognition& r) {
    std::vector<bool> g;
    for (size_t i = 0; i < r.frame_features.size(); ++i) {
      const int feature_id = (*query_physical)[q][static_cast<size_t>(r.frame_features[i])];
      g.push_back(feature_id >= 0 && feature_id ==
                                         (*physical)[static_cast<size_t>(r.landmark_id)]
                                                    [static_cast<size_t>(r.landmark_points[i])]);
    }
    return g;
  };
  return d;
}

// ---- rendered ----

const world::World& apartment() {
  static const world::World w = world::World::loadFile(kSource / "config/worlds/apartment.yaml");
  return w;
}

Eigen::Isometry3d robotTCamera() {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = config::robotRotationCamera(0, 0, 0);
  t.translation() = Eigen::Vector3d(0.1, 0, 0.3);
  return t;
}

class RenderedViews {
 public:
  RenderedViews()
      : intrinsics_(config::readOpenCvCalibration(kSource / "config/calib/sim_320x240.yml")),
        renderer_(apartment(), world::CameraModel{intrinsics_.width, intrinsics_.height,
                                                  intrinsics_.fx, intrinsics_.fy, intrinsics_.cx,
                                                  intrinsics_.cy, intrinsics_.distortion}),
        extractor_(intrinsics_),
        rng_(11) {}

  // Landmarks [0, n): cached across benchmarks (rendering ~17 ms each).
  const std::vector<LandmarkModel>& landmarks(int n) {
    while (static_cast<int>(landmarks_.size()) < n) {
      const Pose2 pose = randomPose();
      Features f;
      view(pose, &f);
      if (f.size() < 30) continue;
      std::vector<int> order(f.size());
      for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
      std::shuffle(order.begin(), order.end(), rng_);
      const int k = std::min<int>(static_cast<int>(f.size()),
                                  std::uniform_int_distribution<int>(30, 70)(rng_));
      cv::Mat desc(0, 128, CV_32F);
      LandmarkModel lm;
      lm.id = static_cast<int64_t>(landmarks_.size());
      for (int i = 0; i < k; ++i) {
        const size_t j = static_cast<size_t>(order[static_cast<size_t>(i)]);
        desc.push_back(f.descriptors.row(static_cast<int>(j)));
        // Not 3-D: the point's normalized image coordinates in the landmark's
        // view, for the two-view check of genuine matches.
        lm.points_robot.emplace_back(f.normalized[j].x(), f.normalized[j].y(), 1.0);
      }
      lm.descriptors = desc;
      landmarks_.push_back(std::move(lm));
      poses_.push_back(pose);
    }
    return landmarks_;
  }

  // Query frames near landmarks of [0, n).
  std::vector<Features> queries(int n) {
    std::mt19937 rng(static_cast<uint32_t>(n));
    std::normal_distribution<double> g(0, 1);
    std::vector<Features> out;
    for (int q = 0; q < kQueries; ++q) {
      const Pose2& p =
          poses_[std::uniform_int_distribution<size_t>(0, static_cast<size_t>(n) - 1)(rng)];
      Features f;
      view(p.compose(Pose2{0.1 * g(rng), 0.1 * g(rng), 0.14 * g(rng)}), &f);
      out.push_back(f);
    }
    return out;
  }

 private:
  Pose2 randomPose() {
    const auto& wp = apartment().routes.at(0).waypoints;
    std::uniform_real_distribution<double> u(0, 1);
    const size_t i = std::uniform_int_distribution<size_t>(0, wp.size() - 2)(rng_);
    const Eigen::Vector2d p = wp[i] + u(rng_) * (wp[i + 1] - wp[i]);
    return {p.x(), p.y(), 2 * M_PI * u(rng_)};
  }
  void view(const Pose2& pose, Features* f) {
    renderer_.render(isometryFromPose2(pose) * robotTCamera(), {}, {}, false, image_);
    extractor_.extract(image_, f);
  }

  config::CameraIntrinsics intrinsics_;
  world::Renderer renderer_;
  FeatureExtractor extractor_;
  std::mt19937 rng_;
  cv::Mat image_;
  std::vector<LandmarkModel> landmarks_;
  std::vector<Pose2> poses_;
};

// Genuine rendered matches: inliers of an essential matrix (RANSAC, 1.5 px)
// between the landmark's view and the frame, when there are min_matches of them.
std::vector<bool> twoViewInliers(const Recognition& r, double focal_px, int min_matches) {
  std::vector<bool> g(r.frame_features.size(), false);
  if (r.frame_features.size() < 5) return g;
  std::vector<cv::Point2d> a, b;
  for (size_t i = 0; i < r.frame_features.size(); ++i) {
    a.emplace_back(r.points_robot[i].x(), r.points_robot[i].y());
    b.emplace_back(r.observations[i].x(), r.observations[i].y());
  }
  cv::Mat mask;
  const cv::Mat e =
      cv::findEssentialMat(a, b, 1.0, cv::Point2d(0, 0), cv::RANSAC, 0.999, 1.5 / focal_px, mask);
  if (e.empty() || cv::countNonZero(mask) < min_matches) return g;
  for (size_t i = 0; i < g.size(); ++i) g[i] = mask.at<uchar>(static_cast<int>(i)) != 0;
  return g;
}

RenderedViews& renderedViews() {
  static RenderedViews v;
  return v;
}

// ---- the benchmark ----

size_t heapInUse() {
  const struct mallinfo2 m = mallinfo2();
  return m.uordblks + m.hblkhd;
}

using MatchSet = std::set<std::tuple<int64_t, int, int>>;  // (landmark, feature, point)

MatchSet matchSet(const std::vector<Recognition>& rs) {
  MatchSet s;
  for (const Recognition& r : rs) {
    for (size_t i = 0; i < r.frame_features.size(); ++i)
      s.emplace(r.landmark_id, r.frame_features[i], r.landmark_points[i]);
  }
  return s;
}

void runRecognition(benchmark::State& state, const Dataset& d) {
  const std::vector<LandmarkModel>& landmarks = d.landmarks;
  const std::vector<Features>& queries = d.queries;
  const RecognitionParams params;
  const size_t heap0 = heapInUse();
  const auto t0 = std::chrono::steady_clock::now();
  LandmarkIndex index(params);
  for (const LandmarkModel& lm : landmarks) index.add(lm);
  const double build_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const size_t heap1 = heapInUse();

  // Exact reference and the approximate result of every query (outside the timing).
  size_t exact = 0, found = 0, common = 0, exact_lm = 0, found_lm = 0, common_lm = 0,
         candidates = 0, features = 0, genuine = 0, genuine_found = 0, genuine_lm = 0,
         genuine_lm_found = 0;
  for (size_t qi = 0; qi < queries.size(); ++qi) {
    const Features& q = queries[qi];
    const std::vector<Recognition> exact_r = index.recognizeExact(q);
    const MatchSet e = matchSet(exact_r);
    RecognitionStats st;
    const MatchSet a = matchSet(index.recognize(q, &st));
    for (const Recognition& r : exact_r) {
      const std::vector<bool> g = d.genuine(qi, r);
      const auto n_genuine = static_cast<int>(std::count(g.begin(), g.end(), true));
      if (n_genuine < RecognitionParams{}.min_matches) continue;  // a chance recognition
      ++genuine_lm;
      bool lm_found = false;
      for (size_t i = 0; i < g.size(); ++i) {
        if (!g[i]) continue;
        ++genuine;
        const bool f = a.count({r.landmark_id, r.frame_features[i], r.landmark_points[i]}) > 0;
        genuine_found += f;
        lm_found = lm_found || f;
      }
      genuine_lm_found += lm_found;
    }
    std::set<int64_t> el, al;
    for (const auto& m : e) el.insert(std::get<0>(m));
    for (const auto& m : a) al.insert(std::get<0>(m));
    exact += e.size();
    found += a.size();
    for (const auto& m : a) common += e.count(m);
    exact_lm += el.size();
    found_lm += al.size();
    for (int64_t l : al) common_lm += el.count(l);
    candidates += static_cast<size_t>(st.candidates);
    features += q.size();
  }

  size_t i = 0;
  for (auto _ : state) {
    benchmark::DoNotOptimize(index.recognize(queries[i++ % queries.size()]));
  }
  const double nq = static_cast<double>(queries.size());
  const double nl = static_cast<double>(landmarks.size());
  auto percent = [](size_t a, size_t b) {
    return b ? 100.0 * static_cast<double>(a) / static_cast<double>(b) : 100.0;
  };
  state.counters["recall_%"] = percent(genuine_found, genuine);
  state.counters["lm_recall_%"] = percent(genuine_lm_found, genuine_lm);
  state.counters["genuine_matches"] = static_cast<double>(genuine) / nq;
  state.counters["genuine_lms"] = static_cast<double>(genuine_lm) / nq;
  state.counters["all_recall_%"] = percent(common, exact);
  state.counters["all_lm_recall_%"] = percent(common_lm, exact_lm);
  state.counters["precision_%"] = percent(common, found);
  state.counters["exact_matches"] = static_cast<double>(exact) / nq;
  state.counters["exact_lms"] = static_cast<double>(exact_lm) / nq;
  state.counters["candidates"] = static_cast<double>(candidates) / nq;
  state.counters["features"] = static_cast<double>(features) / nq;
  state.counters["kB_per_lm"] = static_cast<double>(index.memoryBytes()) / nl / 1000.0;
  state.counters["heap_kB_per_lm"] =
      (static_cast<double>(heap1) - static_cast<double>(heap0)) / nl / 1000.0;
  state.counters["words"] = index.vocabulary().numWords();
  state.counters["build_s"] = build_s;
}

void BM_RecognizeSynthetic(benchmark::State& state) {
  cv::setNumThreads(1);
  runRecognition(state, syntheticDataset(static_cast<int>(state.range(0))));
}
BENCHMARK(BM_RecognizeSynthetic)
    ->ArgName("landmarks")
    ->Arg(10)
    ->Arg(100)
    ->Arg(1000)
    ->Arg(10000)
    ->Unit(benchmark::kMillisecond);

void BM_RecognizeRendered(benchmark::State& state) {
  cv::setNumThreads(1);
  const int n = static_cast<int>(state.range(0));
  RenderedViews& v = renderedViews();
  Dataset d;
  d.landmarks.assign(v.landmarks(n).begin(), v.landmarks(n).begin() + n);
  d.queries = v.queries(n);
  d.genuine = [](size_t, const Recognition& r) {
    return twoViewInliers(r, 277.13, RecognitionParams{}.min_matches);
  };
  runRecognition(state, d);
}
BENCHMARK(BM_RecognizeRendered)
    ->ArgName("landmarks")
    ->Arg(10)
    ->Arg(100)
    ->Arg(1000)
    ->Unit(benchmark::kMillisecond);

}  // namespace
