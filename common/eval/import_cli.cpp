#include "eval/import_cli.hpp"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <ostream>

#include "config/stack_config.hpp"
#include "eval/cli_args.hpp"
#include "eval/errors.hpp"
#include "eval/tum_import.hpp"

namespace vslam::eval {
namespace {

namespace fs = std::filesystem;

struct ImportArgs {
  ImportOptions options;
  std::optional<fs::path> config;  // --config
  bool image_channel_given = false, calibration_channel_given = false;
};

ImportArgs parseImportArgs(const std::vector<std::string>& args) {
  ImportArgs a;
  ImportOptions& o = a.options;
  bool have_dir = false, have_calib = false, have_out = false;
  cli::ArgCursor cur(args);
  while (!cur.done()) {
    const std::string opt = cur.next();
    if (opt == "--calibration") {
      o.calibration = cur.value(opt);
      have_calib = true;
    } else if (opt == "--out") {
      o.output = cur.value(opt);
      have_out = true;
    } else if (opt == "--rgb") {
      o.rgb_list = cur.value(opt);
    } else if (opt == "--groundtruth") {
      o.groundtruth = cur.value(opt);
    } else if (opt == "--odometry") {
      o.odometry = cur.value(opt);
    } else if (opt == "--camera") {
      o.camera = cur.value(opt);
      if (o.camera.empty()) throw UsageError("--camera must not be empty");
    } else if (opt == "--config") {
      a.config = cur.value(opt);
    } else if (opt == "--image-channel") {
      o.image_channel = cur.value(opt);
      a.image_channel_given = true;
    } else if (opt == "--calibration-channel") {
      o.calibration_channel = cur.value(opt);
      a.calibration_channel_given = true;
    } else if (opt == "--gt-channel") {
      o.ground_truth_channel = cur.value(opt);
    } else if (opt == "--odometry-channel") {
      o.odometry_channel = cur.value(opt);
    } else if (opt == "--encoding") {
      const std::string v = cur.value(opt);
      const auto e = parseImageEncoding(v);
      if (!e) throw UsageError("--encoding '" + v + "': expected gray8, bgr8 or jpeg");
      o.encoding = *e;
    } else if (opt == "--jpeg-quality") {
      const double q = cli::parseDouble(opt, cur.value(opt));
      if (q < 1 || q > 100 || q != static_cast<int>(q)) {
        throw UsageError("--jpeg-quality must be an integer 1..100");
      }
      o.jpeg_quality = static_cast<int>(q);
    } else if (opt == "--resize") {
      o.resize = cli::parseSize(opt, cur.value(opt));
    } else if (opt == "--frame-rate") {
      o.frame_rate_hz = cli::parsePositive(opt, cur.value(opt));
    } else if (opt == "--planar-from") {
      const std::string v = cur.value(opt);
      const auto axes = parseFloorAxes(v);
      if (!axes) throw UsageError("--planar-from '" + v + "': expected xy or xz");
      o.floor = *axes;
    } else if (opt == "--gt-frame") {
      const std::string v = cur.value(opt);
      if (v != "camera" && v != "base") {
        throw UsageError("--gt-frame '" + v + "': expected camera or base");
      }
      o.groundtruth_is_camera = v == "camera";
    } else if (opt == "--camera-position") {
      const auto v = cli::parseList(opt, cur.value(opt), 3);
      o.camera_position_m = {v[0], v[1], v[2]};
    } else if (opt == "--camera-orientation") {
      const auto v = cli::parseList(opt, cur.value(opt), 3);
      o.camera_yaw_pitch_roll_deg = {v[0], v[1], v[2]};
    } else if (!opt.empty() && opt[0] == '-') {
      throw UsageError("unknown option '" + opt + "'");
    } else if (have_dir) {
      throw UsageError("more than one dataset folder given");
    } else {
      o.dataset = opt;
      have_dir = true;
    }
  }
  if (!have_dir) throw UsageError("no dataset folder given");
  if (!have_calib) {
    throw UsageError(
        "--calibration FILE is required (an OpenCV calibration file like "
        "config/calib/sim_320x240.yml; the front-ends need it)");
  }
  if (!have_out) throw UsageError("--out LOG is required");
  return a;
}

// The stack config the log is for: --config, else $VSLAM_CONFIG, else
// config/vslam.yaml when it exists here (the processes' default). Its robot
// file's camera sets the size the images must have and the default channels.
void applyRobotFile(const ImportArgs& a, ImportOptions* o, std::ostream& err) {
  fs::path file;
  if (a.config) {
    file = *a.config;
  } else if (const char* env = std::getenv("VSLAM_CONFIG"); env && *env) {
    file = env;
  } else if (std::error_code ec; fs::is_regular_file("config/vslam.yaml", ec)) {
    file = "config/vslam.yaml";
  } else {
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

void printImportUsage(std::ostream& os) {
  os << "usage: vslam-import DIR --calibration FILE --out LOG [options]\n"
        "\n"
        "Converts a TUM RGB-D-layout folder (rgb.txt, images, groundtruth.txt) into an LCM log\n"
        "on the stack's channels, events in time order at the data timestamps.\n"
        "\n"
        "  --calibration FILE        OpenCV calibration file (image_width, image_height,\n"
        "                            camera_matrix, distortion_coefficients); for the source or\n"
        "                            the --resize size; published at 1 Hz\n"
        "  --out LOG                 log to write (replaced)\n"
        "  --rgb FILE                image list 'timestamp filename' (default DIR/rgb.txt;\n"
        "                            file names relative to its folder)\n"
        "  --groundtruth FILE        TUM trajectory (default DIR/groundtruth.txt)\n"
        "  --odometry FILE           TUM trajectory of the robot base (x forward, z up) in the\n"
        "                            odometry frame, written as vslam.odometry_t\n"
        "  --config FILE             stack config the log is for (default $VSLAM_CONFIG, else\n"
        "                            ./config/vslam.yaml if present): the written image size\n"
        "                            must be its robot file's for the camera, and the channels\n"
        "                            default to that camera's\n"
        "  --camera NAME             camera name (default forward)\n"
        "  --image-channel CH        default the robot file's, else CAM_<NAME>_IMAGE\n"
        "  --calibration-channel CH  default the robot file's, else CAM_<NAME>_CALIBRATION\n"
        "  --gt-channel CH           default GROUND_TRUTH\n"
        "  --odometry-channel CH     default ODOMETRY\n"
        "  --encoding gray8|bgr8|jpeg  image encoding (default gray8)\n"
        "  --jpeg-quality Q          1..100 (default 95)\n"
        "  --resize WxH              resize every image (intrinsics are rescaled)\n"
        "  --frame-rate HZ           nominal rate (default 1 / median interval of the list)\n"
        "  --planar-from xy|xz       floor axes of the ground truth's world: xy (z up, TUM's\n"
        "                            motion capture; default) or xz (y down, camera-like)\n"
        "  --gt-frame camera|base    ground truth poses are the camera's (default, TUM) and are\n"
        "                            moved to the robot base with the extrinsics, or the base's\n"
        "  --camera-position X,Y,Z   camera origin in the robot frame, metres (default 0,0,0)\n"
        "  --camera-orientation Y,P,R  degrees, relative to a level camera looking along the\n"
        "                            robot's +x, as in the robot file (default 0,0,0)\n"
        "\n"
        "Exit codes: 0 ok, 1 data problem (missing or malformed file, unreadable image,\n"
        "inconsistent image sizes, images of another size than the robot file's), 2 bad\n"
        "command line or stack config. See docs/evaluation.md.\n";
}

int runImportCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  for (const auto& a : args) {
    if (a == "--help" || a == "-h") {
      printImportUsage(out);
      return kExitOk;
    }
  }
  try {
    const ImportArgs a = parseImportArgs(args);
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
  } catch (const DataError& e) {
    err << "vslam-import: error: " << e.what() << "\n";
    return kExitDataError;
  } catch (const std::exception& e) {
    err << "vslam-import: error: " << e.what() << "\n";
    return kExitDataError;
  }
}

}  // namespace vslam::eval
