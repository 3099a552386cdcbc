#include "eval/tum_import.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <tuple>
#include <vslam/camera_calibration_t.hpp>
#include <vslam/ground_truth_pose_t.hpp>
#include <vslam/image_t.hpp>
#include <vslam/odometry_t.hpp>

#include "bus/log_writer.hpp"
#include "bus/messages.hpp"
#include "config/robot_config.hpp"
#include "eval/errors.hpp"
#include "eval/tum_file.hpp"
#include "util/angles.hpp"
#include "util/log.hpp"
#include "util/progress.hpp"
#include "util/statistics.hpp"

namespace vslam::eval {
namespace {

namespace fs = std::filesystem;

int64_t toUtime(double seconds) { return static_cast<int64_t>(std::llround(seconds * 1e6)); }

std::string upper(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::string sizeText(const cv::Size& s) {
  return std::to_string(s.width) + "x" + std::to_string(s.height);
}

struct ImageEntry {
  double t = 0;
  std::string filename;  // as in the list
  int line = 0;
};

std::vector<ImageEntry> readImageList(const fs::path& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec))
    throw DataError(file.string() + ": no such file (image list)");
  std::ifstream in(file);
  if (!in) throw DataError(file.string() + ": cannot open for reading");
  std::vector<ImageEntry> out;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (isTumCommentOrBlank(line)) continue;
    const auto fields = splitTumFields(line);
    const std::string where = file.string() + ":" + std::to_string(line_no) + ": ";
    if (fields.size() != 2) {
      throw DataError(where + "expected 'timestamp filename', found " +
                      std::to_string(fields.size()) + " fields");
    }
    char* end = nullptr;
    const double t = std::strtod(fields[0].c_str(), &end);
    if (end != fields[0].c_str() + fields[0].size() || !std::isfinite(t)) {
      throw DataError(where + "timestamp '" + fields[0] + "' is not a number");
    }
    out.push_back({t, fields[1], line_no});
  }
  if (out.empty()) throw DataError(file.string() + ": lists no images");
  std::stable_sort(out.begin(), out.end(),
                   [](const ImageEntry& a, const ImageEntry& b) { return a.t < b.t; });
  return out;
}

// The shared OpenCV calibration reader, with its errors as data errors.
config::CameraIntrinsics readCalibration(const fs::path& file) {
  try {
    return config::readOpenCvCalibration(file);
  } catch (const config::ConfigError& e) {
    throw DataError(e.what());
  }
}

// Reads one listed image as 8-bit gray or BGR.
cv::Mat loadImage(const fs::path& dir, const fs::path& list, const ImageEntry& e) {
  const fs::path path = dir / e.filename;
  const std::string where =
      list.string() + ":" + std::to_string(e.line) + ": image '" + e.filename + "'";
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) throw DataError(where + ": no such file " + path.string());
  cv::Mat img;
  try {
    img = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception& ex) {
    throw DataError(where + ": unreadable: " + ex.what());
  }
  if (img.empty()) throw DataError(where + ": unreadable (not a PNG/JPEG image, or damaged)");
  if (img.depth() != CV_8U) {
    throw DataError(where + ": has " + std::to_string(img.elemSize1() * 8) +
                    "-bit samples; only 8-bit images are supported");
  }
  if (img.channels() == 4) {
    cv::cvtColor(img, img, cv::COLOR_BGRA2BGR);
  } else if (img.channels() == 2) {
    cv::Mat planes[2];
    cv::split(img, planes);
    img = planes[0];  // gray + alpha
  } else if (img.channels() != 1 && img.channels() != 3) {
    throw DataError(where + ": has " + std::to_string(img.channels()) + " channels");
  }
  return img;
}

template <class Msg>
std::vector<uint8_t> encode(const Msg& msg) {
  std::vector<uint8_t> buf(static_cast<std::size_t>(msg.getEncodedSize()));
  msg.encode(buf.data(), 0, static_cast<int>(buf.size()));
  return buf;
}

// Kinds in the order they are written at equal timestamps.
enum class Kind { kCalibration = 0, kGroundTruth = 1, kOdometry = 2, kImage = 3 };

struct Pending {
  int64_t utime;
  Kind kind;
  std::size_t index;
};

// Removes the partial output unless released.
class PartialFile {
 public:
  explicit PartialFile(fs::path p) : path_(std::move(p)) {}
  ~PartialFile() {
    if (!path_.empty()) {
      std::error_code ec;
      fs::remove(path_, ec);
    }
  }
  void release() { path_.clear(); }

 private:
  fs::path path_;
};

// What an import reads, all checked before anything is written.
struct ImportInputs {
  fs::path list_file, image_dir;
  std::vector<ImageEntry> images;
  Trajectory ground_truth;
  std::optional<Trajectory> odometry;
  config::CameraIntrinsics calibration;
  cv::Mat first_image;  // sets the source size
};

ImportInputs readInputs(const ImportOptions& o) {
  ImportInputs in;
  in.list_file = o.rgb_list.value_or(o.dataset / "rgb.txt");
  in.images = readImageList(in.list_file);
  in.image_dir = o.rgb_list ? in.list_file.parent_path() : o.dataset;
  in.ground_truth = readTumFile(o.groundtruth.value_or(o.dataset / "groundtruth.txt"));
  if (o.odometry) in.odometry = readTumFile(*o.odometry);
  in.calibration = readCalibration(o.calibration);
  in.first_image = loadImage(in.image_dir, in.list_file, in.images.front());
  return in;
}

// The written size must be the robot camera's, and the calibration must
// refer to the written size or to the source size (then it is rescaled).
// Returns the intrinsics of the written images.
config::CameraIntrinsics writtenIntrinsics(const ImportOptions& o, const ImportInputs& in,
                                           cv::Size source_size, cv::Size image_size) {
  if (o.robot_camera) {
    const cv::Size robot_size(o.robot_camera->width, o.robot_camera->height);
    if (robot_size != image_size) {
      throw DataError("the images are " + sizeText(source_size) +
                      (o.resize ? " resized to " + sizeText(*o.resize) : std::string()) +
                      ", but camera '" + o.robot_camera->name + "' in " + o.robot_file.string() +
                      " is " + sizeText(robot_size) +
                      " (its front-end would drop every frame); use --resize " +
                      sizeText(robot_size) + " (the intrinsics are rescaled) or a --config " +
                      "whose robot file is for " + sizeText(image_size));
    }
  }
  const config::CameraIntrinsics& calib = in.calibration;
  const cv::Size calib_size(calib.width, calib.height);
  config::CameraIntrinsics out_calib = calib;
  if (calib_size == image_size) return out_calib;
  if (calib_size != source_size) {
    throw DataError(o.calibration.string() + ": is for " + sizeText(calib_size) +
                    " images, but the images are " + sizeText(source_size) +
                    (o.resize ? " (resized to " + sizeText(*o.resize) + ")" : std::string()));
  }
  const double sx = static_cast<double>(image_size.width) / source_size.width;
  const double sy = static_cast<double>(image_size.height) / source_size.height;
  // cv::resize maps pixel centres: u' + 0.5 = s (u + 0.5).
  out_calib.fx *= sx;
  out_calib.fy *= sy;
  out_calib.cx = (calib.cx + 0.5) * sx - 0.5;
  out_calib.cy = (calib.cy + 0.5) * sy - 0.5;
  out_calib.width = image_size.width;
  out_calib.height = image_size.height;
  return out_calib;
}

// --frame-rate, else 1 / the median interval of the image list (0 for one image).
double nominalFrameRate(const ImportOptions& o, const std::vector<ImageEntry>& images) {
  if (o.frame_rate_hz > 0) return o.frame_rate_hz;
  if (images.size() < 2) return 0.0;
  std::vector<double> dt;
  for (std::size_t i = 1; i < images.size(); ++i) dt.push_back(images[i].t - images[i - 1].t);
  const double typical = upperMedian(&dt);
  return typical > 0 ? 1.0 / typical : 0.0;
}

// The camera as the calibration messages describe it: written intrinsics, extrinsics, channels.
config::CameraConfig importedCamera(const ImportOptions& o, const config::CameraIntrinsics& calib,
                                    const ImportStats& stats) {
  config::CameraConfig camera;
  camera.name = o.camera;
  camera.width = calib.width;
  camera.height = calib.height;
  camera.fx = calib.fx;
  camera.fy = calib.fy;
  camera.cx = calib.cx;
  camera.cy = calib.cy;
  camera.distortion = calib.distortion;
  camera.frame_rate_hz = stats.frame_rate_hz;
  camera.robot_T_camera = Eigen::Isometry3d::Identity();
  camera.robot_T_camera.linear() = config::robotRotationCamera(
      degToRad(o.camera_yaw_pitch_roll_deg[0]), degToRad(o.camera_yaw_pitch_roll_deg[1]),
      degToRad(o.camera_yaw_pitch_roll_deg[2]));
  camera.robot_T_camera.translation() = o.camera_position_m;
  camera.image_channel = stats.image_channel;
  camera.calibration_channel = stats.calibration_channel;
  return camera;
}

// Every event to write, in time order (at equal times, by Kind).
std::vector<Pending> scheduleEvents(const ImportOptions& o, const ImportInputs& in) {
  std::vector<Pending> schedule;
  for (std::size_t i = 0; i < in.images.size(); ++i) {
    schedule.push_back({toUtime(in.images[i].t), Kind::kImage, i});
  }
  for (std::size_t i = 0; i < in.ground_truth.size(); ++i) {
    schedule.push_back({toUtime(in.ground_truth.poses[i].t), Kind::kGroundTruth, i});
  }
  if (in.odometry) {
    for (std::size_t i = 0; i < in.odometry->size(); ++i) {
      schedule.push_back({toUtime(in.odometry->poses[i].t), Kind::kOdometry, i});
    }
  }
  const int64_t first_image = toUtime(in.images.front().t);
  const int64_t last_image = toUtime(in.images.back().t);
  const int64_t period = std::max<int64_t>(1, toUtime(o.calibration_period_s));
  std::size_t n_calib = 0;
  for (int64_t t = first_image; t <= last_image; t += period) {
    schedule.push_back({t, Kind::kCalibration, n_calib++});
  }
  std::stable_sort(schedule.begin(), schedule.end(), [](const Pending& a, const Pending& b) {
    return std::make_tuple(a.utime, static_cast<int>(a.kind), a.index) <
           std::make_tuple(b.utime, static_cast<int>(b.kind), b.index);
  });
  return schedule;
}

vslam::ground_truth_pose_t groundTruthMessage(const ImportOptions& o, const Trajectory& gt,
                                              const Pending& ev,
                                              const Eigen::Isometry3d& camera_T_robot) {
  Eigen::Isometry3d world_T_base = gt.poses[ev.index].isometry();
  if (o.groundtruth_is_camera) world_T_base = world_T_base * camera_T_robot;
  const PlanarPose p = planarFromPose(world_T_base, o.floor);
  vslam::ground_truth_pose_t m{};
  m.utime = ev.utime;
  m.seq = static_cast<int64_t>(ev.index);
  m.x = p.x;
  m.y = p.y;
  m.z = p.z;
  m.theta = p.theta;
  return m;
}

// Odometry from the base trajectory; *distance and *rotation accumulate
// the path's length and turning since the first reading.
vslam::odometry_t odometryMessage(const Trajectory& odometry, const Pending& ev, double* distance,
                                  double* rotation) {
  const auto& poses = odometry.poses;
  const PlanarPose p = planarFromPose(poses[ev.index].isometry(), FloorAxes::kXY);
  vslam::odometry_t m{};
  m.utime = ev.utime;
  m.seq = static_cast<int64_t>(ev.index);
  m.x = p.x;
  m.y = p.y;
  m.theta = p.theta;
  if (ev.index > 0) {
    const PlanarPose q = planarFromPose(poses[ev.index - 1].isometry(), FloorAxes::kXY);
    const double dx = p.x - q.x, dy = p.y - q.y, dth = wrapAngle(p.theta - q.theta);
    const double dt = poses[ev.index].t - poses[ev.index - 1].t;
    *distance += std::hypot(dx, dy);
    *rotation += std::abs(dth);
    if (dt > 0) {
      // Signed forward speed along the previous heading.
      m.v = (dx * std::cos(q.theta) + dy * std::sin(q.theta)) / dt;
      m.omega = dth / dt;
    }
  }
  m.distance = *distance;
  m.rotation = *rotation;
  return m;
}

// The image of the list entry ev.index, checked for the source size,
// resized and encoded as asked.
vslam::image_t imageMessage(const ImportOptions& o, const ImportInputs& in, const Pending& ev,
                            cv::Size source_size) {
  const ImageEntry& e = in.images[ev.index];
  cv::Mat img = ev.index == 0 ? in.first_image : loadImage(in.image_dir, in.list_file, e);
  if (img.size() != source_size) {
    throw DataError(in.list_file.string() + ":" + std::to_string(e.line) + ": image '" +
                    e.filename + "' is " + sizeText(img.size()) + ", but the first ('" +
                    in.images.front().filename + "', line " +
                    std::to_string(in.images.front().line) + ") is " + sizeText(source_size) +
                    "; all images must have one size");
  }
  if (o.resize && *o.resize != img.size()) {
    const bool shrink = o.resize->area() < img.size().area();
    cv::resize(img, img, *o.resize, 0, 0, shrink ? cv::INTER_AREA : cv::INTER_LINEAR);
  }
  vslam::image_t m{};
  m.utime = ev.utime;
  m.seq = static_cast<int64_t>(ev.index);
  m.camera = o.camera;
  m.width = img.cols;
  m.height = img.rows;
  m.exposure = 1.0f;
  switch (o.encoding) {
    case ImageEncoding::kGray8:
      if (img.channels() == 3) cv::cvtColor(img, img, cv::COLOR_BGR2GRAY);
      m.encoding = vslam::image_t::ENCODING_GRAY8;
      m.row_stride = img.cols;
      break;
    case ImageEncoding::kBgr8:
      if (img.channels() == 1) cv::cvtColor(img, img, cv::COLOR_GRAY2BGR);
      m.encoding = vslam::image_t::ENCODING_BGR8;
      m.row_stride = img.cols * 3;
      break;
    case ImageEncoding::kJpeg:
      m.encoding = vslam::image_t::ENCODING_JPEG;
      m.row_stride = 0;
      break;
  }
  if (o.encoding == ImageEncoding::kJpeg) {
    std::vector<uint8_t> jpeg;
    if (!cv::imencode(".jpg", img, jpeg, {cv::IMWRITE_JPEG_QUALITY, o.jpeg_quality})) {
      throw DataError(in.list_file.string() + ":" + std::to_string(e.line) +
                      ": cannot JPEG-encode '" + e.filename + "'");
    }
    m.data = std::move(jpeg);
  } else {
    if (!img.isContinuous()) img = img.clone();
    m.data.assign(img.data, img.data + img.total() * img.elemSize());
  }
  m.data_size = static_cast<int32_t>(m.data.size());
  return m;
}

// Writes the schedule's events to `file`, counting them in *stats.
void writeEvents(const fs::path& file, const std::vector<Pending>& schedule, const ImportOptions& o,
                 const ImportInputs& in, const config::CameraConfig& camera, ImportStats* stats) {
  bus::LogWriter log(file);
  const Eigen::Isometry3d camera_T_robot = camera.robot_T_camera.inverse();
  double odo_distance = 0, odo_rotation = 0;
  ProgressMeter meter("import", static_cast<double>(in.images.size()), ProgressMeter::kItems);
  for (const Pending& ev : schedule) {
    meter.update(static_cast<double>(stats->images), [] { return std::string("images"); });
    switch (ev.kind) {
      case Kind::kCalibration:
        log.write(ev.utime, stats->calibration_channel,
                  encode(bus::calibrationMessage(camera, ev.utime)));
        ++stats->calibration;
        break;
      case Kind::kGroundTruth:
        log.write(ev.utime, o.ground_truth_channel,
                  encode(groundTruthMessage(o, in.ground_truth, ev, camera_T_robot)));
        ++stats->ground_truth;
        break;
      case Kind::kOdometry:
        log.write(ev.utime, o.odometry_channel,
                  encode(odometryMessage(*in.odometry, ev, &odo_distance, &odo_rotation)));
        ++stats->odometry;
        break;
      case Kind::kImage:
        log.write(ev.utime, stats->image_channel,
                  encode(imageMessage(o, in, ev, stats->source_size)));
        ++stats->images;
        break;
    }
  }
}

}  // namespace

std::optional<ImageEncoding> parseImageEncoding(const std::string& word) {
  if (word == "gray8") return ImageEncoding::kGray8;
  if (word == "bgr8") return ImageEncoding::kBgr8;
  if (word == "jpeg") return ImageEncoding::kJpeg;
  return std::nullopt;
}

std::string toString(ImageEncoding encoding) {
  switch (encoding) {
    case ImageEncoding::kGray8:
      return "gray8";
    case ImageEncoding::kBgr8:
      return "bgr8";
    case ImageEncoding::kJpeg:
      return "jpeg";
  }
  return "?";
}

std::string defaultImageChannel(const std::string& camera) {
  return "CAM_" + upper(camera) + "_IMAGE";
}
std::string defaultCalibrationChannel(const std::string& camera) {
  return "CAM_" + upper(camera) + "_CALIBRATION";
}

ImportStats importTumDataset(const ImportOptions& o) {
  std::error_code ec;
  if (!fs::is_directory(o.dataset, ec)) throw DataError(o.dataset.string() + ": no such folder");
  if (o.jpeg_quality < 1 || o.jpeg_quality > 100) throw UsageError("JPEG quality must be 1..100");
  ImportStats stats;
  stats.image_channel = o.image_channel.empty() ? defaultImageChannel(o.camera) : o.image_channel;
  stats.calibration_channel =
      o.calibration_channel.empty() ? defaultCalibrationChannel(o.camera) : o.calibration_channel;

  const ImportInputs in = readInputs(o);
  stats.source_size = in.first_image.size();
  stats.image_size = o.resize.value_or(stats.source_size);
  const config::CameraIntrinsics calib =
      writtenIntrinsics(o, in, stats.source_size, stats.image_size);
  stats.frame_rate_hz = nominalFrameRate(o, in.images);
  const config::CameraConfig camera = importedCamera(o, calib, stats);
  const std::vector<Pending> schedule = scheduleEvents(o, in);

  // Write to a temporary file next to the output, renamed at the end.
  if (o.output.empty()) throw UsageError("no output log given");
  const fs::path tmp = o.output.string() + ".partial";
  PartialFile guard(tmp);
  writeEvents(tmp, schedule, o, in, camera, &stats);
  fs::rename(tmp, o.output, ec);
  if (ec) throw DataError(o.output.string() + ": cannot move the log into place: " + ec.message());
  guard.release();
  stats.first_utime = schedule.front().utime;
  stats.last_utime = schedule.back().utime;
  return stats;
}

}  // namespace vslam::eval
