#pragma once
// What vslam-viewer shows, and how it draws it (no LCM: the command line
// decodes the bus or a log into these calls; tests make them directly).
//
// One frame is a top-down view of the map frame (landmarks with their 2-sigma
// ellipses, the particle cloud, the estimated, odometry-only and ground-truth
// trajectories, the appearance-SLAM states, links and most believed state),
// beside it each camera's newest image with its SIFT features and those that
// match the landmark it last measured, and a health line below.
//
// The ground truth lives in the world's frame; it is drawn moved rigidly so
// that its pose at the estimate's first time is the estimate's first pose
// (vslam-eval --align origin). Trajectories keep at most kMaxTrajectoryPoints
// points (older ones thinned), so the cost of a frame does not grow with the
// length of a run.

#include <cstdint>
#include <deque>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <optional>
#include <string>
#include <vector>

namespace vslam::viewer {

struct Pose {
  double t = 0;  // seconds
  double x = 0, y = 0, theta = 0;
};

struct Landmark {
  int64_t id = 0;
  double x = 0, y = 0;
  double cxx = 0, cxy = 0, cyy = 0;  // position covariance, m^2
};

struct Particle {
  double x = 0, y = 0, theta = 0, weight = 0;
  bool dual = false;
};

struct AppearanceState {
  double x = 0, y = 0;  // odometry frame
};

// The figures of the health line.
struct Status {
  double effective_sample_size = -1;
  bool kidnapped = false;
  int landmarks = 0;
  int64_t measurements_accepted = 0, measurements_rejected = 0;
  int appearance_states = 0, appearance_hypotheses = 0;
  double appearance_belief = 0;
};

inline constexpr size_t kMaxTrajectoryPoints = 20000;

class ViewerModel {
 public:
  ViewerModel();

  void setTime(double t) { time_ = std::max(time_, t); }
  double time() const { return time_; }

  void addEstimate(const Pose& p, bool kidnapped, double effective_sample_size);
  void addOdometry(const Pose& p);
  void addGroundTruth(const Pose& p);
  void setMap(std::vector<Landmark> landmarks);
  void setParticles(std::vector<Particle> particles);
  void setAppearanceMap(std::map<int64_t, AppearanceState> states,
                        std::vector<std::pair<int64_t, int64_t>> links);
  void setAppearanceBest(int64_t state_id, double belief, int hypotheses);
  // A camera's newest image (8-bit gray); its features are found when drawn.
  void setImage(const std::string& camera, const cv::Mat& gray, double t);
  // A landmark's SIFT descriptors (one row each, CV_8U or CV_32F), for matches.
  void setLandmarkDescriptors(int64_t landmark_id, const cv::Mat& descriptors);
  void removeLandmark(int64_t landmark_id);
  // A visual measurement of `landmark_id` by `camera`; `accepted` by the pre-filter.
  void addMeasurement(const std::string& camera, int64_t landmark_id, bool accepted, double t);

  const std::deque<Pose>& estimate() const { return estimate_; }
  const std::deque<Pose>& odometry() const { return odometry_; }
  const std::deque<Pose>& groundTruth() const { return ground_truth_; }
  const std::vector<Landmark>& landmarks() const { return landmarks_; }
  const std::vector<Particle>& particles() const { return particles_; }
  const Status& status() const { return status_; }
  std::vector<std::string> cameras() const;

  // The ground truth in the map frame (see above); empty without both.
  std::vector<Pose> alignedGroundTruth() const;

  // The whole frame, `size` pixels (at least 640x360).
  cv::Mat render(cv::Size size);

 private:
  struct Camera {
    cv::Mat gray;
    double t = 0;
    bool features_found = false;
    std::vector<cv::KeyPoint> features;
    cv::Mat descriptors;
    int64_t measured_landmark = -1;
    double measured_t = 0;
    bool measured_accepted = false;
    std::vector<cv::KeyPoint> matched;
  };
  void findFeatures(Camera& c);
  void drawTopView(cv::Mat& canvas);
  void drawCamera(cv::Mat& panel, const std::string& name, Camera& c);
  static void append(std::deque<Pose>& trajectory, const Pose& p);

  double time_ = 0;
  std::deque<Pose> estimate_, odometry_, ground_truth_;
  std::vector<Landmark> landmarks_;
  std::vector<Particle> particles_;
  std::map<int64_t, AppearanceState> appearance_states_;
  std::vector<std::pair<int64_t, int64_t>> appearance_links_;
  int64_t appearance_best_ = -1;
  Status status_;
  std::map<std::string, Camera> cameras_;
  std::map<int64_t, cv::Mat> landmark_descriptors_;
  cv::Ptr<cv::Feature2D> sift_;
};

}  // namespace vslam::viewer
