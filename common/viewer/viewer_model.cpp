#include "viewer/viewer_model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <utility>

namespace vslam::viewer {
namespace {

const cv::Scalar kBackground(255, 255, 255), kGrid(235, 235, 235), kText(30, 30, 30);
const cv::Scalar kTruth(0, 0, 0), kOdometry(150, 150, 150), kEstimate(200, 90, 20);
const cv::Scalar kLandmark(30, 30, 220), kNominal(60, 170, 60), kDual(200, 60, 200);
const cv::Scalar kAppearance(0, 160, 255), kBest(0, 0, 255);
constexpr int kHealthLineHeight = 28;
constexpr double kMatchRatio = 0.8;    // Lowe's ratio test for the matches shown
constexpr double kMeasurementAge = 1;  // s: a measurement older than its image is not shown
constexpr int kFeaturesShown = 500;
constexpr double kMaxExtentM = 1e4;  // the view never spans more

std::string format(const char* fmt, double a, double b = 0, double c = 0) {
  char buf[160];
  std::snprintf(buf, sizeof(buf), fmt, a, b, c);
  return buf;
}

// Map frame (metres, y up) to pixels of the top view.
struct View {
  double scale = 1, cx = 0, cy = 0;
  cv::Rect area;
  cv::Point px(double x, double y) const {
    // Far outside (or not a number: values come from the network) is drawn
    // nowhere; the clamp keeps the cast to int defined.
    const auto pixel = [](double v) {
      return static_cast<int>(std::lround(std::isfinite(v) ? std::clamp(v, -1e6, 1e6) : -1e6));
    };
    return {area.x + pixel(area.width / 2.0 + (x - cx) * scale),
            area.y + pixel(area.height / 2.0 - (y - cy) * scale)};
  }
};

void text(cv::Mat& img, const std::string& s, cv::Point at, double size = 0.45,
          const cv::Scalar& colour = kText) {
  cv::putText(img, s, at, cv::FONT_HERSHEY_SIMPLEX, size, colour, 1, cv::LINE_AA);
}

void polyline(cv::Mat& img, const View& v, const std::vector<cv::Point2d>& pts,
              const cv::Scalar& colour, int thickness) {
  if (pts.size() < 2) return;
  std::vector<cv::Point> p;
  p.reserve(pts.size());
  for (const auto& q : pts) p.push_back(v.px(q.x, q.y));
  cv::polylines(img, p, false, colour, thickness, cv::LINE_AA);
}

template <class Container>
std::vector<cv::Point2d> points(const Container& poses) {
  std::vector<cv::Point2d> out;
  out.reserve(poses.size());
  for (const auto& p : poses) out.emplace_back(p.x, p.y);
  return out;
}

bool finite(double x, double y) { return std::isfinite(x) && std::isfinite(y); }

}  // namespace

ViewerModel::ViewerModel() : sift_(cv::SIFT::create(kFeaturesShown)) {}

void ViewerModel::append(std::deque<Pose>& trajectory, const Pose& p) {
  if (!finite(p.x, p.y)) return;
  trajectory.push_back(p);
  if (trajectory.size() > kMaxTrajectoryPoints) {
    // Thin the older half to every other point.
    std::deque<Pose> thinned;
    const size_t half = trajectory.size() / 2;
    for (size_t i = 0; i < trajectory.size(); ++i) {
      if (i >= half || i % 2 == 0) thinned.push_back(trajectory[i]);
    }
    trajectory.swap(thinned);
  }
}

void ViewerModel::addEstimate(const Pose& p, bool kidnapped, double effective_sample_size) {
  append(estimate_, p);
  status_.kidnapped = kidnapped;
  status_.effective_sample_size = effective_sample_size;
  setTime(p.t);
}

void ViewerModel::addOdometry(const Pose& p) {
  append(odometry_, p);
  setTime(p.t);
}

void ViewerModel::addGroundTruth(const Pose& p) {
  append(ground_truth_, p);
  setTime(p.t);
}

void ViewerModel::setMap(std::vector<Landmark> landmarks) {
  landmarks_ = std::move(landmarks);
  status_.landmarks = static_cast<int>(landmarks_.size());
}

void ViewerModel::setParticles(std::vector<Particle> particles) {
  particles_ = std::move(particles);
}

void ViewerModel::setAppearanceMap(std::map<int64_t, AppearanceState> states,
                                   std::vector<std::pair<int64_t, int64_t>> links) {
  appearance_states_ = std::move(states);
  appearance_links_ = std::move(links);
  status_.appearance_states = static_cast<int>(appearance_states_.size());
}

void ViewerModel::setAppearanceBest(int64_t state_id, double belief, int hypotheses) {
  appearance_best_ = state_id;
  status_.appearance_belief = belief;
  status_.appearance_hypotheses = hypotheses;
}

void ViewerModel::setImage(const std::string& camera, const cv::Mat& gray, double t) {
  Camera& c = cameras_[camera];
  c.gray = gray.clone();
  c.t = t;
  c.features_found = false;
  setTime(t);
}

void ViewerModel::setLandmarkDescriptors(int64_t landmark_id, const cv::Mat& descriptors) {
  cv::Mat d;
  descriptors.convertTo(d, CV_32F);
  landmark_descriptors_[landmark_id] = d;
}

void ViewerModel::removeLandmark(int64_t landmark_id) { landmark_descriptors_.erase(landmark_id); }

void ViewerModel::addMeasurement(const std::string& camera, int64_t landmark_id, bool accepted,
                                 double t) {
  (accepted ? status_.measurements_accepted : status_.measurements_rejected) += 1;
  Camera& c = cameras_[camera];
  c.measured_landmark = landmark_id;
  c.measured_t = t;
  c.measured_accepted = accepted;
  c.features_found = false;  // the matches change
}

std::vector<std::string> ViewerModel::cameras() const {
  std::vector<std::string> names;
  for (const auto& [name, c] : cameras_) {
    if (!c.gray.empty()) names.push_back(name);
  }
  return names;
}

std::vector<Pose> ViewerModel::alignedGroundTruth() const {
  std::vector<Pose> out;
  if (estimate_.empty() || ground_truth_.empty()) return out;
  const Pose& e0 = estimate_.front();
  const Pose& g0 = *std::min_element(
      ground_truth_.begin(), ground_truth_.end(),
      [&](const Pose& a, const Pose& b) { return std::abs(a.t - e0.t) < std::abs(b.t - e0.t); });
  const double c = std::cos(e0.theta - g0.theta), s = std::sin(e0.theta - g0.theta);
  out.reserve(ground_truth_.size());
  for (const Pose& g : ground_truth_) {
    const double dx = g.x - g0.x, dy = g.y - g0.y;
    out.push_back(
        {g.t, e0.x + c * dx - s * dy, e0.y + s * dx + c * dy, g.theta + e0.theta - g0.theta});
  }
  return out;
}

void ViewerModel::findFeatures(Camera& c) {
  c.features_found = true;
  c.features.clear();
  c.matched.clear();
  c.descriptors.release();
  if (c.gray.empty()) return;
  sift_->detectAndCompute(c.gray, cv::noArray(), c.features, c.descriptors);
  const auto it = landmark_descriptors_.find(c.measured_landmark);
  if (it == landmark_descriptors_.end() || it->second.rows < 2 || c.descriptors.empty() ||
      std::abs(c.measured_t - c.t) > kMeasurementAge) {
    return;
  }
  cv::BFMatcher matcher(cv::NORM_L2);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(c.descriptors, it->second, knn, 2);
  for (const auto& m : knn) {
    if (m.size() == 2 && m[0].distance < kMatchRatio * m[1].distance) {
      c.matched.push_back(c.features[static_cast<size_t>(m[0].queryIdx)]);
    }
  }
}

void ViewerModel::drawTopView(cv::Mat& img) {
  const std::vector<Pose> truth = alignedGroundTruth();
  View v;
  v.area = cv::Rect(0, 0, img.cols, img.rows);
  double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
  const auto grow = [&](double x, double y) {
    // A home is not kilometres wide: such values (from the network) do not
    // set the view.
    if (!finite(x, y) || std::abs(x) > kMaxExtentM || std::abs(y) > kMaxExtentM) return;
    x0 = std::min(x0, x);
    x1 = std::max(x1, x);
    y0 = std::min(y0, y);
    y1 = std::max(y1, y);
  };
  for (const auto& p : estimate_) grow(p.x, p.y);
  if (!estimate_.empty()) {  // room for the heading arrow
    const Pose& p = estimate_.back();
    grow(p.x + 0.5 * std::cos(p.theta), p.y + 0.5 * std::sin(p.theta));
  }
  for (const auto& p : odometry_) grow(p.x, p.y);
  for (const auto& p : truth) grow(p.x, p.y);
  for (const auto& l : landmarks_) grow(l.x, l.y);
  for (const auto& p : particles_) grow(p.x, p.y);
  for (const auto& [id, s] : appearance_states_) grow(s.x, s.y);
  if (!(x1 >= x0)) x0 = y0 = -1, x1 = y1 = 1;
  const double span_x = std::max(x1 - x0, 2.0) * 1.1, span_y = std::max(y1 - y0, 2.0) * 1.1;
  v.scale = std::min((img.cols - 20) / span_x, (img.rows - 20) / span_y);
  v.cx = (x0 + x1) / 2;
  v.cy = (y0 + y1) / 2;

  // A grid of 1 m (5 m when a metre is under 12 pixels, 100 m under 1).
  const double step = v.scale >= 12 ? 1.0 : v.scale >= 1 ? 5.0 : 100.0;
  const double half_w = img.cols / (2 * v.scale), half_h = img.rows / (2 * v.scale);
  for (double gx = std::floor((v.cx - half_w) / step) * step; gx <= v.cx + half_w; gx += step) {
    cv::line(img, v.px(gx, v.cy - half_h), v.px(gx, v.cy + half_h), kGrid, 1);
  }
  for (double gy = std::floor((v.cy - half_h) / step) * step; gy <= v.cy + half_h; gy += step) {
    cv::line(img, v.px(v.cx - half_w, gy), v.px(v.cx + half_w, gy), kGrid, 1);
  }

  for (const auto& [from, to] : appearance_links_) {
    const auto a = appearance_states_.find(from), b = appearance_states_.find(to);
    if (a == appearance_states_.end() || b == appearance_states_.end()) continue;
    cv::line(img, v.px(a->second.x, a->second.y), v.px(b->second.x, b->second.y), kAppearance, 1,
             cv::LINE_AA);
  }
  for (const auto& [id, s] : appearance_states_) {
    const cv::Point p = v.px(s.x, s.y);
    const int r = id == appearance_best_ ? 5 : 2;
    cv::rectangle(img, p - cv::Point(r, r), p + cv::Point(r, r),
                  id == appearance_best_ ? kBest : kAppearance, id == appearance_best_ ? 2 : -1);
  }
  polyline(img, v, points(truth), kTruth, 2);
  polyline(img, v, points(odometry_), kOdometry, 1);
  polyline(img, v, points(estimate_), kEstimate, 2);
  for (const auto& p : particles_) {
    if (finite(p.x, p.y)) cv::circle(img, v.px(p.x, p.y), 1, p.dual ? kDual : kNominal, -1);
  }
  for (const auto& l : landmarks_) {
    if (!finite(l.x, l.y)) continue;
    const cv::Point c = v.px(l.x, l.y);
    // The 2-sigma ellipse of the position covariance.
    const double tr = l.cxx + l.cyy, det = l.cxx * l.cyy - l.cxy * l.cxy;
    const double disc = std::sqrt(std::max(0.0, tr * tr / 4 - det));
    const double e1 = std::max(0.0, tr / 2 + disc), e2 = std::max(0.0, tr / 2 - disc);
    const double angle = 0.5 * std::atan2(2 * l.cxy, l.cxx - l.cyy) * 180 / M_PI;
    if (std::isfinite(e1) && std::isfinite(angle)) {
      const int a = std::clamp(static_cast<int>(2 * std::sqrt(e1) * v.scale), 1, img.cols);
      const int b = std::clamp(static_cast<int>(2 * std::sqrt(e2) * v.scale), 1, img.cols);
      cv::ellipse(img, c, cv::Size(a, b), -angle, 0, 360, kLandmark, 1, cv::LINE_AA);
    }
    cv::drawMarker(img, c, kLandmark, cv::MARKER_CROSS, 9, 2);
  }
  if (!estimate_.empty()) {
    const Pose& p = estimate_.back();
    const cv::Point c = v.px(p.x, p.y);
    const cv::Point tip = v.px(p.x + 0.4 * std::cos(p.theta), p.y + 0.4 * std::sin(p.theta));
    cv::circle(img, c, 6, kEstimate, 2, cv::LINE_AA);
    cv::arrowedLine(img, c, tip, kEstimate, 2, cv::LINE_AA, 0, 0.3);
  }
  // Legend and scale.
  const std::pair<const char*, cv::Scalar> legend[] = {
      {"estimate", kEstimate},        {"odometry only", kOdometry},
      {"ground truth", kTruth},       {"landmark, 2-sigma", kLandmark},
      {"particles / dual", kNominal}, {"appearance states", kAppearance}};
  int y = 18;
  for (const auto& [label, colour] : legend) {
    cv::line(img, {8, y - 4}, {26, y - 4}, colour, 3);
    text(img, label, {32, y}, 0.42);
    y += 17;
  }
  text(img, format("grid %.0f m", step), {8, img.rows - 8}, 0.42);
  if (status_.kidnapped) text(img, "KIDNAPPED: relocalizing", {img.cols / 2 - 110, 24}, 0.7, kBest);
}

void ViewerModel::drawCamera(cv::Mat& panel, const std::string& name, Camera& c) {
  if (!c.features_found) findFeatures(c);
  cv::Mat bgr;
  cv::cvtColor(c.gray, bgr, cv::COLOR_GRAY2BGR);
  const int caption = 36;
  const double s = std::min(panel.cols / static_cast<double>(bgr.cols),
                            (panel.rows - caption) / static_cast<double>(bgr.rows));
  cv::Mat shown;
  cv::resize(bgr, shown, cv::Size(), s, s, cv::INTER_AREA);
  for (const auto& k : c.features) {
    cv::circle(shown, k.pt * s, 2, cv::Scalar(0, 200, 255), 1, cv::LINE_AA);
  }
  for (const auto& k : c.matched) {
    cv::circle(shown, k.pt * s, 5, cv::Scalar(0, 220, 0), 2, cv::LINE_AA);
  }
  shown.copyTo(panel(cv::Rect(0, caption, shown.cols, shown.rows)));
  text(panel,
       name + format("  t %.1f s  %.0f SIFT features", c.t, static_cast<double>(c.features.size())),
       {4, 14});
  if (c.measured_landmark >= 0 && std::abs(c.measured_t - c.t) <= kMeasurementAge) {
    text(panel,
         format("landmark %.0f: %.0f matches", static_cast<double>(c.measured_landmark),
                static_cast<double>(c.matched.size())) +
             (c.measured_accepted ? " (accepted)" : " (rejected by the pre-filter)"),
         {4, 30}, 0.45, c.measured_accepted ? cv::Scalar(0, 150, 0) : kBest);
  } else {
    text(panel, "no landmark measured", {4, 30}, 0.45, kOdometry);
  }
}

cv::Mat ViewerModel::render(cv::Size size) {
  size.width = std::max(size.width, 640);
  size.height = std::max(size.height, 360);
  cv::Mat frame(size, CV_8UC3, kBackground);
  const std::vector<std::string> cams = cameras();
  const int panel_w = cams.empty() ? 0 : size.width / 3;
  const int body_h = size.height - kHealthLineHeight;
  cv::Mat top = frame(cv::Rect(0, 0, size.width - panel_w, body_h));
  drawTopView(top);
  for (size_t i = 0; i < cams.size(); ++i) {
    const int h = body_h / static_cast<int>(cams.size());
    cv::Mat panel = frame(cv::Rect(size.width - panel_w, static_cast<int>(i) * h, panel_w, h));
    drawCamera(panel, cams[i], cameras_[cams[i]]);
    cv::rectangle(frame, cv::Rect(size.width - panel_w, static_cast<int>(i) * h, panel_w, h),
                  kGrid);
  }
  // The health line.
  cv::Mat line = frame(cv::Rect(0, body_h, size.width, kHealthLineHeight));
  line.setTo(cv::Scalar(245, 245, 245));
  const int64_t judged = status_.measurements_accepted + status_.measurements_rejected;
  std::string h = format("t %.1f s", time_);
  h += status_.effective_sample_size >= 0 ? format("  |  ESS %.0f", status_.effective_sample_size)
                                          : std::string("  |  no estimate yet");
  h += std::string("  |  kidnapped ") + (status_.kidnapped ? "yes" : "no");
  h += format("  |  landmarks %.0f", status_.landmarks);
  if (judged > 0) {
    h += format("  |  pre-filter rejected %.1f%% of %.0f",
                100.0 * static_cast<double>(status_.measurements_rejected) / judged,
                static_cast<double>(judged));
  }
  if (status_.appearance_states > 0) {
    h +=
        format("  |  appearance %.0f states, %.0f hypotheses, belief %.2f",
               status_.appearance_states, status_.appearance_hypotheses, status_.appearance_belief);
  }
  text(line, h, {8, 19}, 0.5);
  return frame;
}

}  // namespace vslam::viewer
