#include "frontend/landmark_index.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>
#include <string>

#include "frontend/descriptor_distance.hpp"

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

namespace vslam::frontend {

namespace {
#if defined(__x86_64__) && defined(__GNUC__)
// squaredDistanceU8's arithmetic on 32 bytes at a time.
__attribute__((target("avx2"))) void squaredDistancesAvx2(const uint8_t* q, const uint8_t* points,
                                                          int n, uint32_t* out) {
  const __m256i zero = _mm256_setzero_si256();
  __m256i qv[kDescriptorBytes / 32];
  for (int k = 0; k < kDescriptorBytes / 32; ++k) {
    qv[k] = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(q + 32 * k));
  }
  for (int i = 0; i < n; ++i) {
    const uint8_t* b = points + static_cast<size_t>(i) * kDescriptorBytes;
    __m256i acc = _mm256_setzero_si256();
    for (int k = 0; k < kDescriptorBytes / 32; ++k) {
      const __m256i vb = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(b + 32 * k));
      const __m256i diff =
          _mm256_or_si256(_mm256_subs_epu8(qv[k], vb), _mm256_subs_epu8(vb, qv[k]));
      const __m256i lo = _mm256_unpacklo_epi8(diff, zero);
      const __m256i hi = _mm256_unpackhi_epi8(diff, zero);
      acc = _mm256_add_epi32(acc, _mm256_madd_epi16(lo, lo));
      acc = _mm256_add_epi32(acc, _mm256_madd_epi16(hi, hi));
    }
    __m128i sum = _mm_add_epi32(_mm256_castsi256_si128(acc), _mm256_extracti128_si256(acc, 1));
    sum = _mm_add_epi32(sum, _mm_shuffle_epi32(sum, _MM_SHUFFLE(1, 0, 3, 2)));
    sum = _mm_add_epi32(sum, _mm_shuffle_epi32(sum, _MM_SHUFFLE(2, 3, 0, 1)));
    out[i] = static_cast<uint32_t>(_mm_cvtsi128_si32(sum));
  }
}
#endif
}  // namespace

void squaredDistancesU8(const uint8_t* q, const uint8_t* points, int n, uint32_t* out) {
#if defined(__x86_64__) && defined(__GNUC__)
  static const bool has_avx2 = __builtin_cpu_supports("avx2");
  if (has_avx2) {
    squaredDistancesAvx2(q, points, n, out);
    return;
  }
#endif
  for (int i = 0; i < n; ++i) {
    out[i] = squaredDistanceU8(q, points + static_cast<size_t>(i) * kDescriptorBytes);
  }
}

cv::Mat toDescriptorsU8(const cv::Mat& descriptors) {
  if (descriptors.empty()) return cv::Mat(0, kDescriptorBytes, CV_8U);
  if (descriptors.cols != kDescriptorBytes ||
      (descriptors.type() != CV_32F && descriptors.type() != CV_8U)) {
    throw std::invalid_argument("descriptors must be n x 128, CV_32F or CV_8U");
  }
  cv::Mat out;
  if (descriptors.type() == CV_8U) {
    out = descriptors.clone();  // continuous
  } else {
    descriptors.convertTo(out, CV_8U);  // rounds and saturates to 0..255
  }
  return out;
}

namespace {

constexpr uint32_t kFarDistance = std::numeric_limits<uint32_t>::max();

// Size of the glibc malloc chunk holding a request of `bytes` (what
// mallinfo2() counts): request + 8 rounded up to 16, at least 32.
size_t heapBlock(size_t bytes) {
  if (bytes == 0) return 0;
  return std::max<size_t>(32, (bytes + 8 + 15) / 16 * 16);
}

}  // namespace

LandmarkIndex::LandmarkIndex(const RecognitionParams& params) : params_(params) {
  if (!(params_.ratio > 0 && params_.ratio <= 1) || params_.min_matches < 3 ||
      params_.max_candidates < 1 || params_.exhaustive_max_landmarks < 0 || params_.min_votes < 1 ||
      params_.search_checks < 1 || !(params_.vote_ratio > 0 && params_.vote_ratio <= 1) ||
      params_.max_overlap < 1 || params_.verify_overlap < 1 ||
      params_.vocabulary_min_descriptors < 1 || params_.vocabulary_max_training < 1 ||
      !(params_.vocabulary_retrain_growth == 0 || params_.vocabulary_retrain_growth > 1)) {
    throw std::invalid_argument(
        "RecognitionParams: ratio in (0, 1], min_matches >= 3, max_candidates >= 1, "
        "min_votes >= 1, search_checks >= 1, vote_ratio in (0, 1], max_overlap >= 1, "
        "verify_overlap >= 1, "
        "exhaustive_max_landmarks >= 0, vocabulary_min_descriptors >= 1, "
        "vocabulary_max_training >= 1, vocabulary_retrain_growth 0 or > 1");
  }
  if (params_.vocabulary.branching < 2 || params_.vocabulary.max_depth < 1 ||
      params_.vocabulary.min_leaf_descriptors < 1 || params_.vocabulary.kmeans_iterations < 1) {
    throw std::invalid_argument("RecognitionParams: invalid vocabulary parameters");
  }
}

LandmarkIndex::~LandmarkIndex() = default;

void LandmarkIndex::add(LandmarkModel landmark) {
  if (landmark.descriptors.rows != static_cast<int>(landmark.points_robot.size()) ||
      (landmark.descriptors.type() != CV_32F && landmark.descriptors.type() != CV_8U) ||
      (landmark.descriptors.rows > 0 && landmark.descriptors.cols != kDescriptorBytes)) {
    throw std::invalid_argument("landmark " + std::to_string(landmark.id) +
                                ": needs one CV_32F or CV_8U 128-value descriptor row per point");
  }
  if (landmark.id < 0) {
    throw std::invalid_argument("landmark ids must be >= 0, got " + std::to_string(landmark.id));
  }
  landmark.descriptors = toDescriptorsU8(landmark.descriptors);
  landmark.points_robot.shrink_to_fit();
  remove(landmark.id);
  uint32_t slot;
  if (!free_slots_.empty()) {
    slot = free_slots_.back();
    free_slots_.pop_back();
  } else {
    slot = static_cast<uint32_t>(entries_.size());
    entries_.emplace_back();
  }
  slot_of_[landmark.id] = slot;
  num_descriptors_ += static_cast<size_t>(landmark.descriptors.rows);
  entries_[slot].model = std::move(landmark);
  indexWords(slot);
  maybeTrain();
}

bool LandmarkIndex::remove(int64_t id) {
  const auto it = slot_of_.find(id);
  if (it == slot_of_.end()) return false;
  const uint32_t slot = it->second;
  slot_of_.erase(it);
  unindexWords(slot);
  Entry& e = entries_[slot];
  num_descriptors_ -= static_cast<size_t>(e.model.descriptors.rows);
  e = Entry{};  // frees its storage
  free_slots_.push_back(slot);
  return true;
}

const LandmarkModel* LandmarkIndex::find(int64_t id) const {
  const auto it = slot_of_.find(id);
  return it == slot_of_.end() ? nullptr : &entries_[it->second].model;
}

void LandmarkIndex::indexWords(uint32_t slot) {
  Entry& e = entries_[slot];
  e.words.clear();
  if (vocabulary_.empty()) {
    e.words.shrink_to_fit();
    return;
  }
  const cv::Mat& d = e.model.descriptors;
  e.words.resize(static_cast<size_t>(d.rows));
  for (int i = 0; i < d.rows; ++i) {
    const uint8_t* row = d.ptr<uint8_t>(i);
    const uint32_t w = vocabulary_.quantize(row);
    e.words[static_cast<size_t>(i)] = w;
    Posting& p = inverted_[w];
    p.points.push_back({slot, static_cast<uint32_t>(i)});
    p.descriptors.insert(p.descriptors.end(), row, row + kDescriptorBytes);
  }
  e.words.shrink_to_fit();
}

void LandmarkIndex::unindexWords(uint32_t slot) {
  Entry& e = entries_[slot];
  for (size_t i = 0; i < e.words.size(); ++i) {
    Posting& p = inverted_[e.words[i]];
    for (size_t k = 0; k < p.points.size(); ++k) {
      if (p.points[k].slot != slot || p.points[k].point != i) continue;
      // Swap with the last point of the word (and its descriptor).
      const size_t last = p.points.size() - 1;
      p.points[k] = p.points[last];
      std::copy(p.descriptors.begin() + static_cast<std::ptrdiff_t>(last * kDescriptorBytes),
                p.descriptors.end(),
                p.descriptors.begin() + static_cast<std::ptrdiff_t>(k * kDescriptorBytes));
      p.points.pop_back();
      p.descriptors.resize(last * kDescriptorBytes);
      if (p.points.empty()) p = Posting{};  // release an emptied word's storage
      break;
    }
  }
  e.words.clear();
}

void LandmarkIndex::maybeTrain() {
  if (!auto_train_) return;
  const bool first = vocabulary_.empty() && num_descriptors_ >= params_.vocabulary_min_descriptors;
  const bool grown =
      !vocabulary_.empty() && params_.vocabulary_retrain_growth > 0 &&
      static_cast<double>(num_descriptors_) >=
          params_.vocabulary_retrain_growth * static_cast<double>(descriptors_at_training_);
  if (first || grown) trainVocabulary();
}

void LandmarkIndex::trainVocabulary() {
  // Training set: every descriptor, or a uniform subsample (deterministic).
  std::vector<const uint8_t*> rows;
  rows.reserve(num_descriptors_);
  for (const Entry& e : entries_) {
    for (int i = 0; i < e.model.descriptors.rows; ++i)
      rows.push_back(e.model.descriptors.ptr<uint8_t>(i));
  }
  if (rows.size() > params_.vocabulary_max_training) {
    std::mt19937 rng(params_.vocabulary.seed);
    for (size_t i = 0; i < params_.vocabulary_max_training; ++i) {
      std::swap(rows[i], rows[std::uniform_int_distribution<size_t>(i, rows.size() - 1)(rng)]);
    }
    rows.resize(params_.vocabulary_max_training);
  }
  descriptors_at_training_ = num_descriptors_;
  if (rows.empty()) {
    setVocabulary(VocabularyTree{});
    auto_train_ = true;
    return;
  }
  cv::Mat training(static_cast<int>(rows.size()), kDescriptorBytes, CV_8U);
  for (size_t i = 0; i < rows.size(); ++i)
    std::copy(rows[i], rows[i] + kDescriptorBytes, training.ptr<uint8_t>(static_cast<int>(i)));
  VocabularyTree v = VocabularyTree::train(training, params_.vocabulary);
  training.release();
  const bool auto_train = auto_train_;
  setVocabulary(std::move(v));
  auto_train_ = auto_train;
}

void LandmarkIndex::setVocabulary(VocabularyTree vocabulary) {
  auto_train_ = false;
  vocabulary_ = std::move(vocabulary);
  inverted_.clear();
  inverted_.shrink_to_fit();
  inverted_.resize(vocabulary_.numWords());
  for (uint32_t slot = 0; slot < entries_.size(); ++slot) {
    if (entries_[slot].model.id >= 0) indexWords(slot);
  }
}

std::vector<Recognition> LandmarkIndex::recognize(const Features& frame,
                                                  RecognitionStats* stats) const {
  RecognitionStats local;
  RecognitionStats& st = stats ? *stats : local;
  st = RecognitionStats{};
  if (frame.descriptors.rows == 0 || slot_of_.empty()) return {};
  const cv::Mat frame_u8 = toDescriptorsU8(frame.descriptors);

  std::vector<uint32_t> slots;
  // Per feature: the verification background seen by the vote search (see
  // verify()); it also covers landmarks that do not become candidates.
  std::vector<uint32_t> background(static_cast<size_t>(frame_u8.rows), kFarDistance);
  if (vocabulary_.empty() || size() <= static_cast<size_t>(params_.exhaustive_max_landmarks)) {
    st.exhaustive = true;
    for (const auto& [id, slot] : slot_of_) slots.push_back(slot);
    std::sort(slots.begin(), slots.end());
  } else {
    // Votes: each frame descriptor searches the inverted file and votes for
    // the landmarks whose nearest point it found is nearer than vote_ratio
    // times the background (the (max_overlap + 1)-th landmark's nearest).
    std::vector<uint16_t> votes(entries_.size(), 0);
    std::vector<uint32_t> voted;
    std::vector<std::pair<uint32_t, uint32_t>> nearest;  // (slot, squared distance)
    std::vector<int> seen_by(entries_.size(), -1);       // slot -> last feature that found it
    std::vector<uint32_t> position(entries_.size());     // slot -> its entry in `nearest`
    const double vote_ratio2 = params_.vote_ratio * params_.vote_ratio;
    const size_t overlap = static_cast<size_t>(params_.max_overlap);
    const size_t verify_overlap = static_cast<size_t>(params_.verify_overlap);
    for (int f = 0; f < frame_u8.rows; ++f) {
      const uint8_t* q = frame_u8.ptr<uint8_t>(f);
      nearest.clear();
      vocabulary_.search(q, params_.search_checks, [&](uint32_t word) {
        const Posting& p = inverted_[word];
        for (size_t k = 0; k < p.points.size(); ++k) {
          const uint32_t d = squaredDistanceU8(q, p.descriptors.data() + k * kDescriptorBytes);
          const uint32_t slot = p.points[k].slot;
          if (seen_by[slot] != f) {  // first point of this landmark for this feature
            seen_by[slot] = f;
            position[slot] = static_cast<uint32_t>(nearest.size());
            nearest.emplace_back(slot, d);
          } else {
            auto& n = nearest[position[slot]].second;
            n = std::min(n, d);
          }
        }
        return static_cast<int>(p.points.size());
      });
      if (nearest.size() < 2) continue;
      const size_t m = std::min(overlap, nearest.size() - 1);
      std::nth_element(nearest.begin(), nearest.begin() + static_cast<std::ptrdiff_t>(m),
                       nearest.end(),
                       [](const auto& a, const auto& b) { return a.second < b.second; });
      const double vote_background = vote_ratio2 * static_cast<double>(nearest[m].second);
      for (size_t i = 0; i < m; ++i) {
        const uint32_t slot = nearest[i].first;
        if (static_cast<double>(nearest[i].second) >= vote_background) continue;
        if (votes[slot]++ == 0) voted.push_back(slot);
      }
      if (verify_overlap < nearest.size()) {
        // The (verify_overlap + 1)-th nearest landmark found: among the m + 1
        // nearest if it is one of them, else nearest[m] itself.
        const auto nth = nearest.begin() + static_cast<std::ptrdiff_t>(verify_overlap);
        if (verify_overlap < m) {
          std::nth_element(nearest.begin(), nth, nearest.begin() + static_cast<std::ptrdiff_t>(m),
                           [](const auto& a, const auto& b) { return a.second < b.second; });
        }
        background[static_cast<size_t>(f)] = nth->second;
      }
    }
    st.voted_landmarks = static_cast<int>(voted.size());
    voted.erase(std::remove_if(voted.begin(), voted.end(),
                               [&](uint32_t s) { return votes[s] < params_.min_votes; }),
                voted.end());
    const size_t k = std::min(voted.size(), static_cast<size_t>(params_.max_candidates));
    std::partial_sort(
        voted.begin(), voted.begin() + static_cast<std::ptrdiff_t>(k), voted.end(),
        [&](uint32_t a, uint32_t b) { return votes[a] != votes[b] ? votes[a] > votes[b] : a < b; });
    slots.assign(voted.begin(), voted.begin() + static_cast<std::ptrdiff_t>(k));
  }
  st.candidates = static_cast<int>(slots.size());
  return verify(frame, frame_u8, slots, std::move(background));
}

std::vector<Recognition> LandmarkIndex::recognizeExact(const Features& frame) const {
  if (frame.descriptors.rows == 0 || slot_of_.empty()) return {};
  std::vector<uint32_t> slots;
  for (const auto& [id, slot] : slot_of_) slots.push_back(slot);
  std::sort(slots.begin(), slots.end());
  return verify(frame, toDescriptorsU8(frame.descriptors), slots,
                std::vector<uint32_t>(static_cast<size_t>(frame.descriptors.rows), kFarDistance));
}

std::vector<Recognition> LandmarkIndex::verify(const Features& frame, const cv::Mat& frame_u8,
                                               const std::vector<uint32_t>& slots,
                                               std::vector<uint32_t> background) const {
  std::vector<Recognition> out;
  const double ratio2 = params_.ratio * params_.ratio;
  const size_t num_features = static_cast<size_t>(frame_u8.rows);
  const size_t num_slots = slots.size();
  constexpr uint32_t kFar = kFarDistance;
  // Nearest and second-nearest point of each candidate for each feature
  // (squared distances; candidate-major).
  struct Nearest {
    uint32_t d1 = kFar, d2 = kFar;
    int point = -1;
  };
  std::vector<Nearest> nearest(num_slots * num_features);
  std::vector<uint32_t> distances;
  for (size_t c = 0; c < num_slots; ++c) {
    const cv::Mat& d = entries_[slots[c]].model.descriptors;
    const uint8_t* points = d.rows > 0 ? d.ptr<uint8_t>(0) : nullptr;
    distances.resize(static_cast<size_t>(d.rows));
    for (size_t f = 0; f < num_features; ++f) {
      const uint8_t* q = frame_u8.ptr<uint8_t>(static_cast<int>(f));
      Nearest& n = nearest[c * num_features + f];
      squaredDistancesU8(q, points, d.rows, distances.data());
      for (int p = 0; p < d.rows; ++p) {
        const uint32_t dist = distances[static_cast<size_t>(p)];
        if (dist < n.d1) {
          n.d2 = n.d1;
          n.d1 = dist;
          n.point = p;
        } else if (dist < n.d2) {
          n.d2 = dist;
        }
      }
    }
  }
  // Background of each feature: the nearest point of the (verify_overlap +
  // 1)-th nearest candidate. A feature matches a landmark only if it is
  // clearly nearer than both the landmark's own second-nearest point and this
  // background, so up to verify_overlap landmarks holding the same physical
  // point all keep it, while a chance match (a small landmark's nearest point
  // that is no nearer than what other landmarks offer) does not. The caller's
  // background (from a search over more landmarks than the candidates) is
  // lowered to the candidates' where theirs is nearer.
  const size_t overlap = static_cast<size_t>(params_.verify_overlap);
  if (num_slots > overlap) {
    std::vector<uint32_t> column(num_slots);
    for (size_t f = 0; f < num_features; ++f) {
      for (size_t c = 0; c < num_slots; ++c) column[c] = nearest[c * num_features + f].d1;
      std::nth_element(column.begin(), column.begin() + static_cast<std::ptrdiff_t>(overlap),
                       column.end());
      background[f] = std::min(background[f], column[overlap]);
    }
  }
  struct Best {
    int feature;
    uint32_t dist;
  };
  std::vector<Best> best_of_point;
  for (size_t c = 0; c < num_slots; ++c) {
    const LandmarkModel& lm = entries_[slots[c]].model;
    const int num_points = lm.descriptors.rows;
    if (num_points < 2) continue;  // no second neighbour: the ratio test cannot pass
    best_of_point.assign(static_cast<size_t>(num_points), {-1, kFar});
    for (size_t f = 0; f < num_features; ++f) {
      const Nearest& n = nearest[c * num_features + f];
      const uint32_t reference = std::min(n.d2, background[f]);
      // Lowe's test on squared distances; each point keeps its closest feature.
      if (static_cast<double>(n.d1) < ratio2 * static_cast<double>(reference) &&
          n.d1 < best_of_point[static_cast<size_t>(n.point)].dist) {
        best_of_point[static_cast<size_t>(n.point)] = {static_cast<int>(f), n.d1};
      }
    }
    std::vector<std::pair<int, int>> pairs;  // (frame feature, point), sorted for determinism
    for (int p = 0; p < num_points; ++p) {
      const Best& b = best_of_point[static_cast<size_t>(p)];
      if (b.feature >= 0) pairs.emplace_back(b.feature, p);
    }
    if (static_cast<int>(pairs.size()) < params_.min_matches) continue;
    std::sort(pairs.begin(), pairs.end());
    Recognition r;
    r.landmark_id = lm.id;
    for (const auto& [feature, point] : pairs) {
      r.points_robot.push_back(lm.points_robot[static_cast<size_t>(point)]);
      r.observations.push_back(frame.normalized[static_cast<size_t>(feature)]);
      r.frame_features.push_back(feature);
      r.landmark_points.push_back(point);
    }
    out.push_back(std::move(r));
  }
  std::sort(out.begin(), out.end(), [](const Recognition& a, const Recognition& b) {
    return a.points_robot.size() != b.points_robot.size()
               ? a.points_robot.size() > b.points_robot.size()
               : a.landmark_id < b.landmark_id;
  });
  return out;
}

size_t LandmarkIndex::memoryBytes() const {
  size_t bytes = sizeof(*this);
  bytes += heapBlock(entries_.capacity() * sizeof(Entry));
  bytes += heapBlock(free_slots_.capacity() * sizeof(uint32_t));
  for (const Entry& e : entries_) {
    bytes += heapBlock(e.model.points_robot.capacity() * sizeof(Eigen::Vector3d));
    bytes += heapBlock(e.words.capacity() * sizeof(uint32_t));
    if (e.model.descriptors.u) {
      // cv::Mat: its UMatData block and a 64-byte aligned data block.
      bytes += heapBlock(sizeof(cv::UMatData));
      bytes += heapBlock(e.model.descriptors.total() * e.model.descriptors.elemSize() + 64 +
                         sizeof(void*));
    }
  }
  // Id map: one node per landmark, plus the bucket array.
  bytes += slot_of_.size() * heapBlock(sizeof(void*) + sizeof(std::pair<const int64_t, uint32_t>));
  bytes += heapBlock(slot_of_.bucket_count() * sizeof(void*));
  bytes += heapBlock(inverted_.capacity() * sizeof(Posting));
  for (const Posting& p : inverted_) {
    bytes += heapBlock(p.points.capacity() * sizeof(PointRef));
    bytes += heapBlock(p.descriptors.capacity());
  }
  bytes += vocabulary_.memoryBytes();
  return bytes;
}

}  // namespace vslam::frontend
