#pragma once
// Descriptor matching for the front-end: exact nearest neighbours with
// Lowe's ratio test, and the paper's consistent three-way correspondences
// (section 4.1.2). No LCM.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

namespace vslam::frontend {

struct MatchParams {
  // Lowe's ratio test: keep a match when the nearest train descriptor is
  // closer than ratio x the second nearest (Euclidean distance).
  double ratio = 0.8;
  // Also require the query to be the nearest neighbour of its train
  // descriptor (mutual consistency).
  bool mutual = false;
};

// Exact ratio-test matching of CV_32F descriptor rows (e.g. SIFT). All
// squared distances come from one matrix product, ||q||^2 + ||t||^2 - 2 q.t,
// which is several times faster than cv::BFMatcher::knnMatch and gives the
// same neighbours (up to float rounding ties). Keeps its distance buffer
// across calls. Not thread-safe: one matcher per thread.
class RatioMatcher {
 public:
  explicit RatioMatcher(const MatchParams& params = {});

  // matches[m].queryIdx indexes `query` rows, .trainIdx `train` rows,
  // .distance is the Euclidean distance; ordered by query index. A train set
  // of fewer than two rows yields no matches (no ratio test possible).
  void match(const cv::Mat& query, const cv::Mat& train, std::vector<cv::DMatch>* matches);

  const MatchParams& params() const { return params_; }

 private:
  using RowMajorMatrixXf = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  MatchParams params_;
  RowMajorMatrixXf dot_;  // query x train inner products
  Eigen::VectorXf query_norm_, train_norm_;
  std::vector<int> train_best_;
  std::vector<float> train_best_dist_;
};

// One feature seen in all three views: indices into each view's features.
struct Triplet {
  int i1 = -1, i2 = -1, i3 = -1;
};

// The paper's consistent three-way matches: for each match i1->i2 of views
// 1-2, keep (i1, i2, i3) when views 1-3 match i1->i3 and views 2-3 match
// i2->i3 with the same i3. m12 and m13 have view-1 queries, m23 view-2
// queries. Triplets that share a view-2 or view-3 feature with another
// triplet are ambiguous and dropped. Ordered by i1.
void threeWayMatches(const std::vector<cv::DMatch>& m12, const std::vector<cv::DMatch>& m13,
                     const std::vector<cv::DMatch>& m23, std::vector<Triplet>* triplets);

}  // namespace vslam::frontend
