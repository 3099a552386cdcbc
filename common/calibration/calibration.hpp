#pragma once
// Camera calibration from views of a planar board (vslam-calibrate; see
// docs/calibration.md): board detection (chessboard, or ChArUco with OpenCV's
// contrib aruco module), view selection (blurred and redundant views
// rejected), cv::calibrateCamera with one pass of outlier rejection, and the
// result written as OpenCV's calibration YAML, the file the robot file's
// `calibration:` key reads. No LCM.

#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace vslam::calibration {

enum class BoardKind { kChessboard, kCharuco };

struct BoardSpec {
  BoardKind kind = BoardKind::kChessboard;
  // Chessboard: inner corners per row and per column (OpenCV's sample board:
  // 9x6). ChArUco: squares per row and per column.
  cv::Size size;
  double square_size_m = 0;                // side of a square (no default: the board's)
  double marker_size_m = 0;                // ChArUco: side of a marker (no default)
  std::string dictionary = "DICT_4X4_50";  // ChArUco: the markers' ArUco dictionary
};

// Throws std::invalid_argument naming the problem (sizes, dictionary name).
void validate(const BoardSpec& board);
// The ArUco dictionaries by name ("DICT_4X4_50", ...), for messages.
std::vector<std::string> arucoDictionaryNames();

// One view of the board: corresponding points.
struct BoardView {
  std::string name;                        // file name, or "frame N"
  std::vector<cv::Point3f> object_points;  // board frame (z = 0), metres
  std::vector<cv::Point2f> image_points;   // pixels
};

class BoardDetector {
 public:
  explicit BoardDetector(BoardSpec board);  // throws std::invalid_argument
  ~BoardDetector();
  BoardDetector(const BoardDetector&) = delete;
  BoardDetector& operator=(const BoardDetector&) = delete;

  // Finds the board in a grey image, corners refined to sub-pixel; false if
  // it is not there (ChArUco: fewer than min_charuco_corners corners seen).
  bool detect(const cv::Mat& gray, BoardView* view) const;
  // The four outer corners of the board's corner grid (board frame, metres).
  const std::vector<cv::Point2f>& outline() const { return outline_; }
  const BoardSpec& board() const { return board_; }

 private:
  struct Charuco;
  BoardSpec board_;
  std::vector<cv::Point2f> outline_;
  std::unique_ptr<Charuco> charuco_;
};

// Variance of the Laplacian of a grey image inside the bounding box of the
// points: high for sharp edges, low when motion or focus blur smears them.
double boardSharpness(const cv::Mat& gray, const std::vector<cv::Point2f>& image_points);

struct ViewSelectionParams {
  // Views whose board is less sharp than this (variance of the Laplacian,
  // grey levels^2, in the board's bounding box) are rejected. OpenCV's 13
  // sample views score 286-1,000; blurred with a Gaussian of sigma 1 / 1.5 /
  // 2 px they score 75-189 / 37-82 / 20-41 (docs/calibration.md). It scales
  // with the board's contrast: lower it for a dim, low-contrast camera.
  double min_sharpness = 100;
  // A view whose board outline lies within this fraction of the image
  // diagonal of a kept view's (mean distance of the four outer corners)
  // adds nothing: rejected as redundant.
  double min_novelty = 0.03;
  int min_charuco_corners = 8;  // fewer seen corners: no view (ChArUco)
};

enum class ViewVerdict { kKept, kNoBoard, kBlurred, kRedundant, kWrongSize };
const char* describe(ViewVerdict verdict);

struct ViewDecision {
  ViewVerdict verdict = ViewVerdict::kNoBoard;
  double sharpness = 0;  // when a board was found
  double novelty = 0;    // fraction of the diagonal to the nearest kept view (1 if none)
};

// Detects the board in each offered frame and keeps the sharp, new views.
class ViewSelector {
 public:
  ViewSelector(const BoardDetector& detector, ViewSelectionParams params);
  // `name` labels the view in reports. All frames must have one size.
  ViewDecision offer(const cv::Mat& gray, const std::string& name);
  const std::vector<BoardView>& kept() const { return kept_; }
  cv::Size imageSize() const { return image_size_; }

 private:
  std::vector<cv::Point2f> projectedOutline(const BoardView& view) const;

  const BoardDetector& detector_;
  ViewSelectionParams params_;
  cv::Size image_size_;
  std::vector<BoardView> kept_;
  std::vector<std::vector<cv::Point2f>> kept_outlines_;
};

struct CalibrationParams {
  int min_views = 5;  // fewer usable views: no calibration
  // A view whose RMS reprojection error exceeds both outlier_factor x the
  // median view's and min_outlier_error_px is dropped, then the camera is
  // calibrated once more without it.
  double outlier_factor = 3.0;
  double min_outlier_error_px = 0.5;
  bool fix_aspect_ratio = false;  // fx = fy (OpenCV's CALIB_FIX_ASPECT_RATIO)
  bool zero_tangential = false;   // p1 = p2 = 0
  bool fix_k3 = false;            // k3 = 0
};

struct CalibrationResult {
  cv::Size image_size;
  cv::Mat camera_matrix;  // 3x3, CV_64F
  cv::Mat distortion;     // 1x5 (k1 k2 p1 p2 k3), CV_64F
  int flags = 0;          // cv::calibrateCamera flags used
  double rms_px = 0;      // overall RMS reprojection error of the final calibration
  // Standard deviations of fx, fy, cx, cy (px) as cv::calibrateCamera
  // estimates them from the residuals: how well the views pin them down.
  cv::Vec4d intrinsics_sigma_px;
  std::vector<BoardView> views;        // the views of the final calibration
  std::vector<double> view_rms_px;     // their RMS errors
  std::vector<std::string> dropped;    // outlier views
  std::vector<double> dropped_rms_px;  // their errors in the first calibration
  double first_rms_px = 0;             // overall RMS before dropping outliers
};

// Throws std::runtime_error when there are too few views or the calibration fails.
CalibrationResult calibrate(const std::vector<BoardView>& views, cv::Size image_size,
                            const CalibrationParams& params);

// Writes OpenCV's calibration YAML (image_width, image_height, camera_matrix,
// distortion_coefficients, as OpenCV's calibration sample does, plus the
// board and the errors), then reads it back as the robot file would
// (config::readOpenCvCalibration); throws std::runtime_error on failure.
void writeCalibrationFile(const std::filesystem::path& file, const CalibrationResult& result,
                          const BoardSpec& board);

}  // namespace vslam::calibration
