#include "eval/eval_cli.hpp"

#include <cctype>
#include <filesystem>
#include <optional>
#include <ostream>

#include "eval/appearance_eval.hpp"
#include "eval/cli_args.hpp"
#include "eval/errors.hpp"
#include "eval/log_measurements.hpp"
#include "eval/log_trajectories.hpp"
#include "eval/plot.hpp"
#include "eval/report.hpp"
#include "eval/tum_file.hpp"
#include "util/log.hpp"

namespace vslam::eval {
namespace {

namespace fs = std::filesystem;

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

TrajectoryArgs parseTrajectoryArgs(const std::vector<std::string>& args) {
  TrajectoryArgs a;
  cli::ArgCursor cur(args);
  while (!cur.done()) {
    const std::string opt = cur.next();
    auto logOption = [&](std::string* target) {
      *target = cur.value(opt);
      a.log_option_given = true;
    };
    if (opt == "--ref") {
      a.ref_file = cur.value(opt);
    } else if (opt == "--est") {
      a.est_files.emplace_back(cur.value(opt));
    } else if (opt == "--odom") {
      a.odom_files.emplace_back(cur.value(opt));
    } else if (opt == "--ref-channel") {
      logOption(&a.log_options.ref_channel);
    } else if (opt == "--est-channel") {
      a.log_options.est_channels.push_back(cur.value(opt));
      a.log_option_given = true;
    } else if (opt == "--odom-channel") {
      a.log_options.odom_channels.push_back(cur.value(opt));
      a.log_option_given = true;
    } else if (opt == "--map-channel") {
      logOption(&a.log_options.map_channel);
    } else if (opt == "--max-diff") {
      a.eval.max_diff = cli::parsePositive(opt, cur.value(opt));
    } else if (opt == "--offset") {
      a.eval.offset = cli::parseDouble(opt, cur.value(opt));
    } else if (opt == "--align") {
      const std::string v = cur.value(opt);
      const auto mode = parseAlignMode(v);
      if (!mode) throw UsageError("--align '" + v + "': expected none, se2, se3 or sim3");
      a.eval.align = *mode;
    } else if (opt == "--delta") {
      a.eval.rpe.delta = cli::parsePositive(opt, cur.value(opt));
    } else if (opt == "--delta-unit") {
      const std::string v = cur.value(opt);
      const auto unit = parseDeltaUnit(v);
      if (!unit) throw UsageError("--delta-unit '" + v + "': expected s or m");
      a.eval.rpe.unit = *unit;
    } else if (opt == "--write-tum") {
      a.write_tum = cur.value(opt);
    } else if (opt == "--write-tum-ref") {
      a.write_tum_ref = cur.value(opt);
    } else if (opt == "--plot-dir") {
      a.plot_dir = cur.value(opt);
    } else if (opt == "--plot-size") {
      a.plot_size = cli::parseSize(opt, cur.value(opt));
      const cv::Size min = Figure::minimumSize();
      if (a.plot_size.width < min.width || a.plot_size.height < min.height) {
        throw UsageError("--plot-size must be at least " + std::to_string(min.width) + "x" +
                         std::to_string(min.height));
      }
    } else if (opt == "--json") {
      a.json = cur.value(opt);
    } else if (!opt.empty() && opt[0] == '-') {
      throw UsageError("unknown option '" + opt + "'");
    } else if (a.log) {
      throw UsageError("more than one log given ('" + a.log->string() + "' and '" + opt + "')");
    } else {
      a.log = opt;
    }
  }
  const bool tum = a.ref_file || !a.est_files.empty() || !a.odom_files.empty();
  if (a.log && tum) throw UsageError("give either a LOG or --ref/--est TUM files, not both");
  if (!a.log && !tum) throw UsageError("nothing to evaluate: give a LOG or --ref REF --est EST");
  if (tum) {
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
  return a;
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

int runTrajectory(const std::vector<std::string>& args, std::ostream& out) {
  const TrajectoryArgs a = parseTrajectoryArgs(args);
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

// ---- --measurements -----------------------------------------------------

int runMeasurements(const std::vector<std::string>& args, std::ostream& out) {
  std::optional<fs::path> log;
  MeasurementLogOptions options;
  MeasurementEvalOptions eval;
  std::optional<fs::path> csv;
  cli::ArgCursor cur(args);
  while (!cur.done()) {
    const std::string opt = cur.next();
    if (opt == "--ref-channel") {
      options.ref_channel = cur.value(opt);
    } else if (opt == "--measurement-channel") {
      options.measurement_channel = cur.value(opt);
    } else if (opt == "--max-proj-err") {
      options.prefilter.max_proj_err_rms_px = cli::parsePositive(opt, cur.value(opt));
    } else if (opt == "--min-points") {
      options.prefilter.min_num_points = static_cast<int>(cli::parsePositive(opt, cur.value(opt)));
    } else if (opt == "--max-slope") {
      options.prefilter.max_slope = cli::parsePositive(opt, cur.value(opt));
    } else if (opt == "--rejudge") {
      options.rejudge = true;
    } else if (opt == "--max-gap") {
      eval.max_gap = cli::parsePositive(opt, cur.value(opt));
    } else if (opt == "--csv") {
      csv = cur.value(opt);
    } else if (!opt.empty() && opt[0] == '-') {
      throw UsageError("unknown option '" + opt + "' for --measurements");
    } else if (log) {
      throw UsageError("more than one log given ('" + log->string() + "' and '" + opt + "')");
    } else {
      log = opt;
    }
  }
  if (!log) throw UsageError("--measurements needs a LOG");
  MeasurementLog m = readMeasurementLog(*log, options);
  MeasurementReport report =
      evaluateMeasurements(m.reference, std::move(m.samples), m.creations, eval);
  report.input = log->string();
  printMeasurementReport(out, report);
  if (csv) {
    writeMeasurementCsv(csv->string(), report);
    log::info("wrote ", csv->string());
  }
  return kExitOk;
}

// ---- modes ----------------------------------------------------------------

struct Mode {
  const char* flag;
  int (*run)(const std::vector<std::string>& args, std::ostream& out);
};

const Mode kModes[] = {
    {"--trajectory", runTrajectory},
    {"--appearance", runAppearanceEval},
    {"--measurements", runMeasurements},
};

}  // namespace

void printEvalUsage(std::ostream& os) {
  os << "usage: vslam-eval [MODE] INPUT [options]\n"
        "\n"
        "modes (default --trajectory):\n"
        "  --trajectory            compare estimated trajectories with a reference: ATE, RPE,\n"
        "                          TUM copies, plots\n"
        "  --measurements LOG      accuracy of the visual measurements against ground truth\n"
        "                          (vSLAM paper Table 1)\n"
        "\n"
        "--trajectory input, one of:\n"
        "  LOG                     an LCM log\n"
        "    --ref-channel CH      reference, vslam.ground_truth_pose_t (default GROUND_TRUTH)\n"
        "    --est-channel CH      SLAM estimate, vslam.pose_estimate_t; repeatable\n"
        "    --odom-channel CH     odometry-only estimate, vslam.pose_estimate_t or raw\n"
        "                          vslam.odometry_t; repeatable\n"
        "                          (neither given: POSE_ESTIMATE if present, and POSE_ODOMETRY,\n"
        "                          else ODOMETRY, if present)\n"
        "    --map-channel CH      landmarks to plot, vslam.map_t (default MAP, if present)\n"
        "  --ref FILE --est FILE   TUM trajectory files 'timestamp tx ty tz qx qy qz qw';\n"
        "    [--odom FILE]         --est and --odom repeatable\n"
        "\n"
        "--trajectory options:\n"
        "  --max-diff S            association: max |t_ref - (t_est + offset)|, strictly less\n"
        "                          (default 0.02 s)\n"
        "  --offset S              seconds added to the estimate's stamps (default 0)\n"
        "  --align none|se2|se3|sim3|origin  alignment before ATE (default se3, as "
        "evaluate_ate.py;\n"
        "                      origin: first poses made to coincide, evo --align_origin)\n"
        "  --delta D               RPE pair spacing (default 1)\n"
        "  --delta-unit s|m        ...in seconds or metres travelled (default s)\n"
        "  --write-tum FILE        write the estimate(s) as TUM (several: FILE.<name>.ext)\n"
        "  --write-tum-ref FILE    write the reference as TUM\n"
        "  --plot-dir DIR          write DIR/trajectory.png and DIR/error.png\n"
        "  --plot-size WxH         plot size in pixels (default 1000x800)\n"
        "  --json FILE             write the results as JSON\n"
        "\n"
        "--measurements options:\n"
        "  --measurement-channel CH  vslam.visual_measurement_t (default VISUAL_MEASUREMENT)\n"
        "  --ref-channel CH        ground truth (default GROUND_TRUTH)\n"
        "  --max-proj-err PX, --min-points N, --max-slope S\n"
        "                          pre-filter region for measurements without a verdict\n"
        "                          (default 3.0, 10, 0.1: the paper's)\n"
        "  --rejudge               apply that region to judged measurements too\n"
        "  --max-gap S             max spacing of the ground truth around a stamp (default 0.1)\n"
        "  --csv FILE              write every measurement with its truth and errors\n"
        "\n"
        "Prints a table to stdout. Exit codes: 0 ok, 1 data problem (unreadable or malformed\n"
        "input, missing channel, no associated poses, damaged log), 2 bad command line.\n"
        "Definitions: docs/evaluation.md.\n";
  os << "\n";
  printAppearanceUsage(os);
}

int runEvalCli(const std::vector<std::string>& args, std::ostream& out, std::ostream& err) {
  const Mode* mode = nullptr;
  std::vector<std::string> rest;
  for (const auto& a : args) {
    if (a == "--help" || a == "-h") {
      printEvalUsage(out);
      return kExitOk;
    }
    const Mode* m = nullptr;
    for (const auto& candidate : kModes) {
      if (a == candidate.flag) m = &candidate;
    }
    if (!m) {
      rest.push_back(a);
      continue;
    }
    if (mode && mode != m) {
      err << "vslam-eval: " << mode->flag << " and " << m->flag
          << " are different modes; give one\n";
      return kExitUsage;
    }
    mode = m;
  }
  if (!mode) mode = &kModes[0];
  try {
    return mode->run(rest, out);
  } catch (const UsageError& e) {
    err << "vslam-eval: " << e.what() << " (see --help)\n";
    return kExitUsage;
  } catch (const DataError& e) {
    err << "vslam-eval: error: " << e.what() << "\n";
    return kExitDataError;
  } catch (const std::exception& e) {
    err << "vslam-eval: error: " << e.what() << "\n";
    return kExitDataError;
  }
}

}  // namespace vslam::eval
