#pragma once
// Recognition of known landmarks in a frame (paper section 4: every processed
// image is matched against the landmark database). The in-process store of
// landmarks with one approximate-nearest-neighbour index (FLANN KD-trees) over
// the descriptors of all of them; the landmark DB manager of its own issue
// will serve the same queries for every front-end. No LCM.

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <memory>
#include <opencv2/core.hpp>
#include <opencv2/flann.hpp>
#include <vector>

#include "frontend/features.hpp"

namespace vslam::frontend {

// What recognition and measurement need of a landmark: its 3-D points (robot
// frame at creation) and the reference view's descriptor of each point.
struct LandmarkModel {
  int64_t id = -1;
  std::vector<Eigen::Vector3d> points_robot;
  cv::Mat descriptors;  // CV_32F, one 128-float row per point, same order
};

struct RecognitionParams {
  // Lowe's ratio test, applied per landmark (as if the frame were matched
  // against each landmark's image on its own), so a point seen by two
  // overlapping landmarks is not rejected as ambiguous.
  double ratio = 0.8;
  int min_matches = 10;  // fewer matches do not make a measurement (paper: NPoints >= 10)
  int neighbours = 4;    // neighbours fetched per frame feature
  int kdtree_trees = 4;
  int kdtree_checks = 64;
};

// A landmark seen in a frame: matched 2-D/3-D pairs for the measurement.
struct Recognition {
  int64_t landmark_id = -1;
  std::vector<Eigen::Vector3d> points_robot;  // matched landmark points
  std::vector<Eigen::Vector2d> observations;  // their features in the frame (normalized coords)
  std::vector<int> frame_features;            // index of each observation in the frame's Features
};

class LandmarkIndex {
 public:
  explicit LandmarkIndex(const RecognitionParams& params = {});
  ~LandmarkIndex();

  // Adds or replaces (same id) a landmark; throws std::invalid_argument if
  // its points and descriptors disagree.
  void add(LandmarkModel landmark);
  bool remove(int64_t id);
  size_t size() const { return landmarks_.size(); }
  size_t numDescriptors() const;
  const LandmarkModel* find(int64_t id) const;

  // Landmarks with at least min_matches matches in the frame, most matches
  // first; each frame feature and each landmark point is used at most once
  // per landmark. Rebuilds the index first if landmarks changed.
  std::vector<Recognition> recognize(const Features& frame);

 private:
  void rebuild();

  RecognitionParams params_;
  std::map<int64_t, LandmarkModel> landmarks_;
  cv::Mat all_descriptors_;                     // rows of every landmark, stacked
  std::vector<std::pair<int64_t, int>> owner_;  // row -> (landmark id, point index)
  std::unique_ptr<cv::flann::Index> index_;
  bool dirty_ = true;
};

}  // namespace vslam::frontend
