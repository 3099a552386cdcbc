#pragma once
// Plots drawn with OpenCV (no Python, no display): a small 2-D figure with
// axes, "nice" tick labels, grid, legend and optional equal aspect, and the
// two evaluation plots of the vSLAM paper:
//   trajectory.png  top view like Fig. 7: reference black, estimate red,
//                   odometry-only green, landmarks as blue circles;
//   error.png       position error over time like Fig. 9.

#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <utility>
#include <vector>

#include "eval/evaluate.hpp"

namespace vslam::eval {

struct PlotSeries {
  enum class Style { kLine, kCircles };
  std::string label;  // empty: not in the legend
  cv::Scalar color;   // BGR
  std::vector<cv::Point2d> points;
  Style style = Style::kLine;
  int thickness = 2;  // line width, or circle outline width
  int radius = 5;     // circles, pixels
};

class Figure {
 public:
  Figure(cv::Size size, std::string title, std::string x_label, std::string y_label);
  void add(PlotSeries series) { series_.push_back(std::move(series)); }
  void setEqualAspect(bool on) { equal_aspect_ = on; }
  void setYFromZero(bool on) { y_from_zero_ = on; }
  cv::Mat render() const;

  // Smallest figure the layout fits in.
  static cv::Size minimumSize() { return {320, 240}; }

 private:
  cv::Size size_;
  std::string title_, x_label_, y_label_;
  std::vector<PlotSeries> series_;
  bool equal_aspect_ = false;
  bool y_from_zero_ = false;
};

// A "nice" tick step (1, 2 or 5 times a power of ten) for about `target`
// intervals over `range`.
double niceTickStep(double range, int target);

// Colours: kind kEstimate red shades, kOdometry green shades, index-th of its kind.
cv::Scalar seriesColour(EstimateKind kind, std::size_t index);

cv::Mat plotTrajectories(const TrajectoryReport& report, cv::Size size);
cv::Mat plotErrors(const TrajectoryReport& report, cv::Size size);

// Creates `dir` if needed; DataError naming it if that fails.
void ensurePlotDirectory(const std::filesystem::path& dir);

// Writes each image to its path and returns the paths; DataError naming the
// file if one cannot be written.
std::vector<std::filesystem::path> writePlotImages(
    const std::vector<std::pair<std::filesystem::path, cv::Mat>>& plots);

// Writes trajectory.png and error.png into `dir` (created if needed) and
// returns their paths. Throws DataError if they cannot be written.
std::vector<std::filesystem::path> writePlots(const std::filesystem::path& dir,
                                              const TrajectoryReport& report, cv::Size size);

}  // namespace vslam::eval
