#include "eval/plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "eval/errors.hpp"

namespace vslam::eval {
namespace {

const cv::Scalar kBlack(0, 0, 0);
const cv::Scalar kWhite(255, 255, 255);
const cv::Scalar kGrid(225, 225, 225);
const cv::Scalar kFrame(60, 60, 60);
const cv::Scalar kLandmarkBlue(220, 60, 0);
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kTickFontScale = 0.45;
constexpr double kLabelFontScale = 0.55;
constexpr double kTitleFontScale = 0.65;
// Sub-pixel drawing: OpenCV's fixed-point shift for lines and circles.
constexpr int kShift = 4;
constexpr double kSubpixel = 1 << kShift;

struct Range {
  double lo = std::numeric_limits<double>::infinity();
  double hi = -std::numeric_limits<double>::infinity();
  void add(double v) {
    if (!std::isfinite(v)) return;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
  bool valid() const { return lo <= hi; }
  double span() const { return hi - lo; }
  double mid() const { return 0.5 * (lo + hi); }
};

std::string tickLabel(double v, double step) {
  const int decimals = std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)));
  if (std::abs(v) < step * 1e-6) v = 0;  // no "-0"
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, v);
  return buf;
}

void putText(cv::Mat& img, const std::string& text, cv::Point org, double scale,
             const cv::Scalar& colour = kBlack, int thickness = 1) {
  cv::putText(img, text, org, kFont, scale, colour, thickness, cv::LINE_AA);
}

cv::Size textSize(const std::string& text, double scale, int thickness = 1) {
  int baseline = 0;
  return cv::getTextSize(text, kFont, scale, thickness, &baseline);
}

// Text rotated 90 degrees counter-clockwise, centred at `centre`.
void putVerticalText(cv::Mat& img, const std::string& text, cv::Point centre, double scale) {
  const cv::Size ts = textSize(text, scale);
  cv::Mat strip(ts.height + 8, ts.width + 4, img.type(), kWhite);
  putText(strip, text, {2, ts.height + 2}, scale);
  cv::Mat rotated;
  cv::rotate(strip, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
  cv::Rect dst(centre.x - rotated.cols / 2, centre.y - rotated.rows / 2, rotated.cols,
               rotated.rows);
  dst &= cv::Rect(0, 0, img.cols, img.rows);
  if (dst.area() > 0) rotated(cv::Rect(0, 0, dst.width, dst.height)).copyTo(img(dst));
}

// The plot area in the image and the data ranges it shows.
struct PlotAxes {
  cv::Rect area;
  Range xr, yr;
  // Data to pixels, relative to the plot area.
  cv::Point2d toPixel(const cv::Point2d& p) const {
    return cv::Point2d((p.x - xr.lo) / xr.span() * area.width,
                       area.height - (p.y - yr.lo) / yr.span() * area.height);
  }
};

// Ranges that hold every finite point with a margin (unit spans for
// degenerate data; metres alike on both axes with equal_aspect).
PlotAxes fitAxes(const std::vector<PlotSeries>& series, cv::Size size, bool equal_aspect,
                 bool y_from_zero) {
  const int left = 80, right = 20, top = 44, bottom = 60;
  PlotAxes axes;
  axes.area = cv::Rect(left, top, size.width - left - right, size.height - top - bottom);
  const cv::Rect& area = axes.area;
  Range& xr = axes.xr;
  Range& yr = axes.yr;
  for (const auto& s : series) {
    for (const auto& p : s.points) {
      if (std::isfinite(p.x) && std::isfinite(p.y)) {
        xr.add(p.x);
        yr.add(p.y);
      }
    }
  }
  if (!xr.valid()) xr.lo = 0, xr.hi = 1;
  if (!yr.valid()) yr.lo = 0, yr.hi = 1;
  if (y_from_zero) yr.lo = std::min(0.0, yr.lo);
  // Degenerate ranges (a single point, a straight line) get a unit span.
  if (xr.span() <= 0) xr.lo -= 0.5, xr.hi += 0.5;
  if (yr.span() <= 0) yr.hi += 1.0, yr.lo -= y_from_zero ? 0.0 : 1.0;
  {
    const double px = 0.04 * xr.span(), py = 0.04 * yr.span();
    xr.lo -= px, xr.hi += px;
    yr.hi += py;
    if (!(y_from_zero && yr.lo == 0)) yr.lo -= py;
  }
  if (equal_aspect) {
    const double ppm = std::min(area.width / xr.span(), area.height / yr.span());
    const double wx = area.width / ppm, wy = area.height / ppm;
    const double cx = xr.mid(), cy = yr.mid();
    xr.lo = cx - wx / 2, xr.hi = cx + wx / 2;
    yr.lo = cy - wy / 2, yr.hi = cy + wy / 2;
  }
  return axes;
}

void drawGrid(cv::Mat& img, const PlotAxes& axes) {
  const cv::Rect& area = axes.area;
  const Range& xr = axes.xr;
  const Range& yr = axes.yr;
  const double xstep = niceTickStep(xr.span(), std::max(2, area.width / 110));
  const double ystep = niceTickStep(yr.span(), std::max(2, area.height / 70));
  for (double x = std::ceil(xr.lo / xstep) * xstep; x <= xr.hi + 1e-9 * xstep; x += xstep) {
    const int px = area.x + static_cast<int>(std::lround(axes.toPixel({x, yr.lo}).x));
    cv::line(img, {px, area.y}, {px, area.y + area.height}, kGrid, 1);
    cv::line(img, {px, area.y + area.height}, {px, area.y + area.height + 5}, kFrame, 1);
    const std::string label = tickLabel(x, xstep);
    const cv::Size ts = textSize(label, kTickFontScale);
    putText(img, label, {px - ts.width / 2, area.y + area.height + 8 + ts.height}, kTickFontScale);
  }
  for (double y = std::ceil(yr.lo / ystep) * ystep; y <= yr.hi + 1e-9 * ystep; y += ystep) {
    const int py = area.y + static_cast<int>(std::lround(axes.toPixel({xr.lo, y}).y));
    cv::line(img, {area.x, py}, {area.x + area.width, py}, kGrid, 1);
    cv::line(img, {area.x - 5, py}, {area.x, py}, kFrame, 1);
    const std::string label = tickLabel(y, ystep);
    const cv::Size ts = textSize(label, kTickFontScale);
    putText(img, label, {area.x - 8 - ts.width, py + ts.height / 2}, kTickFontScale);
  }
}

// The data, clipped to the plot area by drawing into its ROI.
void drawSeries(cv::Mat& img, const PlotAxes& axes, const std::vector<PlotSeries>& series) {
  cv::Mat roi = img(axes.area);
  for (const auto& s : series) {
    if (s.style == PlotSeries::Style::kLine) {
      std::vector<cv::Point> pts;
      pts.reserve(s.points.size());
      for (const auto& p : s.points) {
        if (!std::isfinite(p.x) || !std::isfinite(p.y)) continue;
        const cv::Point2d q = axes.toPixel(p) * kSubpixel;
        pts.emplace_back(static_cast<int>(std::lround(q.x)), static_cast<int>(std::lround(q.y)));
      }
      if (pts.size() == 1) {
        cv::circle(roi, pts[0], static_cast<int>(s.thickness * kSubpixel), s.color, cv::FILLED,
                   cv::LINE_AA, kShift);
      } else if (pts.size() > 1) {
        cv::polylines(roi, pts, false, s.color, s.thickness, cv::LINE_AA, kShift);
      }
    } else {
      for (const auto& p : s.points) {
        if (!std::isfinite(p.x) || !std::isfinite(p.y)) continue;
        const cv::Point2d q = axes.toPixel(p) * kSubpixel;
        cv::circle(roi, {static_cast<int>(std::lround(q.x)), static_cast<int>(std::lround(q.y))},
                   static_cast<int>(s.radius * kSubpixel), s.color, s.thickness, cv::LINE_AA,
                   kShift);
      }
    }
  }
}

void drawTitleAndLabels(cv::Mat& img, const cv::Rect& area, const std::string& title,
                        const std::string& x_label, const std::string& y_label) {
  const cv::Size ts = textSize(title, kTitleFontScale);
  putText(img, title, {(img.cols - ts.width) / 2, 10 + ts.height}, kTitleFontScale);
  const cv::Size xs = textSize(x_label, kLabelFontScale);
  putText(img, x_label, {area.x + (area.width - xs.width) / 2, img.rows - 12}, kLabelFontScale);
  putVerticalText(img, y_label, {16, area.y + area.height / 2}, kLabelFontScale);
}

// The labelled series, top-left inside the plot area.
void drawLegend(cv::Mat& img, const cv::Rect& area, const std::vector<PlotSeries>& series) {
  std::vector<const PlotSeries*> entries;
  for (const auto& s : series) {
    if (!s.label.empty()) entries.push_back(&s);
  }
  if (entries.empty()) return;
  const int line_h = 20, sample_w = 30;
  int text_w = 0;
  for (const auto* s : entries) text_w = std::max(text_w, textSize(s->label, kTickFontScale).width);
  const cv::Rect box(area.x + 10, area.y + 10, sample_w + text_w + 24,
                     static_cast<int>(entries.size()) * line_h + 10);
  cv::rectangle(img, box, kWhite, cv::FILLED);
  cv::rectangle(img, box, kFrame, 1);
  for (std::size_t i = 0; i < entries.size(); ++i) {
    const int y = box.y + 5 + static_cast<int>(i) * line_h + line_h / 2;
    const int x = box.x + 8;
    if (entries[i]->style == PlotSeries::Style::kLine) {
      cv::line(img, {x, y}, {x + sample_w, y}, entries[i]->color, entries[i]->thickness,
               cv::LINE_AA);
    } else {
      cv::circle(img, {x + sample_w / 2, y}, std::min(entries[i]->radius, 7), entries[i]->color,
                 entries[i]->thickness, cv::LINE_AA);
    }
    putText(img, entries[i]->label, {x + sample_w + 8, y + 5}, kTickFontScale);
  }
}

}  // namespace

double niceTickStep(double range, int target) {
  if (!(range > 0) || target < 1) return 1.0;
  const double raw = range / target;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  const double r = raw / magnitude;
  const double nice = r <= 1.0 ? 1.0 : r <= 2.0 ? 2.0 : r <= 5.0 ? 5.0 : 10.0;
  return nice * magnitude;
}

Figure::Figure(cv::Size size, std::string title, std::string x_label, std::string y_label)
    : size_(size),
      title_(std::move(title)),
      x_label_(std::move(x_label)),
      y_label_(std::move(y_label)) {}

cv::Mat Figure::render() const {
  cv::Mat img(size_, CV_8UC3, kWhite);
  const PlotAxes axes = fitAxes(series_, size_, equal_aspect_, y_from_zero_);
  drawGrid(img, axes);
  drawSeries(img, axes, series_);
  cv::rectangle(img, axes.area, kFrame, 1);
  drawTitleAndLabels(img, axes.area, title_, x_label_, y_label_);
  drawLegend(img, axes.area, series_);
  return img;
}

cv::Scalar seriesColour(EstimateKind kind, std::size_t index) {
  static const cv::Scalar kReds[] = {{0, 0, 230}, {0, 128, 255}, {180, 0, 200}};
  static const cv::Scalar kGreens[] = {{0, 170, 0}, {0, 90, 0}, {140, 140, 0}};
  const auto& palette = kind == EstimateKind::kEstimate ? kReds : kGreens;
  return palette[index % 3];
}

namespace {

std::string seriesLabel(const EstimateEvaluation& e) {
  return e.name + " (" + toString(e.kind) + ")";
}

template <class Fn>
void forEachColoured(const TrajectoryReport& r, Fn fn) {
  std::size_t n_est = 0, n_odo = 0;
  for (const auto& e : r.estimates) {
    const std::size_t idx = e.kind == EstimateKind::kEstimate ? n_est++ : n_odo++;
    fn(e, seriesColour(e.kind, idx));
  }
}

}  // namespace

cv::Mat plotTrajectories(const TrajectoryReport& r, cv::Size size) {
  Figure fig(size, "Trajectories, top view (alignment " + toString(r.options.align) + ")", "x [m]",
             "y [m]");
  fig.setEqualAspect(true);
  PlotSeries ref{r.reference.name + " (reference)", kBlack, {}};
  for (const auto& p : r.reference.poses) ref.points.emplace_back(p.position.x(), p.position.y());
  // Odometry under the estimate, estimate on top (drawing order).
  std::vector<PlotSeries> odometry, estimates;
  forEachColoured(r, [&](const EstimateEvaluation& e, const cv::Scalar& colour) {
    PlotSeries s{seriesLabel(e), colour, {}};
    for (const auto& p : e.aligned.poses) s.points.emplace_back(p.position.x(), p.position.y());
    (e.kind == EstimateKind::kEstimate ? estimates : odometry).push_back(std::move(s));
  });
  fig.add(ref);
  for (auto& s : odometry) fig.add(std::move(s));
  for (auto& s : estimates) fig.add(std::move(s));
  if (!r.landmarks.empty()) {
    // Landmarks are in the map frame of the (first) SLAM estimate.
    Similarity map_to_ref;
    for (const auto& e : r.estimates) {
      if (e.kind == EstimateKind::kEstimate) {
        map_to_ref = e.ate.alignment;
        break;
      }
    }
    PlotSeries lm{"landmarks (" + std::to_string(r.landmarks.size()) + ")", kLandmarkBlue, {}};
    lm.style = PlotSeries::Style::kCircles;
    for (const auto& l : r.landmarks) {
      const Eigen::Vector3d p = map_to_ref.apply(Eigen::Vector3d(l.x, l.y, 0));
      lm.points.emplace_back(p.x(), p.y());
    }
    fig.add(lm);
  }
  if (!r.reference.empty()) {
    PlotSeries start{"", kBlack, {}};
    start.style = PlotSeries::Style::kCircles;
    start.radius = 3;
    start.thickness = cv::FILLED;
    start.points.emplace_back(r.reference.poses.front().position.x(),
                              r.reference.poses.front().position.y());
    fig.add(start);
  }
  return fig.render();
}

cv::Mat plotErrors(const TrajectoryReport& r, cv::Size size) {
  Figure fig(size, "Position error after alignment " + toString(r.options.align),
             "time since start of " + r.reference.name + " [s]", "position error [m]");
  fig.setYFromZero(true);
  const double t0 = r.reference.empty() ? 0.0 : r.reference.poses.front().t;
  std::vector<PlotSeries> odometry, estimates;
  forEachColoured(r, [&](const EstimateEvaluation& e, const cv::Scalar& colour) {
    PlotSeries s{seriesLabel(e), colour, {}};
    for (std::size_t i = 0; i < e.ate.errors.size(); ++i) {
      s.points.emplace_back(e.error_times[i] - t0, e.ate.errors[i]);
    }
    (e.kind == EstimateKind::kEstimate ? estimates : odometry).push_back(std::move(s));
  });
  for (auto& s : odometry) fig.add(std::move(s));
  for (auto& s : estimates) fig.add(std::move(s));
  return fig.render();
}

void ensurePlotDirectory(const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec || !std::filesystem::is_directory(dir)) {
    throw DataError(dir.string() + ": cannot create plot directory" +
                    (ec ? ": " + ec.message() : std::string()));
  }
}

std::vector<std::filesystem::path> writePlotImages(
    const std::vector<std::pair<std::filesystem::path, cv::Mat>>& plots) {
  std::vector<std::filesystem::path> written;
  for (const auto& [path, img] : plots) {
    bool ok = false;
    try {
      ok = cv::imwrite(path.string(), img);
    } catch (const cv::Exception& e) {
      throw DataError(path.string() + ": cannot write plot: " + e.what());
    }
    if (!ok) throw DataError(path.string() + ": cannot write plot");
    written.push_back(path);
  }
  return written;
}

std::vector<std::filesystem::path> writePlots(const std::filesystem::path& dir,
                                              const TrajectoryReport& report, cv::Size size) {
  ensurePlotDirectory(dir);
  return writePlotImages({{dir / "trajectory.png", plotTrajectories(report, size)},
                          {dir / "error.png", plotErrors(report, size)}});
}

}  // namespace vslam::eval
