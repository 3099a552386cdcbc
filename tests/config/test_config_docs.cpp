// The parameter tables of docs/ are the declared ones (config/param_table.hpp),
// and config/vslam.yaml departs from the declared defaults only where this
// test says why. VSLAM_UPDATE_CONFIG_DOCS=1 rewrites the tables instead of
// comparing them (scripts/config-docs).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "stages/param_docs.hpp"

namespace fs = std::filesystem;
using vslam::stages::declaredParams;
using vslam::stages::documentedParamBlocks;

namespace {

const fs::path kSource = VSLAM_SOURCE_DIR;

vslam::config::StackConfig shippedStack() {
  return vslam::config::StackConfig::loadFile(kSource / "config/vslam.yaml");
}

std::string readFile(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// The same value to 4 significant digits where both are numbers: the file
// writes degrees where the structs hold radians.
bool sameValue(const std::string& a, const std::string& b) {
  char *end_a = nullptr, *end_b = nullptr;
  const double x = std::strtod(a.c_str(), &end_a), y = std::strtod(b.c_str(), &end_b);
  if (*end_a != 0 || *end_b != 0 || a.empty() || b.empty()) return a == b;
  return std::abs(x - y) <= 1e-4 * std::max(1e-3, std::abs(y));
}

}  // namespace

TEST(ConfigDocs, ParameterTablesAreTheDeclaredOnes) {
  const auto stack = shippedStack();
  const bool update = std::getenv("VSLAM_UPDATE_CONFIG_DOCS") != nullptr;
  std::set<std::string> documented;
  for (const auto& entry : fs::directory_iterator(kSource / "docs")) {
    if (entry.path().extension() != ".md") continue;
    const std::string text = readFile(entry.path());
    const std::string expected =
        vslam::stages::updateParamTables(text, stack, "in config/vslam.yaml");
    for (size_t at = text.find("\n<!-- params "); at != std::string::npos;
         at = text.find("\n<!-- params ", at + 1)) {
      documented.insert(text.substr(at + 13, text.find(" -->", at) - at - 13));
    }
    if (expected == text) continue;
    if (update) {
      std::ofstream(entry.path()) << expected;
      continue;
    }
    ADD_FAILURE() << entry.path() << ": a parameter table differs from the declaration in the "
                  << "code; run scripts/config-docs (or fix the declaration)";
  }
  for (const auto& block : documentedParamBlocks()) {
    EXPECT_TRUE(documented.count(block))
        << "no table of '" << block << "' in docs/: add <!-- params " << block
        << " --> <!-- /params --> where its keys are explained and run scripts/config-docs";
  }
}

TEST(ConfigDocs, TheShippedConfigDiffersFromTheDefaultsOnlyWhereItSaysWhy) {
  // block.key -> why config/vslam.yaml sets another value than the library.
  const std::map<std::string, std::string> why = {
      {"backend.landmark_min_interval_s", "correlated measurements (docs/backend.md, Robustness)"},
      {"backend.mixture.dual_ratio_max",
       "0.5 let aliases flood the set with dual particles in generated homes"},
      {"backend.mixture.motion_min_sigma_xy_m", "set with the robust likelihood (commit 62e4053)"},
      {"backend.mixture.motion_min_sigma_theta_deg", "as motion_min_sigma_xy_m"},
      {"backend.kidnap.detect_count", "wallpaper aliases fired 3 (commit 46f4641)"},
      {"backend.kidnap.detect_min_span_s", "repeated patterns (commit 72e71db)"},
      {"backend.kidnap.suspect_after", "repeated patterns (commit 72e71db)"},
      {"backend.kidnap.recover_landmarks", "one look-alike must not confirm a relocalization"},
      {"backend.kidnap.recover_window_s", "confirmation among look-alikes (commit 22854ee)"},
      {"backend.kidnap.drift_gate_mahalanobis_sq",
       "drift or kidnapping (commit 5553833; the paper has none)"},
      {"backend.kidnap.drift_sigma_scale", "the motion model's sigmas are a guess"},
      {"backend.kidnap.detect_dissent_ratio",
       "busy repeated patterns (generated home 1116; the paper has none)"},
      {"backend.measurement_sigma_xy_m",
       "Sigma_vis measured on generated homes (docs/backend.md); the library keeps the paper's"},
      {"backend.measurement_sigma_theta_deg", "as measurement_sigma_xy_m"},
      {"backend.measurement_sigma_xy_per_m", "as measurement_sigma_xy_m"},
      {"backend.measurement_sigma_theta_deg_per_m", "as measurement_sigma_xy_m"},
      {"backend.kidnap.cancel_count",
       "look-alikes that declared a kidnapping (tuning home 23; the paper has none)"},
      {"backend.map_correction.enabled",
       "map correction (commit 42605d4; the paper has the filter alone)"},
      {"backend.map_correction.solve_interval_s", "map correction (commit 42605d4)"},
      {"backend.map_correction.measurement_min_interval_s", "map correction (commit 42605d4)"},
      {"backend.map_correction.measurement_sigma_xy_per_m", "map correction (commit 42605d4)"},
      {"backend.map_correction.odometry_gate_mahalanobis_sq",
       "landmarks against the odometry (commit 6a47028)"},
      {"backend.odometry_calibration.enabled", "estimates reported in health (docs/backend.md)"},
      {"backend.map_prior_file",
       "a restarted back-end continues in the landmark DB's map (kill campaign, issue 19)"},
      {"backend.map_prior_start", "as map_prior_file: relocalize in that map"},
      {"appearance.map_file",
       "the live robot's topological map survives restarts and sessions (issue 19); the library "
       "keeps it in memory, as tests and replays do"},
      {"appearance.map_load", "as appearance.map_file"},
      {"appearance.map_save", "as appearance.map_file"},
      {"frontend.dim_frame_gain_target",
       "dim rooms of generated homes (docs/frontend.md); the library keeps the paper's frames"},
      {"frontend.view_jump_max_matched_share",
       "carried robots (docs/frontend.md, \"View jumps\"); the library's frames are not tested"},
      {"frontend.view_jump_min_thumbnail_similarity",
       "carries from plain walls, dark rooms and tiles (docs/frontend.md, \"View jumps\"); the "
       "library's frames are not tested"},
      {"frontend.view_jump_features_below_similarity",
       "carries between views of one pattern (docs/frontend.md, \"View jumps\"); the library's "
       "frames are not tested"},
      {"frontend.refine_distance_m",
       "tuning homes 21-52 (docs/benchmark-homes.md); the library keeps the paper's three views"},
      {"frontend.coverage_gate_sigmas",
       "repeated wall patterns of tuning homes 1200-1219 (docs/frontend.md, \"Coverage checked by "
       "the odometry\"); the library keeps the paper's coverage by any accepted measurement"},
      {"backend.kidnap.view_jump_window_s",
       "carries of the tuning homes (docs/backend.md, \"View jumps\"); the library ignores them"},
      {"backend.kidnap.unchecked_jump_window_s",
       "a carry into a part of the home not mapped yet (docs/backend.md, \"View jumps\"); off in "
       "the library as view jumps are"},
      {"backend.kidnap.moved_evidence_s",
       "carries of the tuning homes 21-52 (docs/backend.md, \"View jumps\"); off in the library "
       "as view jumps are"},
      {"backend.kidnap.declare_on_every_view_jump",
       "carries of the generated homes 1260-1289 (docs/backend.md, \"View jumps\"); off in the "
       "library as view jumps are"},
      {"camera.width", "the robot file's cameras are calibrated at 320x240"},
      {"camera.height", "as camera.width"},
      {"camera.max_fps", "the robot file's frame_rate_hz (10)"},
      {"frontend.min_matches",
       "92% of measurements pass the pre-filter on the apartment at 16, 79% at 10 (commit "
       "8b77e34)"},
  };
  const auto stack = shippedStack();
  std::set<std::string> differing;
  for (const auto& block : documentedParamBlocks()) {
    for (const auto& row : declaredParams(block, &stack)) {
      // A required key has no default to differ from: the robot's odometry, its cameras, ...
      if (row.default_value == "required" || row.configured.empty() ||
          sameValue(row.configured, row.default_value)) {
        continue;
      }
      const std::string key = block + "." + row.key;
      differing.insert(key);
      EXPECT_TRUE(why.count(key)) << key << ": config/vslam.yaml sets " << row.configured
                                  << ", the library " << row.default_value
                                  << " (say why in this test, or make them agree)";
    }
  }
  for (const auto& [key, reason] : why) {
    EXPECT_TRUE(differing.count(key))
        << key << " is listed as differing (" << reason << ") but config/vslam.yaml agrees";
  }
}
