#include "eval/import_cli.hpp"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <ostream>

#include "config/stack_config.hpp"
#include "eval/command_line.hpp"
#include "eval/errors.hpp"
#include "eval/tum_import.hpp"
#include "util/command_line.hpp"

namespace vslam::eval {
namespace {

namespace fs = std::filesystem;

struct ImportArgs {
  ImportOptions options;
  std::optional<fs::path> config;  // --config
  bool image_channel_given = false, calibration_channel_given = false;
};

std::optional<bool> parseGroundTruthIsCamera(const std::string& word) {
  if (word == "camera") return true;
  if (word == "base") return false;
  return std::nullopt;
}

void addImportOptions(CLI::App& app, ImportArgs& a) {
  ImportOptions& o = a.options;
  app.add_option("dir", o.dataset, "a TUM RGB-D-layout folder")->required();
  app.add_option("--calibration", o.calibration,
                 "OpenCV calibration file (image_width, image_height,\n"
                 "camera_matrix, distortion_coefficients); for the source or\n"
                 "the --resize size; published at 1 Hz");
  app.add_option("--out", o.output, "log to write (replaced)")->required();
  app.add_option("--rgb", o.rgb_list,
                 "image list 'timestamp filename' (default DIR/rgb.txt;\n"
                 "file names relative to its folder)");
  app.add_option("--groundtruth", o.groundtruth, "TUM trajectory (default DIR/groundtruth.txt)");
  app.add_option("--odometry", o.odometry,
                 "TUM trajectory of the robot base (x forward, z up) in the\n"
                 "odometry frame, written as vslam.odometry_t");
  app.add_option("--config", a.config,
                 "stack config the log is for (default $VSLAM_CONFIG, else\n"
                 "./config/vslam.yaml if present): the written image size\n"
                 "must be its robot file's for the camera, and the channels\n"
                 "default to that camera's");
  app.add_option("--camera", o.camera, "camera name")
      ->capture_default_str()
      ->check(CLI::Validator(
          [](const std::string& name) { return name.empty() ? "must not be empty" : ""; }, ""));
  app.add_option("--image-channel", o.image_channel,
                 "default the robot file's, else CAM_<NAME>_IMAGE")
      ->each([&a](const std::string&) { a.image_channel_given = true; });
  app.add_option("--calibration-channel", o.calibration_channel,
                 "default the robot file's, else CAM_<NAME>_CALIBRATION")
      ->each([&a](const std::string&) { a.calibration_channel_given = true; });
  app.add_option("--gt-channel", o.ground_truth_channel)->capture_default_str();
  app.add_option("--odometry-channel", o.odometry_channel)->capture_default_str();
  addChoiceOption(app, "--encoding", &o.encoding, parseImageEncoding, "gray8, bgr8 or jpeg",
                  "image encoding: gray8|bgr8|jpeg")
      ->default_str(toString(o.encoding));
  app.add_option("--jpeg-quality", o.jpeg_quality, "1..100")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  addSizeOption(app, "--resize", &o.resize, "resize every image (intrinsics are rescaled)");
  app.add_option("--frame-rate", o.frame_rate_hz,
                 "nominal rate, Hz (default 1 / median interval of the list)")
      ->check(positiveNumber());
  addChoiceOption(app, "--planar-from", &o.floor, parseFloorAxes, "xy or xz",
                  "floor axes of the ground truth's world: xy (z up, TUM's\n"
                  "motion capture; default) or xz (y down, camera-like)");
  addChoiceOption(app, "--gt-frame", &o.groundtruth_is_camera, parseGroundTruthIsCamera,
                  "camera or base",
                  "camera|base: ground truth poses are the camera's (default,\n"
                  "TUM) and are moved to the robot base with the extrinsics,\n"
                  "or the base's");
  addTripleOption(app, "--camera-position", &o.camera_position_m,
                  "camera origin in the robot frame, metres (default 0,0,0)");
  addTripleOption(app, "--camera-orientation", &o.camera_yaw_pitch_roll_deg,
                  "Y,P,R degrees, relative to a level camera looking along the\n"
                  "robot's +x, as in the robot file (default 0,0,0)");
}

// The stack config the log is for: --config, else $VSLAM_CONFIG, else
// config/vslam.yaml when it exists here (the processes' default). Its robot
// file's camera sets the size the images must have and the default channels.
void applyRobotFile(const ImportArgs& a, ImportOptions* o, std::ostream& err) {
  const fs::path file = config::resolveStackConfig(a.config ? a.config->string() : "");
  if (std::error_code ec;
      !a.config && file == config::kDefaultStackConfig && !fs::is_regular_file(file, ec)) {
    err << "vslam-import: note: no stack config (--config, $VSLAM_CONFIG or ./config/vslam.yaml):"
           " the image size is not checked against a robot file\n";
    return;
  }
  const config::StackConfig stack = config::StackConfig::loadFile(file);
  const config::RobotConfig& robot = stack.robot;
  const auto it = std::find_if(robot.cameras.begin(), robot.cameras.end(),
                               [&](const config::CameraConfig& c) { return c.name == o->camera; });
  if (it == robot.cameras.end()) {
    std::string names;
    for (const auto& c : robot.cameras) names += (names.empty() ? "" : ", ") + c.name;
    throw UsageError("--camera " + o->camera + ": no such camera in " + robot.file.string() +
                     " (robot file of " + file.string() + "; cameras: " + names + ")");
  }
  o->robot_camera = *it;
  o->robot_file = robot.file;
  if (!a.image_channel_given) o->image_channel = it->image_channel;
  if (!a.calibration_channel_given) o->calibration_channel = it->calibration_channel;
}

}  // namespace

int runImportCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  CLI::App app{
      "vslam-import: converts a TUM RGB-D-layout folder (rgb.txt, images, groundtruth.txt)\n"
      "into an LCM log on the stack's channels, events in time order at the data timestamps.",
      "vslam-import"};
  app.footer(
      "Exit codes: 0 ok, 1 data problem (missing or malformed file, unreadable image,\n"
      "inconsistent image sizes, images of another size than the robot file's), 2 bad\n"
      "command line or stack config. See docs/evaluation.md.");
  ImportArgs a;
  addImportOptions(app, a);
  try {
    if (const auto code = parseCommandLine(app, "vslam-import", args, out, err)) return *code;
    if (a.options.calibration.empty()) {
      throw UsageError(
          "--calibration FILE is required (an OpenCV calibration file like "
          "config/calib/sim_320x240.yml; the front-ends need it)");
    }
    ImportOptions o = a.options;
    applyRobotFile(a, &o, err);
    const ImportStats s = importTumDataset(o);
    out << "wrote " << o.output.string() << ": " << s.images << " images (" << toString(o.encoding)
        << ", " << s.image_size.width << "x" << s.image_size.height << ") on " << s.image_channel
        << ", " << s.calibration << " calibrations on " << s.calibration_channel << ", "
        << s.ground_truth << " ground-truth poses on " << o.ground_truth_channel;
    if (o.odometry) out << ", " << s.odometry << " odometry readings on " << o.odometry_channel;
    out << "; " << (s.last_utime - s.first_utime) * 1e-6 << " s, frame rate " << s.frame_rate_hz
        << " Hz\n";
    return kExitOk;
  } catch (const UsageError& e) {
    err << "vslam-import: " << e.what() << " (see --help)\n";
    return kExitUsage;
  } catch (const config::ConfigError& e) {
    err << "vslam-import: bad configuration: " << e.what() << "\n";
    return kExitUsage;
  } catch (const std::exception& e) {  // DataError and any other failure on the data
    err << "vslam-import: error: " << e.what() << "\n";
    return kExitDataError;
  }
}

}  // namespace vslam::eval
