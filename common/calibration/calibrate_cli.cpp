#include "calibration/calibrate_cli.hpp"

#include <cstdio>
#include <iomanip>
#include <optional>
#include <ostream>

#include "calibration/calibration.hpp"
#include "calibration/frame_source.hpp"
#include "eval/cli_args.hpp"
#include "util/process.hpp"

namespace vslam::calibration {
namespace {

using eval::UsageError;

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

int parseCount(const std::string& option, const std::string& text, int min) {
  const double v = eval::cli::parseDouble(option, text);
  if (v != static_cast<int>(v) || v < min) {
    throw UsageError(option + " must be an integer >= " + std::to_string(min) + ", got " + text);
  }
  return static_cast<int>(v);
}

CalibrateOptions parseArgs(const std::vector<std::string>& args) {
  CalibrateOptions o;
  bool have_board = false, have_square = false;
  eval::cli::ArgCursor cur(args);
  while (!cur.done()) {
    const std::string opt = cur.next();
    if (opt == "--chessboard" || opt == "--charuco") {
      if (have_board) throw UsageError("give one board: --chessboard or --charuco");
      o.board.kind = opt == "--chessboard" ? BoardKind::kChessboard : BoardKind::kCharuco;
      o.board.size = eval::cli::parseSize(opt, cur.value(opt));
      have_board = true;
    } else if (opt == "--square") {
      o.board.square_size_m = eval::cli::parsePositive(opt, cur.value(opt));
      have_square = true;
    } else if (opt == "--marker") {
      o.board.marker_size_m = eval::cli::parsePositive(opt, cur.value(opt));
    } else if (opt == "--dictionary") {
      o.board.dictionary = cur.value(opt);
    } else if (opt == "--images") {
      o.folder = cur.value(opt);
    } else if (opt == "--video") {
      o.video = cur.value(opt);
    } else if (opt == "--device") {
      o.device = parseCount(opt, cur.value(opt), 0);
    } else if (opt == "--out") {
      o.out = cur.value(opt);
    } else if (opt == "--stride") {
      o.stride = parseCount(opt, cur.value(opt), 1);
    } else if (opt == "--max-frames") {
      o.max_frames = parseCount(opt, cur.value(opt), 1);
    } else if (opt == "--max-views") {
      o.max_views = parseCount(opt, cur.value(opt), 1);
    } else if (opt == "--min-sharpness") {
      o.selection.min_sharpness = eval::cli::parseDouble(opt, cur.value(opt));
      if (o.selection.min_sharpness < 0) throw UsageError(opt + " must be >= 0");
    } else if (opt == "--min-novelty") {
      o.selection.min_novelty = eval::cli::parseDouble(opt, cur.value(opt));
      if (o.selection.min_novelty < 0 || o.selection.min_novelty > 1) {
        throw UsageError(opt + " must be in 0..1 (a fraction of the image diagonal)");
      }
    } else if (opt == "--outlier-factor") {
      o.calibration.outlier_factor = eval::cli::parsePositive(opt, cur.value(opt));
    } else if (opt == "--min-views") {
      o.calibration.min_views = parseCount(opt, cur.value(opt), 3);
    } else if (opt == "--fix-aspect-ratio") {
      o.calibration.fix_aspect_ratio = true;
    } else if (opt == "--zero-tangent") {
      o.calibration.zero_tangential = true;
    } else if (opt == "--fix-k3") {
      o.calibration.fix_k3 = true;
    } else if (!opt.empty() && opt[0] == '-') {
      throw UsageError("unknown option '" + opt + "'");
    } else {
      o.images.emplace_back(opt);
    }
  }
  if (!have_board) throw UsageError("no board: --chessboard COLSxROWS or --charuco COLSxROWS");
  if (!have_square) throw UsageError("--square METRES (the side of a square) is required");
  if (o.board.kind == BoardKind::kCharuco && !(o.board.marker_size_m > 0)) {
    throw UsageError("--charuco needs --marker METRES (the side of a marker)");
  }
  try {
    validate(o.board);
  } catch (const std::invalid_argument& e) {
    throw UsageError(std::string("board: ") + e.what());
  }
  const int sources = (o.images.empty() ? 0 : 1) + (o.folder.empty() ? 0 : 1) +
                      (o.video.empty() ? 0 : 1) + (o.device ? 1 : 0);
  if (sources != 1) {
    throw UsageError(
        "give exactly one source: image files, --images DIR, --video FILE or --device N");
  }
  if (o.out.empty()) throw UsageError("--out FILE.yml is required");
  return o;
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

void printCalibrateUsage(std::ostream& os) {
  os << "usage: vslam-calibrate (--chessboard COLSxROWS | --charuco COLSxROWS --marker M)\n"
        "                       --square M --out FILE.yml SOURCE [options]\n"
        "\n"
        "Camera intrinsics and distortion from views of a planar board, written as OpenCV's\n"
        "calibration YAML: point the robot file's `calibration:` key at it.\n"
        "\n"
        "board:\n"
        "  --chessboard COLSxROWS    inner corners per row and column (OpenCV's sample: 9x6)\n"
        "  --charuco COLSxROWS       ChArUco board: squares per row and column\n"
        "  --square M                side of a square, metres\n"
        "  --marker M                ChArUco: side of a marker, metres\n"
        "  --dictionary NAME         ChArUco: ArUco dictionary (default DICT_4X4_50)\n"
        "source (exactly one):\n"
        "  IMAGE...                  image files\n"
        "  --images DIR              every image in a folder, by name\n"
        "  --video FILE              a video file\n"
        "  --device N                live camera /dev/videoN (V4L2); stop with Ctrl-C, or\n"
        "                            --max-frames / --max-views\n"
        "  --stride N                video or camera: every N-th frame (default 1)\n"
        "  --max-frames N            stop after N frames read\n"
        "  --max-views N             stop after N views kept\n"
        "view selection:\n"
        "  --min-sharpness V         variance of the Laplacian in the board's box below which a\n"
        "                            view is blurred (default "
     << ViewSelectionParams{}.min_sharpness
     << ")\n"
        "  --min-novelty F           board outline within F x the image diagonal of a kept\n"
        "                            view's: redundant (default "
     << ViewSelectionParams{}.min_novelty
     << ")\n"
        "calibration:\n"
        "  --outlier-factor F        drop views with an error above F x the median (and above "
     << CalibrationParams{}.min_outlier_error_px << " px), recalibrate (default "
     << CalibrationParams{}.outlier_factor
     << ")\n"
        "  --min-views N             fewer usable views is an error (default "
     << CalibrationParams{}.min_views
     << ")\n"
        "  --fix-aspect-ratio        fx = fy\n"
        "  --zero-tangent            p1 = p2 = 0\n"
        "  --fix-k3                  k3 = 0\n"
        "  --out FILE.yml            the calibration file (replaced)\n"
        "\n"
        "Exit codes: 0 ok, 1 data problem (unreadable input, too few usable views), 2 bad\n"
        "command line. See docs/calibration.md.\n";
}

int runCalibrateCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  for (const auto& a : args) {
    if (a == "--help" || a == "-h") {
      printCalibrateUsage(out);
      return eval::kExitOk;
    }
  }
  CalibrateOptions o;
  try {
    o = parseArgs(args);
  } catch (const UsageError& e) {
    err << "vslam-calibrate: " << e.what() << " (see --help)\n";
    return eval::kExitUsage;
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
    return eval::kExitOk;
  } catch (const UsageError& e) {
    err << "vslam-calibrate: " << e.what() << " (see --help)\n";
    return eval::kExitUsage;
  } catch (const std::exception& e) {
    err << "vslam-calibrate: " << e.what() << "\n";
    return eval::kExitDataError;
  }
}

}  // namespace vslam::calibration
