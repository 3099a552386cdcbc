#pragma once
// SIFT features of one image with their undistorted normalized coordinates,
// the front-end's unit of work (paper section 4.1.3: "compute un-warped
// homogeneous coordinates for the features"). No LCM.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <vector>

#include "config/robot_config.hpp"

namespace vslam::frontend {

struct Features {
  std::vector<cv::KeyPoint> keypoints;  // distorted pixel positions, as detected
  cv::Mat descriptors;                  // CV_32F, keypoints.size() x 128
  // Undistorted normalized image coordinates (x/z, y/z in the OpenCV camera
  // frame) of each keypoint, same order.
  std::vector<Eigen::Vector2d> normalized;
  double gain = 1.0;  // the digital gain applied to the image before SIFT (1: none)
  // The image reduced kThumbnailScale times (CV_32F, each pixel the mean of
  // its block): the front-end's continuity test compares consecutive frames
  // by it (FrontendParams::view_jump_min_thumbnail_similarity).
  cv::Mat thumbnail;

  size_t size() const { return keypoints.size(); }
  void clear();
};

inline constexpr int kThumbnailScale = 10;  // 320 x 240 -> 32 x 24

// How alike two thumbnails (Features::thumbnail) of views a small turn apart
// are: the highest normalized cross-correlation of their overlap over
// horizontal shifts of up to max_shift_px thumbnail pixels (the overlap at
// least half the width) whose overlap has a standard deviation of at least
// flat_level in both images. In [-1, 1]; NaN where no shift has (a plain
// wall: its correlation is the noise's, near 0 against anything) or the
// sizes differ.
double thumbnailSimilarity(const cv::Mat& a, const cv::Mat& b, int max_shift_px, double flat_level);

// OpenCV's SIFT parameters (cv::SIFT::create), with its defaults, and the
// digital gain applied to dim frames before it.
struct SiftParams {
  int nfeatures = 0;  // keep the best N by contrast; 0 = all
  int octave_layers = 3;
  double contrast_threshold = 0.04;
  double edge_threshold = 10.0;
  double sigma = 1.6;
  // OpenCV starts its pyramid at twice the image's resolution (Lowe's first
  // octave), which is about three quarters of SIFT's time. false: it starts
  // at the image's own resolution (the image is halved before OpenCV doubles
  // it again, and the keypoints are scaled back), losing the smallest
  // features.
  bool double_first_octave = true;
  // SIFT's contrast threshold is absolute: a frame at a third of its
  // exposure (dusk, a camera without auto-exposure) loses most keypoints. A
  // frame whose 99th-percentile level is below gain_target_level is scaled
  // up to it, by at most max_gain (a digital gain, as a camera's
  // auto-exposure would apply); brighter frames are used unchanged.
  // gain_target_level 0: off.
  double gain_target_level = 0;
  double max_gain = 4.0;
};

// Detects SIFT keypoints and descriptors and undistorts the keypoints with
// the OpenCV lens model (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [tx ty]]]]).
// Keeps its SIFT object and point buffers across calls; `extract` reuses the
// output's storage. Not thread-safe: one extractor per thread.
class FeatureExtractor {
 public:
  FeatureExtractor(const config::CameraConfig& camera, const SiftParams& sift = {});
  FeatureExtractor(const config::CameraIntrinsics& intrinsics, const SiftParams& sift = {});
  FeatureExtractor(const cv::Matx33d& camera_matrix, const std::vector<double>& distortion,
                   const SiftParams& sift = {});

  // `gray`: CV_8UC1 image. Replaces *out.
  void extract(const cv::Mat& gray, Features* out);

  // Distorted pixel coordinates -> undistorted normalized coordinates
  // (iterative inversion of the lens model to ~1e-10, not OpenCV's default
  // five iterations).
  void undistort(const std::vector<cv::Point2f>& pixels,
                 std::vector<Eigen::Vector2d>* normalized) const;

  const cv::Matx33d& cameraMatrix() const { return camera_matrix_; }
  const std::vector<double>& distortion() const { return distortion_; }
  // Mean focal length, pixels: converts normalized-coordinate errors to pixels.
  double focalPx() const { return 0.5 * (camera_matrix_(0, 0) + camera_matrix_(1, 1)); }
  const SiftParams& siftParams() const { return params_; }

 private:
  cv::Matx33d camera_matrix_;
  std::vector<double> distortion_;
  SiftParams params_;
  cv::Ptr<cv::SIFT> sift_;
  cv::Mat gained_;        // the gained frame, reused
  cv::Mat halved_;        // the frame at half size (double_first_octave false), reused
  cv::Mat thumbnail_8u_;  // Features::thumbnail before its conversion, reused
  // Reused across calls.
  mutable std::vector<cv::Point2f> pixels_;
  mutable std::vector<cv::Point2d> distorted_, undistorted_;
};

}  // namespace vslam::frontend
