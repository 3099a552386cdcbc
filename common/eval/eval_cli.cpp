#include "eval/eval_cli.hpp"

#include <cctype>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <memory>
#include <optional>
#include <ostream>

#include "eval/appearance_eval.hpp"
#include "eval/command_line.hpp"
#include "eval/errors.hpp"
#include "eval/log_measurements.hpp"
#include "eval/log_trajectories.hpp"
#include "eval/plot.hpp"
#include "eval/report.hpp"
#include "eval/tum_file.hpp"
#include "util/command_line.hpp"
#include "util/log.hpp"

namespace vslam::eval {
namespace {

namespace fs = std::filesystem;

// A mode's run, once its options are parsed.
using ModeRun = std::function<int(std::ostream& out)>;

// ---- --trajectory -------------------------------------------------------

struct TrajectoryArgs {
  std::optional<fs::path> log;
  std::optional<fs::path> ref_file;
  std::vector<fs::path> est_files, odom_files;
  LogReadOptions log_options;
  bool log_option_given = false;
  TrajectoryEvalOptions eval;
  std::optional<fs::path> write_tum, write_tum_ref, plot_dir, json;
  cv::Size plot_size{1000, 800};
};

void addTrajectoryOptions(CLI::App& app, TrajectoryArgs& a) {
  const auto log_option = [&a](const std::string&) { a.log_option_given = true; };
  const std::string input = "input: an LCM log", tum = "input: TUM files",
                    options = "trajectory options";
  app.add_option("log", a.log, "an LCM log")->group(input);
  app.add_option("--ref-channel", a.log_options.ref_channel, "reference, vslam.ground_truth_pose_t")
      ->capture_default_str()
      ->each(log_option)
      ->group(input);
  app.add_option("--est-channel", a.log_options.est_channels,
                 "SLAM estimate, vslam.pose_estimate_t; repeatable")
      ->each(log_option)
      ->group(input);
  app.add_option("--odom-channel", a.log_options.odom_channels,
                 "odometry-only estimate, vslam.pose_estimate_t or raw\n"
                 "vslam.odometry_t; repeatable (neither given: " +
                     std::string(kDefaultEstimateChannel) +
                     " if present,\nand POSE_ODOMETRY, else ODOMETRY, if present)")
      ->each(log_option)
      ->group(input);
  app.add_option("--map-channel", a.log_options.map_channel,
                 "landmarks to plot, vslam.map_t (if present; '' for none)")
      ->capture_default_str()
      ->each(log_option)
      ->group(input);
  app.add_option("--ref", a.ref_file,
                 "reference TUM trajectory file\n'timestamp tx ty tz qx qy qz qw'")
      ->group(tum);
  app.add_option("--est", a.est_files, "estimate TUM file; repeatable")->group(tum);
  app.add_option("--odom", a.odom_files, "odometry-only TUM file; repeatable")->group(tum);
  app.add_option("--max-diff", a.eval.max_diff,
                 "association: max |t_ref - (t_est + offset)|, strictly less (s)")
      ->check(positiveNumber())
      ->capture_default_str()
      ->group(options);
  app.add_option("--offset", a.eval.offset, "seconds added to the estimate's stamps")
      ->check(finiteNumber())
      ->capture_default_str()
      ->group(options);
  addChoiceOption(app, "--align", &a.eval.align, parseAlignMode, "none, se2, se3, sim3 or origin",
                  "alignment before ATE: none|se2|se3|sim3|origin (se3 as\nevaluate_ate.py; "
                  "origin: first poses made to coincide,\nevo --align_origin)")
      ->default_str(toString(a.eval.align))
      ->group(options);
  app.add_option("--delta", a.eval.rpe.delta, "RPE pair spacing")
      ->check(positiveNumber())
      ->capture_default_str()
      ->group(options);
  addChoiceOption(app, "--delta-unit", &a.eval.rpe.unit, parseDeltaUnit, "s or m",
                  "...in seconds or metres travelled: s|m")
      ->default_str(toString(a.eval.rpe.unit))
      ->group(options);
  app.add_option("--write-tum", a.write_tum,
                 "write the estimate(s) as TUM (several: FILE.<name>.ext)")
      ->group(options);
  app.add_option("--write-tum-ref", a.write_tum_ref, "write the reference as TUM")->group(options);
  app.add_option("--plot-dir", a.plot_dir, "write DIR/trajectory.png and DIR/error.png")
      ->group(options);
  addSizeOption(app, "--plot-size", &a.plot_size, "plot size in pixels", Figure::minimumSize())
      ->group(options);
  app.add_option("--json", a.json, "write the results as JSON")->group(options);
}

void checkTrajectoryArgs(const TrajectoryArgs& a) {
  const bool tum = a.ref_file || !a.est_files.empty() || !a.odom_files.empty();
  if (a.log && tum) throw UsageError("give either a LOG or --ref/--est TUM files, not both");
  if (!a.log && !tum) throw UsageError("nothing to evaluate: give a LOG or --ref REF --est EST");
  if (!tum) return;
  if (!a.ref_file) throw UsageError("--est/--odom need --ref REF (the reference TUM file)");
  if (a.est_files.empty() && a.odom_files.empty()) {
    throw UsageError("--ref needs --est EST (or --odom ODOM), a TUM file to evaluate");
  }
  if (a.log_option_given) {
    throw UsageError(
        "--ref-channel/--est-channel/--odom-channel/--map-channel apply to a LOG, "
        "not to TUM files");
  }
}

// est.txt -> est.POSE_ODOMETRY.txt when several estimates share --write-tum.
fs::path tumPathFor(const fs::path& base, const std::string& name, bool several) {
  if (!several) return base;
  std::string safe;
  for (const char c : fs::path(name).filename().string()) {
    safe += (std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-') ? c : '_';
  }
  fs::path out = base;
  out.replace_filename(base.stem().string() + "." + safe + base.extension().string());
  return out;
}

int runTrajectory(const TrajectoryArgs& a, std::ostream& out) {
  TrajectoryReport report;
  report.options = a.eval;
  std::vector<EstimateInput> inputs;
  if (a.log) {
    LogContents c = readLogTrajectories(*a.log, a.log_options);
    report.input = "log " + a.log->string();
    report.reference = std::move(c.reference);
    report.reference_source = c.reference_source;
    report.landmarks = std::move(c.landmarks);
    inputs = std::move(c.estimates);
  } else {
    report.input = "TUM files (reference " + a.ref_file->string() + ")";
    report.reference = readTumFile(*a.ref_file);
    report.reference.name = a.ref_file->filename().string();
    report.reference_source = "TUM file";
    auto add = [&](const fs::path& f, EstimateKind kind) {
      EstimateInput in{readTumFile(f), kind, "TUM file"};
      in.trajectory.name = f.filename().string();
      inputs.push_back(std::move(in));
    };
    for (const auto& f : a.est_files) add(f, EstimateKind::kEstimate);
    for (const auto& f : a.odom_files) add(f, EstimateKind::kOdometry);
  }

  // TUM copies first, so they exist for other tools even if evaluation fails.
  if (a.write_tum) {
    for (const auto& in : inputs) {
      const fs::path p = tumPathFor(*a.write_tum, in.trajectory.name, inputs.size() > 1);
      writeTumFile(p, in.trajectory);
      log::info("wrote ", in.trajectory.name, " (", in.trajectory.size(), " poses) to ",
                p.string());
    }
  }
  if (a.write_tum_ref) {
    writeTumFile(*a.write_tum_ref, report.reference);
    log::info("wrote reference ", report.reference.name, " to ", a.write_tum_ref->string());
  }

  for (const auto& in : inputs) {
    try {
      report.estimates.push_back(evaluateEstimate(report.reference, in, a.eval));
    } catch (const DataError& e) {
      throw DataError(in.trajectory.name + " vs " + report.reference.name + ": " + e.what());
    }
    const auto& e = report.estimates.back();
    if (e.rpe.trans.count == 0) {
      log::warn(e.name, ": no RPE pairs at delta ", a.eval.rpe.delta, " ",
                toString(a.eval.rpe.unit),
                " (trajectory shorter than delta, or no reference "
                "pose near its stamps)");
    }
  }
  printTable(out, report);
  if (a.json) {
    writeJson(*a.json, report);
    log::info("wrote ", a.json->string());
  }
  if (a.plot_dir) {
    for (const auto& p : writePlots(*a.plot_dir, report, a.plot_size)) {
      log::info("wrote ", p.string());
    }
  }
  return kExitOk;
}

ModeRun setUpTrajectory(CLI::App& app) {
  auto a = std::make_shared<TrajectoryArgs>();
  addTrajectoryOptions(app, *a);
  return [a](std::ostream& out) {
    checkTrajectoryArgs(*a);
    return runTrajectory(*a, out);
  };
}

// ---- --measurements -----------------------------------------------------

struct MeasurementArgs {
  std::optional<fs::path> log;
  MeasurementLogOptions options;
  MeasurementEvalOptions eval;
  std::optional<fs::path> csv;
};

void addMeasurementOptions(CLI::App& app, MeasurementArgs& a) {
  frontend::PrefilterParams& prefilter = a.options.prefilter;
  app.add_option("log", a.log, "an LCM log");
  app.add_option("--measurement-channel", a.options.measurement_channel,
                 "vslam.visual_measurement_t")
      ->capture_default_str();
  app.add_option("--ref-channel", a.options.ref_channel, "ground truth")->capture_default_str();
  app.add_option("--max-proj-err", prefilter.max_proj_err_rms_px,
                 "pre-filter region for measurements without a verdict\n(the paper's): "
                 "max RMS reprojection error, px")
      ->check(positiveNumber())
      ->capture_default_str();
  app.add_option("--min-points", prefilter.min_num_points, "... min points")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--max-slope", prefilter.max_slope, "... max slope")
      ->check(positiveNumber())
      ->capture_default_str();
  app.add_flag("--rejudge", a.options.rejudge, "apply that region to judged measurements too");
  app.add_option("--max-gap", a.eval.max_gap, "max spacing of the ground truth around a stamp, s")
      ->check(positiveNumber())
      ->capture_default_str();
  app.add_option("--csv", a.csv, "write every measurement with its truth and errors");
}

int runMeasurements(const MeasurementArgs& a, std::ostream& out) {
  if (!a.log) throw UsageError("--measurements needs a LOG");
  MeasurementLog m = readMeasurementLog(*a.log, a.options);
  MeasurementReport report = evaluateMeasurements(m.reference, std::move(m.samples), m.creations,
                                                  a.eval, m.camera_heading_rad);
  report.input = a.log->string();
  printMeasurementReport(out, report);
  if (a.csv) {
    writeMeasurementCsv(a.csv->string(), report);
    log::info("wrote ", a.csv->string());
  }
  return kExitOk;
}

ModeRun setUpMeasurements(CLI::App& app) {
  auto a = std::make_shared<MeasurementArgs>();
  addMeasurementOptions(app, *a);
  return [a](std::ostream& out) { return runMeasurements(*a, out); };
}

ModeRun setUpAppearance(CLI::App& app) {
  auto a = std::make_shared<AppearanceEvalArgs>();
  addAppearanceEvalOptions(app, *a);
  return [a](std::ostream& out) { return runAppearanceEval(*a, out); };
}

// ---- modes ----------------------------------------------------------------

struct Mode {
  const char* flag;
  const char* description;
  ModeRun (*set_up)(CLI::App& app);  // adds the mode's options, returns its run
};

const Mode kModes[] = {
    {"--trajectory", "trajectories against a reference: ATE, RPE, TUM copies, plots (default)",
     setUpTrajectory},
    {"--appearance", "appearance SLAM against ground truth (Lee & Sowmya Figs. 8-11)",
     setUpAppearance},
    {"--measurements", "visual measurements against ground truth (vSLAM paper Table 1)",
     setUpMeasurements},
};

// The mode's parser: its flag (accepted where it stands) and options.
std::unique_ptr<CLI::App> modeApp(const Mode& mode, ModeRun* run) {
  auto app =
      std::make_unique<CLI::App>(std::string("vslam-eval ") + mode.flag + ": " + mode.description,
                                 std::string("vslam-eval ") + mode.flag);
  app->set_help_flag();  // runEvalCli prints the help of every mode
  app->add_flag(mode.flag, "this mode");
  *run = mode.set_up(*app);
  return app;
}

}  // namespace

void printEvalUsage(std::ostream& os) {
  os << "usage: vslam-eval [MODE] INPUT [options]   (an option's value follows it, or "
        "--key=value)\n"
        "\n"
        "modes:\n";
  for (const auto& mode : kModes) {
    os << "  " << std::left << std::setw(16) << mode.flag << mode.description << "\n";
  }
  os << "\n"
        "Prints a table to stdout. Exit codes: 0 ok, 1 data problem (unreadable or malformed\n"
        "input, missing channel, no associated poses, damaged log), 2 bad command line.\n"
        "Definitions: docs/evaluation.md.\n";
  for (const auto& mode : kModes) {
    ModeRun run;
    os << "\n" << modeApp(mode, &run)->help();
  }
}

int runEvalCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  const Mode* mode = nullptr;
  for (const auto& a : args) {
    if (a == "--help" || a == "-h") {
      printEvalUsage(out);
      return kExitOk;
    }
    for (const auto& candidate : kModes) {
      if (a != candidate.flag || mode == &candidate) continue;
      if (mode) {
        err << "vslam-eval: " << mode->flag << " and " << candidate.flag
            << " are different modes; give one\n";
        return kExitUsage;
      }
      mode = &candidate;
    }
  }
  if (!mode) mode = &kModes[0];
  try {
    ModeRun run;
    const auto app = modeApp(*mode, &run);
    if (const auto code = parseCommandLine(*app, "vslam-eval", args, out, err)) return *code;
    return run(out);
  } catch (const UsageError& e) {
    err << "vslam-eval: " << e.what() << " (see --help)\n";
    return kExitUsage;
  } catch (const std::exception& e) {  // DataError and any other failure on the data
    err << "vslam-eval: error: " << e.what() << "\n";
    return kExitDataError;
  }
}

}  // namespace vslam::eval
