#pragma once
// Recognition of known landmarks in a frame (paper section 4: every processed
// image is matched against the landmark database), at the scale of the
// landmark DB (issue 5: 10,000 landmarks and more). No LCM.
//
// Two steps per frame (docs/frontend.md, "Recognition"):
//  1. Candidate selection: an inverted file keyed by the visual words of a
//     hierarchical k-means vocabulary (VocabularyTree) holds every landmark
//     point's descriptor. Each frame descriptor searches it best-bin-first
//     (its own word, then the nearest other branches, up to `search_checks`
//     points) and votes for the landmarks whose nearest point found passes a
//     ratio test against the background: nearer than `vote_ratio` times the
//     nearest point of the (`max_overlap` + 1)-th nearest landmark, so up to
//     `max_overlap` landmarks holding the same physical point all get a vote
//     while a feature close to nothing in particular gives none. The
//     landmarks with the most votes (at least `min_votes`, at most
//     `max_candidates`) go on.
//  2. Verification: the frame is matched exactly against each candidate
//     (nearest and second-nearest point of that landmark, Lowe's ratio test),
//     with the second-nearest distance capped by a background: the nearest
//     point of the (`verify_overlap` + 1)-th nearest candidate. Up to
//     `verify_overlap` landmarks holding the same physical point all keep its
//     match; a chance match, a small landmark's nearest point no nearer than
//     what other landmarks offer, does not.
// Descriptors are held as uint8 (128 B per point, twice: per landmark for
// verification and per word for the search); the vocabulary is trained on
// the landmarks themselves and retrained as they grow, or given.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <unordered_map>
#include <vector>

#include "frontend/features.hpp"
#include "frontend/vocabulary_tree.hpp"
#include "odometry/pose2.hpp"
#include "util/time.hpp"

namespace vslam::frontend {

// What recognition and measurement need of a landmark: its 3-D points (robot
// frame at creation) and the reference view's descriptor of each point.
struct LandmarkModel {
  int64_t id = -1;
  std::vector<Eigen::Vector3d> points_robot;
  // One 128-value row per point, same order. add() takes CV_32F (SIFT's
  // output: integers 0..255) or CV_8U; the index holds CV_8U (values rounded
  // and saturated to 0..255), which is what find() returns.
  cv::Mat descriptors;
  // Its reference view's time and odometry pose, in the odometry of the run
  // that made it (0: unknown). Not used by recognition: the front-end
  // compares them with its own odometry (FrontendParams::coverage_gate_sigmas).
  Utime created_utime = 0;
  Pose2 created_odometry;
};

struct RecognitionParams {
  // Lowe's ratio test, against the landmark's own second-nearest point and
  // the background of the other candidates (see verify_overlap).
  double ratio = 0.8;
  // Landmarks that may hold the same physical point and all keep its match:
  // the background a match must beat is the nearest point of the
  // (verify_overlap + 1)-th nearest candidate.
  int verify_overlap = 3;
  int min_matches = 10;  // fewer matches do not make a measurement (paper: NPoints >= 10)
  // Landmarks verified per frame, most votes first. Verification costs ~0.15
  // ms per landmark for a 600-feature frame; this bounds it.
  int max_candidates = 48;
  int min_votes = 4;        // fewer votes: not a candidate
  int search_checks = 192;  // landmark points compared per frame descriptor
  double vote_ratio = 0.8;  // ratio test of a vote against the background (see above)
  int max_overlap = 16;     // landmarks that may hold the same physical point
  // With at most this many landmarks, or no vocabulary yet, every landmark is
  // verified (exact).
  int exhaustive_max_landmarks = 24;
  // The vocabulary: trained on the landmarks' own descriptors once they hold
  // `vocabulary_min_descriptors`, and again whenever their number has grown
  // by `vocabulary_retrain_growth` since the last training (0: never
  // retrain), on at most `vocabulary_max_training` of them (a uniform
  // subsample). setVocabulary() installs a given one and stops this.
  VocabularyParams vocabulary = {};
  size_t vocabulary_min_descriptors = 1000;
  double vocabulary_retrain_growth = 4.0;
  size_t vocabulary_max_training = 100000;
};

// A landmark seen in a frame: matched 2-D/3-D pairs for the measurement.
struct Recognition {
  int64_t landmark_id = -1;
  std::vector<Eigen::Vector3d> points_robot;  // matched landmark points
  std::vector<Eigen::Vector2d> observations;  // their features in the frame (normalized coords)
  std::vector<int> frame_features;            // index of each observation in the frame's Features
  // Index of each matched point in the landmark (LandmarkModel row), same order.
  std::vector<int> landmark_points;
};

// What one query did (optional output of recognize()).
struct RecognitionStats {
  bool exhaustive = false;  // every landmark verified
  int candidates = 0;       // landmarks verified
  int voted_landmarks = 0;  // landmarks with at least one vote
};

class LandmarkIndex {
 public:
  explicit LandmarkIndex(const RecognitionParams& params = {});
  ~LandmarkIndex();
  LandmarkIndex(const LandmarkIndex&) = delete;
  LandmarkIndex& operator=(const LandmarkIndex&) = delete;

  // Adds or replaces (same id) a landmark, incrementally (its words join the
  // inverted file); may (re)train the vocabulary (see RecognitionParams).
  // Throws std::invalid_argument if its points and descriptors disagree or
  // the descriptors are not n x 128 CV_32F/CV_8U.
  void add(LandmarkModel landmark);
  bool remove(int64_t id);
  size_t size() const { return slot_of_.size(); }
  size_t numDescriptors() const { return num_descriptors_; }
  // The landmark as held (descriptors CV_8U), or nullptr.
  const LandmarkModel* find(int64_t id) const;

  // Landmarks with at least min_matches matches in the frame, most matches
  // first; each frame feature and each landmark point is used at most once
  // per landmark.
  std::vector<Recognition> recognize(const Features& frame,
                                     RecognitionStats* stats = nullptr) const;
  // The same with every landmark verified: the exact search that recall is
  // measured against (cost linear in the number of landmarks).
  std::vector<Recognition> recognizeExact(const Features& frame) const;

  // Trains the vocabulary on the landmarks held now and re-quantizes them.
  void trainVocabulary();
  // Installs a vocabulary trained elsewhere (e.g. on a generic set) and stops
  // automatic (re)training.
  void setVocabulary(VocabularyTree vocabulary);
  const VocabularyTree& vocabulary() const { return vocabulary_; }

  // Bytes held by the index: landmarks (descriptors, points, words), the
  // inverted file, the id map and the vocabulary, each heap block counted as
  // the glibc malloc chunk that holds it (what mallinfo2() reports).
  size_t memoryBytes() const;

 private:
  struct Entry {
    LandmarkModel model;          // model.id < 0: free slot
    std::vector<uint32_t> words;  // word of each point (empty without vocabulary)
  };
  struct PointRef {
    uint32_t slot;   // landmark
    uint32_t point;  // its row
  };
  // The points of one word and a copy of their descriptors (128 B each, same
  // order), contiguous for the search.
  struct Posting {
    std::vector<PointRef> points;
    std::vector<uint8_t> descriptors;
  };

  void indexWords(uint32_t slot);
  void unindexWords(uint32_t slot);
  void maybeTrain();
  // `background`: per frame feature, an upper bound of the verification
  // background already known (max: none).
  std::vector<Recognition> verify(const Features& frame, const cv::Mat& frame_u8,
                                  const std::vector<uint32_t>& slots,
                                  std::vector<uint32_t> background) const;

  RecognitionParams params_;
  std::vector<Entry> entries_;
  std::vector<uint32_t> free_slots_;
  std::unordered_map<int64_t, uint32_t> slot_of_;
  std::vector<Posting> inverted_;  // word -> the points holding it
  VocabularyTree vocabulary_;
  size_t num_descriptors_ = 0;
  size_t descriptors_at_training_ = 0;
  bool auto_train_ = true;
};

}  // namespace vslam::frontend
