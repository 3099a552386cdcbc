#include "landmark_db/map_tool.hpp"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iomanip>
#include <iostream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <optional>

#include "config/stack_config.hpp"
#include "eval/plot.hpp"
#include "util/command_line.hpp"

namespace vslam::landmark_db {
namespace {

constexpr int kExitDamaged = 1;

struct Options {
  std::string command, file, out, config, instance = "landmark_db";
  bool dry_run = false;
  Utime now = 0;
};

const char* sourceName(PoseSource s) {
  switch (s) {
    case PoseSource::kMap:
      return "map";
    case PoseSource::kProvisional:
      return "provisional";
    case PoseSource::kOdometry:
      return "odometry";
  }
  return "?";
}

DatabaseParams paramsFromConfig(const Options& o) {
  const auto stack = config::StackConfig::loadFile(o.config);
  const config::ConfigNode node = stack.process(o.instance);
  DatabaseParams p = loadDatabaseParams(node, stack.robot);
  return p;
}

std::unique_ptr<LandmarkDatabase> openDatabase(const Options& o, const DatabaseParams& p,
                                               bool read_only) {
  StoreOptions so;
  so.create_if_missing = false;
  so.read_only = read_only;
  return std::make_unique<LandmarkDatabase>(std::make_unique<LandmarkStore>(o.file, so), p);
}

void printInfo(LandmarkDatabase& db) {
  const auto& infos = db.infos();
  std::map<std::string, int> per_camera;
  std::map<std::string, int> per_source;
  int64_t points = 0, recognitions = 0, accepted = 0, rejected = 0;
  Utime newest = 0;
  for (const auto& [id, i] : infos) {
    ++per_camera[i.camera];
    ++per_source[sourceName(i.pose_source)];
    points += i.num_points;
    recognitions += i.stats.num_recognitions;
    accepted += i.stats.num_accepted;
    rejected += i.stats.num_rejected;
    newest = std::max({newest, i.created_utime, i.stats.last_seen_utime});
  }
  const auto regions = db.regions();
  std::cout << "file            " << db.store().file() << "\n"
            << "database_id     " << db.databaseId() << "\n"
            << "revision        " << db.revision() << "\n"
            << "size            " << std::fixed << std::setprecision(1)
            << static_cast<double>(db.store().fileBytes()) / 1024.0 << " KiB\n"
            << "landmarks       " << infos.size() << "\n";
  if (!infos.empty()) {
    std::cout << "ids             " << infos.begin()->first << " .. " << infos.rbegin()->first
              << "\n"
              << "points          " << points << " (" << std::setprecision(1)
              << static_cast<double>(points) / static_cast<double>(infos.size())
              << " per landmark)\n"
              << "bytes on disk   " << std::setprecision(0)
              << static_cast<double>(db.store().fileBytes()) / static_cast<double>(infos.size())
              << " per landmark\n";
  }
  for (const auto& [c, n] : per_camera) std::cout << "camera " << c << "  " << n << "\n";
  for (const auto& [s, n] : per_source) std::cout << "position from " << s << "  " << n << "\n";
  std::cout << "measurements    " << recognitions << " (accepted " << accepted << ", rejected "
            << rejected << ")\n"
            << "regions         " << regions.size() << " of "
            << db.params().segmentation.region_size_m << " m\n"
            << "newest time     " << newest << "\n";
}

void printList(LandmarkDatabase& db) {
  std::cout << "landmark_id,camera,proposal_id,version,revision,created_utime,odom_x,odom_y,"
               "odom_theta,num_points,num_recognitions,num_accepted,num_rejected,"
               "last_seen_utime,position_source,x,y,theta,region_x,region_y\n";
  std::cout << std::setprecision(6);
  for (const auto& [id, i] : db.infos()) {
    const RegionKey k = db.regionOf(i.position());
    std::cout << id << ',' << i.camera << ',' << i.proposal_id << ',' << i.version << ','
              << i.revision << ',' << i.created_utime << ',' << i.created_odom.x << ','
              << i.created_odom.y << ',' << i.created_odom.theta << ',' << i.num_points << ','
              << i.stats.num_recognitions << ',' << i.stats.num_accepted << ','
              << i.stats.num_rejected << ',' << i.stats.last_seen_utime << ','
              << sourceName(i.pose_source) << ',' << i.position().x << ',' << i.position().y << ','
              << i.position().theta << ',' << k.ix << ',' << k.iy << '\n';
  }
}

void printRegions(LandmarkDatabase& db) {
  std::cout << "region_x,region_y,centre_x,centre_y,landmarks,replica_kib\n";
  for (const auto& r : db.regions()) {
    std::cout << r.key.ix << ',' << r.key.iy << ',' << r.centre_x << ',' << r.centre_y << ','
              << r.landmarks << ',' << std::fixed << std::setprecision(1)
              << static_cast<double>(r.replica_bytes) / 1024.0 << '\n';
  }
}

void writePng(const std::filesystem::path& file, const cv::Mat& img) {
  if (!cv::imwrite(file.string(), img)) {
    throw MapFileError("cannot write " + file.string());
  }
  std::cout << "wrote " << file.string() << "\n";
}

void plot(LandmarkDatabase& db, const std::filesystem::path& dir) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  const cv::Size size(900, 700);
  // Fig. 6: the landmarks (their estimated positions, the creation robot
  // poses in the map frame where known) and the creation poses with heading.
  {
    eval::Figure fig(size, "Landmarks and their creation poses", "x [m]", "y [m]");
    fig.setEqualAspect(true);
    eval::PlotSeries placed{
        "landmark (map pose)", cv::Scalar(200, 80, 0), {}, eval::PlotSeries::Style::kCircles, 2, 5};
    eval::PlotSeries created{"creation pose (odometry)",
                             cv::Scalar(0, 0, 200),
                             {},
                             eval::PlotSeries::Style::kCircles,
                             1,
                             3};
    std::vector<eval::PlotSeries> headings;
    for (const auto& [id, i] : db.infos()) {
      created.points.emplace_back(i.created_odom.x, i.created_odom.y);
      eval::PlotSeries h{"", cv::Scalar(0, 0, 200), {}, eval::PlotSeries::Style::kLine, 1, 1};
      h.points.emplace_back(i.created_odom.x, i.created_odom.y);
      h.points.emplace_back(i.created_odom.x + 0.3 * std::cos(i.created_odom.theta),
                            i.created_odom.y + 0.3 * std::sin(i.created_odom.theta));
      headings.push_back(std::move(h));
      if (i.pose_source != PoseSource::kOdometry) {
        placed.points.emplace_back(i.map_pose.x, i.map_pose.y);
      }
    }
    for (auto& h : headings) fig.add(std::move(h));
    fig.add(std::move(created));
    if (!placed.points.empty()) fig.add(std::move(placed));
    writePng(dir / "landmarks.png", fig.render());
  }
  // Fig. 10: the number of landmarks by the number of measurements made of them.
  {
    int max_n = 0;
    for (const auto& [id, i] : db.infos()) max_n = std::max(max_n, i.stats.num_recognitions);
    const int bins = std::max(1, std::min(40, max_n + 1));
    const double width = static_cast<double>(max_n + 1) / bins;
    std::vector<int> counts(static_cast<size_t>(bins), 0);
    for (const auto& [id, i] : db.infos()) {
      const int b = std::min(bins - 1, static_cast<int>(i.stats.num_recognitions / width));
      ++counts[static_cast<size_t>(b)];
    }
    eval::Figure fig(size, "Measurements per landmark", "measurements of a landmark", "landmarks");
    fig.setYFromZero(true);
    eval::PlotSeries bars{
        "landmarks", cv::Scalar(160, 60, 0), {}, eval::PlotSeries::Style::kLine, 2, 1};
    bars.points.emplace_back(0, 0);
    for (int b = 0; b < bins; ++b) {
      const double x0 = b * width, x1 = (b + 1) * width;
      const double h = counts[static_cast<size_t>(b)];
      bars.points.emplace_back(x0, h);
      bars.points.emplace_back(x1, h);
      bars.points.emplace_back(x1, 0);
      if (b + 1 < bins) bars.points.emplace_back(x1, counts[static_cast<size_t>(b + 1)]);
    }
    fig.add(std::move(bars));
    writePng(dir / "measurements_histogram.png", fig.render());
  }
}

// The command line into o; the exit code when the tool should stop here.
std::optional<int> parseMapToolArgs(const std::vector<std::string>& args, Options& o) {
  CLI::App app{"vslam-map: inspects and maintains a landmark map file (no LCM)", "vslam-map"};
  app.footer("Exit codes: 0 ok, 1 damaged or failing file, 2 usage or configuration error.");
  app.add_option("command", o.command,
                 "info: counts, ids, file size, revision, regions\n"
                 "list: one CSV line per landmark\n"
                 "regions: the map's regions (segmentation)\n"
                 "check: SQLite integrity check (exit 1 if damaged)\n"
                 "prune: remove landmarks by the configured policy [--dry-run]\n"
                 "plot: --out DIR: landmarks.png (Fig. 6),\n"
                 "measurements_histogram.png (Fig. 10)")
      ->required()
      ->check(CLI::IsMember({"info", "list", "regions", "check", "prune", "plot"}));
  app.add_option("file", o.file, "the map file")->required();
  app.add_option("--out", o.out, "plot: the folder to write to");
  app.add_option("--config", o.config,
                 "stack configuration: the prune policy and region size\n"
                 "(default $VSLAM_CONFIG, else config/vslam.yaml)");
  app.add_option("--instance", o.instance, "the landmark database's process instance")
      ->capture_default_str();
  app.add_flag("--dry-run", o.dry_run, "prune: list what would be removed, remove nothing");
  app.add_option("--now-utime", o.now, "ages for prune (default: the newest time in the file)");
  const auto code = parseCommandLine(app, "vslam-map", args, std::cout, std::cerr, [&] {
    if (o.command == "plot" && o.out.empty()) throw CLI::ValidationError("plot needs --out DIR");
  });
  if (code) return *code;
  o.config = config::resolveStackConfig(o.config);
  return std::nullopt;
}

}  // namespace

int runMapTool(const std::vector<std::string>& args) {
  Options o;
  if (const auto code = parseMapToolArgs(args, o)) return *code;
  DatabaseParams params;
  try {
    params = paramsFromConfig(o);
  } catch (const std::exception& e) {
    std::cerr << "vslam-map: " << e.what() << "\n";
    return kExitUsage;
  }
  // Every landmark is loaded for the tool: no memory budget here.
  params.segmentation.memory_budget_mb = 1e6;
  params.segmentation.active_radius_m = 1e9;
  try {
    if (o.command == "check") {
      StoreOptions so;
      so.create_if_missing = false;
      so.read_only = true;
      so.quick_check = false;
      LandmarkStore store(o.file, so);
      const std::string result = store.integrityCheck();
      std::cout << o.file << ": integrity_check " << result << "\n";
      return result == "ok" ? kExitOk : kExitDamaged;
    }
    auto db = openDatabase(o, params, o.command != "prune" || o.dry_run);
    if (o.command == "info") {
      printInfo(*db);
    } else if (o.command == "list") {
      printList(*db);
    } else if (o.command == "regions") {
      printRegions(*db);
    } else if (o.command == "plot") {
      plot(*db, o.out);
    } else if (o.command == "prune") {
      Utime now = o.now;
      if (now == 0) {
        for (const auto& [id, i] : db->infos()) {
          now = std::max({now, i.created_utime, i.stats.last_seen_utime});
        }
      }
      const auto removed = db->prune(now, o.dry_run);
      std::map<std::string, int> why;
      for (const auto& c : removed) {
        std::cout << (o.dry_run ? "would remove " : "removed ") << c.id << " (" << c.reason
                  << ")\n";
        ++why[c.reason];
      }
      std::cout << removed.size() << " of " << db->numStored() + (o.dry_run ? 0 : removed.size())
                << " landmarks " << (o.dry_run ? "would be " : "") << "pruned";
      for (const auto& [w, n] : why) std::cout << "; " << w << " " << n;
      std::cout << "\n";
    }
  } catch (const MapFileError& e) {
    std::cerr << "vslam-map: " << e.what() << "\n";
    return kExitDamaged;
  }
  return kExitOk;
}

}  // namespace vslam::landmark_db
