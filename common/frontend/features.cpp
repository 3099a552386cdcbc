#include "frontend/features.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace vslam::frontend {

void Features::clear() {
  keypoints.clear();
  descriptors.release();
  normalized.clear();
  gain = 1.0;
  thumbnail.release();
}

double thumbnailSimilarity(const cv::Mat& a, const cv::Mat& b, int max_shift_px,
                           double flat_level) {
  if (a.empty() || a.size() != b.size() || a.type() != CV_32F || b.type() != CV_32F)
    return std::numeric_limits<double>::quiet_NaN();
  const int width = a.cols;
  const int max_shift = std::clamp(max_shift_px, 0, width / 2);
  const double floor_var = flat_level * flat_level;
  double best = std::numeric_limits<double>::quiet_NaN();
  // b's column c + shift shows what a's column c showed.
  for (int shift = -max_shift; shift <= max_shift; ++shift) {
    const int a0 = std::max(0, -shift), a1 = std::min(width, width - shift);
    double sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
    for (int r = 0; r < a.rows; ++r) {
      const float* pa = a.ptr<float>(r);
      const float* pb = b.ptr<float>(r);
      for (int c = a0; c < a1; ++c) {
        const double va = pa[c], vb = pb[c + shift];
        sa += va;
        sb += vb;
        saa += va * va;
        sbb += vb * vb;
        sab += va * vb;
      }
    }
    const double n = static_cast<double>(a.rows) * (a1 - a0);
    const double var_a = std::max(0.0, saa / n - (sa / n) * (sa / n));
    const double var_b = std::max(0.0, sbb / n - (sb / n) * (sb / n));
    if (var_a < floor_var || var_b < floor_var) continue;
    const double ncc = (sab / n - (sa / n) * (sb / n)) / std::sqrt(var_a * var_b);
    if (!(ncc <= best)) best = ncc;
  }
  return best;
}

FeatureExtractor::FeatureExtractor(const config::CameraConfig& camera, const SiftParams& sift)
    : FeatureExtractor(cv::Matx33d(camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1),
                       camera.distortion, sift) {}

FeatureExtractor::FeatureExtractor(const config::CameraIntrinsics& intrinsics,
                                   const SiftParams& sift)
    : FeatureExtractor(
          cv::Matx33d(intrinsics.fx, 0, intrinsics.cx, 0, intrinsics.fy, intrinsics.cy, 0, 0, 1),
          intrinsics.distortion, sift) {}

FeatureExtractor::FeatureExtractor(const cv::Matx33d& camera_matrix,
                                   const std::vector<double>& distortion, const SiftParams& sift)
    : camera_matrix_(camera_matrix), distortion_(distortion), params_(sift) {
  if (!(camera_matrix_(0, 0) > 0) || !(camera_matrix_(1, 1) > 0))
    throw std::invalid_argument("FeatureExtractor: focal lengths must be positive");
  static const size_t kValidSizes[] = {0, 4, 5, 8, 12, 14};
  bool valid = false;
  for (size_t n : kValidSizes) valid = valid || distortion_.size() == n;
  if (!valid)
    throw std::invalid_argument(
        "FeatureExtractor: distortion needs 0, 4, 5, 8, 12 or 14 coefficients");
  if (!(params_.gain_target_level >= 0 && params_.gain_target_level <= 255) ||
      !(params_.max_gain >= 1))
    throw std::invalid_argument(
        "FeatureExtractor: gain_target_level must be in [0, 255] and max_gain >= 1");
  sift_ = cv::SIFT::create(params_.nfeatures, params_.octave_layers, params_.contrast_threshold,
                           params_.edge_threshold, params_.sigma);
}

void FeatureExtractor::extract(const cv::Mat& gray, Features* out) {
  if (gray.empty() || gray.type() != CV_8UC1)
    throw std::invalid_argument("FeatureExtractor::extract: needs a non-empty CV_8UC1 image");
  out->keypoints.clear();
  out->gain = 1.0;
  const cv::Mat* image = &gray;
  if (params_.gain_target_level > 0) {
    // The 99th-percentile level, from a histogram.
    int counts[256] = {0};
    for (int r = 0; r < gray.rows; ++r) {
      const uint8_t* row = gray.ptr<uint8_t>(r);
      for (int c = 0; c < gray.cols; ++c) ++counts[row[c]];
    }
    const auto total = static_cast<int64_t>(gray.total());
    int64_t above = 0;
    int level = 255;
    while (level > 0 && (above + counts[level]) * 100 <= total) above += counts[level--];
    if (level < params_.gain_target_level) {
      out->gain = std::min(params_.max_gain, params_.gain_target_level / std::max(level, 1));
      gray.convertTo(gained_, CV_8U, out->gain);
      image = &gained_;
    }
  }
  if (params_.double_first_octave) {
    sift_->detectAndCompute(*image, cv::noArray(), out->keypoints, out->descriptors);
  } else {
    cv::resize(*image, halved_, cv::Size((image->cols + 1) / 2, (image->rows + 1) / 2), 0, 0,
               cv::INTER_AREA);
    sift_->detectAndCompute(halved_, cv::noArray(), out->keypoints, out->descriptors);
    // Pixel centres are at integers: halved pixel c covers image pixels 2c
    // and 2c+1 (centre 2c + 0.5). OpenCV 4.6 reports keypoints of its doubled
    // octave a quarter pixel too far right and down (its 2x INTER_LINEAR
    // puts doubled pixel d at d/2 - 0.25, it reports d/2), so the true
    // position in the halved image is the reported one minus 0.25.
    // (With double_first_octave the stack keeps OpenCV's quarter pixel: a
    // shift of every bearing alike, which a landmark's creation and its
    // measurements share. FeatureExtractor tests measure both.)
    const float sx = static_cast<float>(image->cols) / static_cast<float>(halved_.cols);
    const float sy = static_cast<float>(image->rows) / static_cast<float>(halved_.rows);
    for (cv::KeyPoint& k : out->keypoints) {
      k.pt.x = (k.pt.x + 0.25f) * sx - 0.5f;
      k.pt.y = (k.pt.y + 0.25f) * sy - 0.5f;
      k.size *= 0.5f * (sx + sy);
    }
  }
  cv::resize(
      gray, thumbnail_8u_,
      cv::Size(std::max(1, gray.cols / kThumbnailScale), std::max(1, gray.rows / kThumbnailScale)),
      0, 0, cv::INTER_AREA);
  thumbnail_8u_.convertTo(out->thumbnail, CV_32F);
  pixels_.resize(out->keypoints.size());
  for (size_t i = 0; i < pixels_.size(); ++i) pixels_[i] = out->keypoints[i].pt;
  undistort(pixels_, &out->normalized);
}

void FeatureExtractor::undistort(const std::vector<cv::Point2f>& pixels,
                                 std::vector<Eigen::Vector2d>* normalized) const {
  normalized->resize(pixels.size());
  if (pixels.empty()) return;
  // Double precision in and out: float pixel inputs are exact, and the
  // iteration count matters more than OpenCV's default 5 for wide lenses.
  distorted_.assign(pixels.begin(), pixels.end());
  cv::undistortPoints(distorted_, undistorted_, camera_matrix_, distortion_, cv::noArray(),
                      cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 50, 1e-12));
  for (size_t i = 0; i < pixels.size(); ++i)
    (*normalized)[i] = Eigen::Vector2d(undistorted_[i].x, undistorted_[i].y);
}

}  // namespace vslam::frontend
