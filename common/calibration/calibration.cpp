#include "calibration/calibration.hpp"

#include <algorithm>
#include <ctime>
#include <opencv2/aruco/charuco.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "config/robot_config.hpp"

namespace vslam::calibration {
namespace {

const std::vector<std::pair<std::string, cv::aruco::PREDEFINED_DICTIONARY_NAME>>&
arucoDictionaries() {
  using namespace cv::aruco;
  static const std::vector<std::pair<std::string, PREDEFINED_DICTIONARY_NAME>> kNames = {
      {"DICT_4X4_50", DICT_4X4_50},
      {"DICT_4X4_100", DICT_4X4_100},
      {"DICT_4X4_250", DICT_4X4_250},
      {"DICT_4X4_1000", DICT_4X4_1000},
      {"DICT_5X5_50", DICT_5X5_50},
      {"DICT_5X5_100", DICT_5X5_100},
      {"DICT_5X5_250", DICT_5X5_250},
      {"DICT_5X5_1000", DICT_5X5_1000},
      {"DICT_6X6_50", DICT_6X6_50},
      {"DICT_6X6_100", DICT_6X6_100},
      {"DICT_6X6_250", DICT_6X6_250},
      {"DICT_6X6_1000", DICT_6X6_1000},
      {"DICT_7X7_50", DICT_7X7_50},
      {"DICT_7X7_100", DICT_7X7_100},
      {"DICT_7X7_250", DICT_7X7_250},
      {"DICT_7X7_1000", DICT_7X7_1000},
      {"DICT_ARUCO_ORIGINAL", DICT_ARUCO_ORIGINAL},
      {"DICT_APRILTAG_16h5", DICT_APRILTAG_16h5},
      {"DICT_APRILTAG_25h9", DICT_APRILTAG_25h9},
      {"DICT_APRILTAG_36h10", DICT_APRILTAG_36h10},
      {"DICT_APRILTAG_36h11", DICT_APRILTAG_36h11},
  };
  return kNames;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Mean distance between corresponding corners of two board outlines, taking
// the better of the two orderings: a board that looks the same turned by
// 180 degrees may be reported with its corners in the opposite order.
double outlineDistance(const std::vector<cv::Point2f>& a, const std::vector<cv::Point2f>& b) {
  double same = 0, turned = 0;
  for (size_t i = 0; i < 4; ++i) {
    same += cv::norm(a[i] - b[i]);
    turned += cv::norm(a[i] - b[(i + 2) % 4]);
  }
  return std::min(same, turned) / 4.0;
}

}  // namespace

std::vector<std::string> arucoDictionaryNames() {
  std::vector<std::string> names;
  for (const auto& d : arucoDictionaries()) names.push_back(d.first);
  return names;
}

void validate(const BoardSpec& b) {
  auto require = [](bool ok, const std::string& problem) {
    if (!ok) throw std::invalid_argument(problem);
  };
  require(b.square_size_m > 0, "the square size must be > 0");
  if (b.kind == BoardKind::kChessboard) {
    require(b.size.width >= 3 && b.size.height >= 3,
            "a chessboard needs at least 3x3 inner corners");
    require(b.size.width != b.size.height,
            "a chessboard with as many inner corners per row as per column looks the same "
            "turned by 90 degrees; use a board with a different count (e.g. 9x6)");
    return;
  }
  require(b.size.width >= 3 && b.size.height >= 3, "a ChArUco board needs at least 3x3 squares");
  require(b.marker_size_m > 0 && b.marker_size_m < b.square_size_m,
          "the marker size must be > 0 and smaller than the square size");
  const auto& dicts = arucoDictionaries();
  require(std::any_of(dicts.begin(), dicts.end(),
                      [&](const auto& d) { return d.first == b.dictionary; }),
          "unknown ArUco dictionary '" + b.dictionary + "'");
}

struct BoardDetector::Charuco {
  cv::Ptr<cv::aruco::CharucoBoard> board;
  cv::Ptr<cv::aruco::DetectorParameters> parameters;
};

BoardDetector::BoardDetector(BoardSpec board) : board_(std::move(board)) {
  validate(board_);
  const float s = static_cast<float>(board_.square_size_m);
  // The corner grid spans (w-1) x (h-1) squares: a chessboard's inner corners
  // are w x h; a ChArUco board of w x h squares has (w-1) x (h-1) corners.
  const int cols =
      board_.kind == BoardKind::kChessboard ? board_.size.width : board_.size.width - 1;
  const int rows =
      board_.kind == BoardKind::kChessboard ? board_.size.height : board_.size.height - 1;
  const float w = s * static_cast<float>(cols - 1), h = s * static_cast<float>(rows - 1);
  const float o =
      board_.kind == BoardKind::kChessboard ? 0.f : s;  // ChArUco corners start one square in
  outline_ = {{o, o}, {o + w, o}, {o + w, o + h}, {o, o + h}};
  if (board_.kind == BoardKind::kCharuco) {
    charuco_ = std::make_unique<Charuco>();
    cv::aruco::PREDEFINED_DICTIONARY_NAME dict = cv::aruco::DICT_4X4_50;
    for (const auto& d : arucoDictionaries()) {
      if (d.first == board_.dictionary) dict = d.second;
    }
    charuco_->board = cv::aruco::CharucoBoard::create(board_.size.width, board_.size.height, s,
                                                      static_cast<float>(board_.marker_size_m),
                                                      cv::aruco::getPredefinedDictionary(dict));
    charuco_->parameters = cv::aruco::DetectorParameters::create();
  }
}

BoardDetector::~BoardDetector() = default;

bool BoardDetector::detect(const cv::Mat& gray, BoardView* view) const {
  view->object_points.clear();
  view->image_points.clear();
  if (board_.kind == BoardKind::kChessboard) {
    std::vector<cv::Point2f> corners;
    const bool found = cv::findChessboardCorners(
        gray, board_.size, corners,
        cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_FAST_CHECK);
    if (!found) return false;
    cv::cornerSubPix(gray, corners, cv::Size(11, 11), cv::Size(-1, -1),
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 30, 0.01));
    const float s = static_cast<float>(board_.square_size_m);
    for (int r = 0; r < board_.size.height; ++r) {
      for (int c = 0; c < board_.size.width; ++c) {
        view->object_points.emplace_back(s * static_cast<float>(c), s * static_cast<float>(r), 0.f);
      }
    }
    view->image_points = std::move(corners);
    return true;
  }
  std::vector<int> marker_ids;
  std::vector<std::vector<cv::Point2f>> marker_corners, rejected;
  cv::aruco::detectMarkers(gray, charuco_->board->dictionary, marker_corners, marker_ids,
                           charuco_->parameters, rejected);
  if (marker_ids.empty()) return false;
  std::vector<cv::Point2f> corners;
  std::vector<int> ids;
  cv::aruco::interpolateCornersCharuco(marker_corners, marker_ids, gray, charuco_->board, corners,
                                       ids);
  if (ids.empty()) return false;
  for (size_t i = 0; i < ids.size(); ++i) {
    view->object_points.push_back(charuco_->board->chessboardCorners[ids[i]]);
  }
  view->image_points = std::move(corners);
  return true;
}

double boardSharpness(const cv::Mat& gray, const std::vector<cv::Point2f>& image_points) {
  cv::Rect box = cv::boundingRect(image_points) & cv::Rect(0, 0, gray.cols, gray.rows);
  if (box.area() < 9) return 0;
  cv::Mat laplacian;
  cv::Laplacian(gray(box), laplacian, CV_64F);
  cv::Scalar mean, stddev;
  cv::meanStdDev(laplacian, mean, stddev);
  return stddev[0] * stddev[0];
}

const char* describe(ViewVerdict verdict) {
  switch (verdict) {
    case ViewVerdict::kKept:
      return "kept";
    case ViewVerdict::kNoBoard:
      return "no board found";
    case ViewVerdict::kBlurred:
      return "blurred";
    case ViewVerdict::kRedundant:
      return "redundant (like a kept view)";
    case ViewVerdict::kWrongSize:
      return "image size differs from the first view's";
  }
  return "?";
}

ViewSelector::ViewSelector(const BoardDetector& detector, ViewSelectionParams params)
    : detector_(detector), params_(params) {}

std::vector<cv::Point2f> ViewSelector::projectedOutline(const BoardView& view) const {
  // The board plane to the image: a homography, exact for a pinhole camera
  // and close enough under distortion to compare two views.
  std::vector<cv::Point2f> plane;
  for (const auto& p : view.object_points) plane.emplace_back(p.x, p.y);
  const cv::Mat h = cv::findHomography(plane, view.image_points);
  std::vector<cv::Point2f> outline;
  if (h.empty()) return outline;
  cv::perspectiveTransform(detector_.outline(), outline, h);
  return outline;
}

ViewDecision ViewSelector::offer(const cv::Mat& gray, const std::string& name) {
  ViewDecision d;
  if (image_size_.area() == 0) image_size_ = gray.size();
  if (gray.size() != image_size_) {
    d.verdict = ViewVerdict::kWrongSize;
    return d;
  }
  BoardView view;
  view.name = name;
  if (!detector_.detect(gray, &view)) return d;
  const int min_points =
      detector_.board().kind == BoardKind::kCharuco ? std::max(params_.min_charuco_corners, 4) : 4;
  if (static_cast<int>(view.image_points.size()) < min_points) return d;
  d.sharpness = boardSharpness(gray, view.image_points);
  if (d.sharpness < params_.min_sharpness) {
    d.verdict = ViewVerdict::kBlurred;
    return d;
  }
  const std::vector<cv::Point2f> outline = projectedOutline(view);
  if (outline.size() != 4) return d;
  const double diagonal = std::hypot(image_size_.width, image_size_.height);
  d.novelty = 1.0;
  for (const auto& kept : kept_outlines_) {
    d.novelty = std::min(d.novelty, outlineDistance(outline, kept) / diagonal);
  }
  if (d.novelty < params_.min_novelty) {
    d.verdict = ViewVerdict::kRedundant;
    return d;
  }
  d.verdict = ViewVerdict::kKept;
  kept_.push_back(std::move(view));
  kept_outlines_.push_back(outline);
  return d;
}

namespace {

struct Pass {
  cv::Mat k, dist;
  double rms = 0;
  std::vector<double> per_view;
  cv::Vec4d sigma;  // fx, fy, cx, cy
};

Pass calibratePass(const std::vector<BoardView>& views, cv::Size image_size, int flags) {
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> image;
  for (const auto& v : views) {
    object.push_back(v.object_points);
    image.push_back(v.image_points);
  }
  Pass p;
  p.k = cv::Mat::eye(3, 3, CV_64F);  // fx/fy = 1 for CALIB_FIX_ASPECT_RATIO
  p.dist = cv::Mat::zeros(1, 5, CV_64F);
  std::vector<cv::Mat> rvecs, tvecs;
  cv::Mat std_intrinsics, std_extrinsics, per_view;
  p.rms = cv::calibrateCamera(object, image, image_size, p.k, p.dist, rvecs, tvecs, std_intrinsics,
                              std_extrinsics, per_view, flags);
  for (int i = 0; i < per_view.rows; ++i) p.per_view.push_back(per_view.at<double>(i));
  for (int i = 0; i < 4 && i < std_intrinsics.rows; ++i) p.sigma[i] = std_intrinsics.at<double>(i);
  return p;
}

}  // namespace

CalibrationResult calibrate(const std::vector<BoardView>& views, cv::Size image_size,
                            const CalibrationParams& params) {
  if (static_cast<int>(views.size()) < params.min_views) {
    throw std::runtime_error(std::to_string(views.size()) + " usable views; at least " +
                             std::to_string(params.min_views) + " are needed");
  }
  CalibrationResult r;
  r.image_size = image_size;
  r.flags = (params.fix_aspect_ratio ? cv::CALIB_FIX_ASPECT_RATIO : 0) |
            (params.zero_tangential ? cv::CALIB_ZERO_TANGENT_DIST : 0) |
            (params.fix_k3 ? cv::CALIB_FIX_K3 : 0);
  Pass pass;
  try {
    pass = calibratePass(views, image_size, r.flags);
  } catch (const cv::Exception& e) {
    throw std::runtime_error(std::string("cv::calibrateCamera failed: ") + e.what());
  }
  r.first_rms_px = pass.rms;
  const double threshold =
      std::max(params.outlier_factor * median(pass.per_view), params.min_outlier_error_px);
  std::vector<BoardView> inliers;
  for (size_t i = 0; i < views.size(); ++i) {
    if (pass.per_view[i] > threshold) {
      r.dropped.push_back(views[i].name);
      r.dropped_rms_px.push_back(pass.per_view[i]);
    } else {
      inliers.push_back(views[i]);
    }
  }
  if (!r.dropped.empty() && static_cast<int>(inliers.size()) >= params.min_views) {
    try {
      pass = calibratePass(inliers, image_size, r.flags);
    } catch (const cv::Exception& e) {
      throw std::runtime_error(std::string("cv::calibrateCamera failed: ") + e.what());
    }
    r.views = std::move(inliers);
  } else {
    // Too few would be left: keep them all rather than calibrate on too few.
    r.dropped.clear();
    r.dropped_rms_px.clear();
    r.views = views;
  }
  r.camera_matrix = pass.k;
  r.distortion = pass.dist.reshape(1, 1);
  r.rms_px = pass.rms;
  r.intrinsics_sigma_px = pass.sigma;
  r.view_rms_px = pass.per_view;
  if (!cv::checkRange(r.camera_matrix) || !cv::checkRange(r.distortion) ||
      !(r.camera_matrix.at<double>(0, 0) > 0) || !(r.camera_matrix.at<double>(1, 1) > 0)) {
    throw std::runtime_error("the calibration diverged (non-finite or negative focal length)");
  }
  return r;
}

void writeCalibrationFile(const std::filesystem::path& file, const CalibrationResult& r,
                          const BoardSpec& board) {
  {
    cv::FileStorage fs(file.string(), cv::FileStorage::WRITE);
    if (!fs.isOpened()) throw std::runtime_error("cannot write " + file.string());
    char when[64] = "";
    const std::time_t now = std::time(nullptr);
    std::strftime(when, sizeof(when), "%Y-%m-%d %H:%M:%S", std::localtime(&now));
    fs.writeComment("Written by vslam-calibrate; the robot file's `calibration:` key reads it.");
    fs << "calibration_time" << when;
    fs << "nframes" << static_cast<int>(r.views.size());
    fs << "image_width" << r.image_size.width;
    fs << "image_height" << r.image_size.height;
    fs << "board_type" << (board.kind == BoardKind::kChessboard ? "chessboard" : "charuco");
    fs << "board_width" << board.size.width;
    fs << "board_height" << board.size.height;
    fs << "square_size" << board.square_size_m;
    if (board.kind == BoardKind::kCharuco) {
      fs << "marker_size" << board.marker_size_m;
      fs << "dictionary" << board.dictionary;
    }
    fs << "flags" << r.flags;
    fs << "camera_matrix" << r.camera_matrix;
    fs << "distortion_coefficients" << r.distortion;
    fs << "avg_reprojection_error" << r.rms_px;
    fs << "per_view_reprojection_errors" << cv::Mat(r.view_rms_px).clone();
  }
  try {
    const config::CameraIntrinsics check = config::readOpenCvCalibration(file);
    if (check.width != r.image_size.width || check.height != r.image_size.height) {
      throw std::runtime_error("read back with another image size");
    }
  } catch (const std::exception& e) {
    throw std::runtime_error("wrote " + file.string() +
                             " but the robot file could not read it: " + e.what());
  }
}

}  // namespace vslam::calibration
