#include "calibration/calibrate_cli.hpp"

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <iomanip>
#include <limits>
#include <optional>
#include <ostream>
#include <regex>
#include <sstream>

#include "calibration/calibration.hpp"
#include "calibration/frame_source.hpp"
#include "util/command_line.hpp"
#include "util/process.hpp"

namespace vslam::calibration {
namespace {

constexpr int kExitDataError = 1;

struct CalibrateOptions {
  BoardSpec board;
  ViewSelectionParams selection;
  CalibrationParams calibration;
  std::vector<std::filesystem::path> images;
  std::filesystem::path folder, video, out;
  std::optional<int> device;
  int stride = 1;
  int64_t max_frames = 0;  // 0: no limit (a camera: until Ctrl-C or enough views)
  int max_views = 0;       // 0: no limit
};

// A whole finite number (CLI11's range checks let nan and inf through).
const CLI::Validator kFinite(
    [](std::string& text) -> std::string {
      std::istringstream in(text);
      double v = 0;
      return in >> v && in.peek() == EOF && std::isfinite(v) ? ""
                                                             : "'" + text + "' is not a number";
    },
    "");

std::string shortNumber(double v) {
  std::ostringstream os;
  os << v;
  return os.str();
}

// --chessboard / --charuco COLSxROWS: the board's kind and size.
void addBoardOption(CLI::App& app, const std::string& name, BoardKind kind, BoardSpec* board,
                    const std::string& description) {
  app.add_option_function<std::string>(
         name,
         [=](const std::string& text) {
           if (board->size.width > 0) {
             throw CLI::ValidationError("give one board: --chessboard or --charuco");
           }
           std::smatch m;
           if (!std::regex_match(text, m, std::regex("([0-9]{1,5})x([0-9]{1,5})")) ||
               std::stoi(m[1]) < 1 || std::stoi(m[2]) < 1) {
             throw CLI::ValidationError(name, "'" + text + "' is not COLSxROWS (e.g. 9x6)");
           }
           board->kind = kind;
           board->size = cv::Size(std::stoi(m[1]), std::stoi(m[2]));
         },
         description)
      ->type_name("COLSxROWS");
}

void addBoardOptions(CLI::App& app, CalibrateOptions& o) {
  addBoardOption(app, "--chessboard", BoardKind::kChessboard, &o.board,
                 "inner corners per row and column (OpenCV's sample: 9x6)");
  addBoardOption(app, "--charuco", BoardKind::kCharuco, &o.board,
                 "ChArUco board: squares per row and column");
  app.add_option("--square", o.board.square_size_m, "side of a square, metres")
      ->check(kFinite & CLI::PositiveNumber);
  app.add_option("--marker", o.board.marker_size_m, "ChArUco: side of a marker, metres")
      ->check(kFinite & CLI::PositiveNumber);
  app.add_option("--dictionary", o.board.dictionary, "ChArUco: ArUco dictionary")
      ->capture_default_str();
}

void addSourceOptions(CLI::App& app, CalibrateOptions& o) {
  app.add_option("image", o.images, "image files");
  app.add_option("--images", o.folder, "every image in a folder, by name");
  app.add_option("--video", o.video, "a video file");
  app.add_option("--device", o.device,
                 "live camera /dev/videoN (V4L2); stop with Ctrl-C, or\n"
                 "--max-frames / --max-views")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--stride", o.stride, "video or camera: every N-th frame")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-frames", o.max_frames, "stop after N frames read")
      ->check(CLI::PositiveNumber);
  app.add_option("--max-views", o.max_views, "stop after N views kept")->check(CLI::PositiveNumber);
}

void addSelectionOptions(CLI::App& app, CalibrateOptions& o) {
  ViewSelectionParams& s = o.selection;
  CalibrationParams& c = o.calibration;
  app.add_option("--min-sharpness", s.min_sharpness,
                 "variance of the Laplacian in the board's box below which\n"
                 "a view is blurred")
      ->check(kFinite & CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--min-novelty", s.min_novelty,
                 "board outline within F x the image diagonal of a kept\n"
                 "view's: redundant (0..1)")
      ->check(kFinite & CLI::Range(0.0, 1.0))
      ->capture_default_str();
  app.add_option("--outlier-factor", c.outlier_factor,
                 "drop views with an error above F x the median (and above\n" +
                     shortNumber(c.min_outlier_error_px) + " px), recalibrate")
      ->check(kFinite & CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--min-views", c.min_views, "fewer usable views is an error")
      ->check(CLI::Range(3, std::numeric_limits<int>::max()))
      ->capture_default_str();
  app.add_flag("--fix-aspect-ratio", c.fix_aspect_ratio, "fx = fy");
  app.add_flag("--zero-tangent", c.zero_tangential, "p1 = p2 = 0");
  app.add_flag("--fix-k3", c.fix_k3, "k3 = 0");
}

// What the options say together; CLI::ValidationError if they do not fit.
void checkOptions(const CalibrateOptions& o, const CLI::App& app) {
  if (o.board.size.width == 0) {
    throw CLI::ValidationError("no board: --chessboard COLSxROWS or --charuco COLSxROWS");
  }
  if (app.count("--square") == 0) {
    throw CLI::ValidationError("--square METRES (the side of a square) is required");
  }
  if (o.board.kind == BoardKind::kCharuco && !(o.board.marker_size_m > 0)) {
    throw CLI::ValidationError("--charuco needs --marker METRES (the side of a marker)");
  }
  try {
    validate(o.board);
  } catch (const std::invalid_argument& e) {
    throw CLI::ValidationError(std::string("board: ") + e.what());
  }
  const int sources = (o.images.empty() ? 0 : 1) + (o.folder.empty() ? 0 : 1) +
                      (o.video.empty() ? 0 : 1) + (o.device ? 1 : 0);
  if (sources != 1) {
    throw CLI::ValidationError(
        "give exactly one source: image files, --images DIR, --video FILE or --device N");
  }
  if (o.out.empty()) throw CLI::ValidationError("--out FILE.yml is required");
}

FrameSource openSource(const CalibrateOptions& o) {
  if (!o.images.empty()) return FrameSource::images(o.images);
  if (!o.folder.empty()) return FrameSource::folder(o.folder);
  if (!o.video.empty()) return FrameSource::video(o.video);
  return FrameSource::device(*o.device);
}

void report(std::ostream& out, const CalibrationResult& r) {
  out << std::fixed << std::setprecision(3);
  out << "reprojection error per view (RMS, px):\n";
  for (size_t i = 0; i < r.views.size(); ++i) {
    out << "  " << std::left << std::setw(24) << r.views[i].name << std::right << " "
        << r.view_rms_px[i] << "\n";
  }
  for (size_t i = 0; i < r.dropped.size(); ++i) {
    out << "  " << std::left << std::setw(24) << r.dropped[i] << std::right << " "
        << r.dropped_rms_px[i] << "  dropped as an outlier, then recalibrated\n";
  }
  out << "overall RMS reprojection error: " << r.rms_px << " px over " << r.views.size()
      << " views";
  if (!r.dropped.empty()) out << " (" << r.first_rms_px << " px before dropping outliers)";
  out << "\n";
  const cv::Mat& k = r.camera_matrix;
  out << std::setprecision(2) << "image " << r.image_size.width << "x" << r.image_size.height
      << "  fx " << k.at<double>(0, 0) << "  fy " << k.at<double>(1, 1) << "  cx "
      << k.at<double>(0, 2) << "  cy " << k.at<double>(1, 2) << "\n";
  const cv::Vec4d& sd = r.intrinsics_sigma_px;
  out << "standard deviations: fx " << sd[0] << "  fy " << sd[1] << "  cx " << sd[2] << "  cy "
      << sd[3] << "\n";
  out << std::setprecision(5) << "distortion (k1 k2 p1 p2 k3):";
  for (int i = 0; i < r.distortion.cols; ++i) out << " " << r.distortion.at<double>(i);
  out << "\n";
}

}  // namespace

int runCalibrateCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  CLI::App app{
      "vslam-calibrate: camera intrinsics and distortion from views of a planar board,\n"
      "written as OpenCV's calibration YAML: point the robot file's `calibration:` key at it.\n"
      "Board: --chessboard COLSxROWS, or --charuco COLSxROWS --marker M; --square M.\n"
      "Source, exactly one: IMAGE..., --images DIR, --video FILE or --device N.",
      "vslam-calibrate"};
  app.footer(
      "Exit codes: 0 ok, 1 data problem (unreadable input, too few usable views), 2 bad\n"
      "command line. See docs/calibration.md.");
  CalibrateOptions o;
  addBoardOptions(app, o);
  addSourceOptions(app, o);
  addSelectionOptions(app, o);
  app.add_option("--out", o.out, "the calibration file (replaced)");
  if (const auto code =
          parseCommandLine(app, "vslam-calibrate", args, out, err, [&] { checkOptions(o, app); })) {
    return *code;
  }
  try {
    FrameSource source = openSource(o);
    BoardDetector detector(o.board);
    ViewSelector selector(detector, o.selection);
    out << "reading " << source.describe() << "\n";
    cv::Mat gray;
    std::string name;
    int64_t frames = 0;
    int counts[5] = {0, 0, 0, 0, 0};
    // Frames of a video without a board are the common case: not listed one by one.
    const bool list_every_frame = !o.images.empty() || !o.folder.empty();
    while (!stopRequested() && source.next(&gray, &name, o.stride)) {
      ++frames;
      const ViewDecision d = selector.offer(gray, name);
      ++counts[static_cast<int>(d.verdict)];
      if (d.verdict != ViewVerdict::kNoBoard || list_every_frame) {
        out << "  " << name << ": " << describe(d.verdict);
        if (d.verdict == ViewVerdict::kKept || d.verdict == ViewVerdict::kBlurred ||
            d.verdict == ViewVerdict::kRedundant) {
          out << std::fixed << std::setprecision(0) << " (sharpness " << d.sharpness;
          if (d.verdict != ViewVerdict::kBlurred) {
            out << std::setprecision(3) << ", novelty " << d.novelty;
          }
          out << ")";
        }
        out << "\n";
      }
      if (o.max_frames > 0 && frames >= o.max_frames) break;
      if (o.max_views > 0 && static_cast<int>(selector.kept().size()) >= o.max_views) break;
    }
    out << frames << " frames: " << counts[0] << " kept, " << counts[1] << " without a board, "
        << counts[2] << " blurred, " << counts[3] << " redundant, " << counts[4]
        << " of another size\n";
    const CalibrationResult r = calibrate(selector.kept(), selector.imageSize(), o.calibration);
    report(out, r);
    writeCalibrationFile(o.out, r, o.board);
    out << "wrote " << o.out.string()
        << "\nuse it in the robot file (a path relative to the robot file), e.g.\n"
           "  cameras:\n"
           "    - name: forward\n"
           "      calibration: ../calib/"
        << o.out.filename().string() << "\n";
    return kExitOk;
  } catch (const std::exception& e) {
    err << "vslam-calibrate: " << e.what() << "\n";
    return kExitDataError;
  }
}

}  // namespace vslam::calibration
