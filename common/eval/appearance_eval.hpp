#pragma once
// vslam-eval --appearance: the appearance SLAM process against ground truth,
// like Lee & Sowmya's Figs. 8-11. From one log that holds the process's
// APPEARANCE_HYPOTHESES and APPEARANCE_EVENT and the simulator's
// GROUND_TRUTH (vslam-replay keeps its input):
//   - the number of path hypotheses at each step (Fig. 8);
//   - the x, y and heading error of every hypothesis that places the robot
//     in a previously visited state (the new-state hypothesis is excluded,
//     as the paper does): the true pose where that state's snapshot was
//     taken minus the robot's true pose now (Figs. 9-11);
//   - each re-localisation event, with the true distance between the robot
//     and the state it re-localised to (correct if below one action length);
//   - recognition: of the steps at which the robot truly is at a mapped place
//     (near a state made earlier), those whose most believed hypothesis is a
//     revisit of a state near the robot; and the steps at which it is a
//     revisit of a state far from it (a committed wrong belief);
//   - carries and kidnappings (a jump in the ground truth) and restarts in a
//     loaded map: the steps from reaching a place mapped before the event to
//     the first step whose most believed hypothesis is correctly back in it.
// A state's snapshot time is that of the step whose new-state hypothesis
// named it (or the map message's, for states of a loaded map).

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace vslam::eval {

struct AppearanceEvalOptions {
  std::string hypotheses_channel = "APPEARANCE_HYPOTHESES";
  std::string event_channel = "APPEARANCE_EVENT";
  std::string map_channel = "APPEARANCE_MAP";
  std::string ref_channel = "GROUND_TRUTH";
  double action_length_m = 1.0;  // a re-localisation is correct within this distance
  // The robot is at a mapped place when a state made before (not at the
  // step just before) is this close and faces within 45 degrees (of the
  // robot, or of the robot turned around: AppearanceReport::states_either_way).
  double revisit_radius_m = 0.5;
  double carry_step_m = 0.5;  // a ground-truth step longer than this is a carry or kidnapping
};

struct AppearanceHypothesisError {
  int64_t step = 0;
  int64_t state_id = 0;
  double belief = 0;
  double ex = 0, ey = 0, eheading = 0;  // metres, metres, radians (state minus robot)
  double position() const;
};

struct AppearanceStepRow {
  int64_t step = 0;
  double t = 0;  // seconds since the first step
  int hypotheses = 0;
  int revisits = 0;  // hypotheses in previously visited states
  bool best_is_revisit = false;
  double mean_position_error = 0;     // over revisits; NaN if none
  double best_position_error = 0;     // of the most believed, if a revisit; else NaN
  double nearest_state_distance = 0;  // robot to the nearest earlier state; NaN if none
  bool at_mapped_place = false;  // a state made before the previous step is within revisit_radius_m
  bool best_correct = false;     // the most believed is a revisit within action_length_m
  bool best_wrong = false;       // ... a revisit action_length_m or more away
};

// A carry or kidnapping (the ground truth jumps), or a restart in a loaded
// map (the first step already has revisit hypotheses), and how long the
// process took to be back in the map after it.
struct AppearanceKidnap {
  enum class Kind { kCarry, kRestart };
  enum class Status { kRelocalized, kNotRelocalized, kNoMappedPlaceReached };
  Kind kind = Kind::kCarry;
  int64_t step = 0;  // the first step after it
  double t = 0;      // seconds since the first step
  Status status = Status::kNoMappedPlaceReached;
  int64_t first_mapped_step = -1;    // first step at a place mapped before it; -1: none
  int64_t first_correct_step = -1;   // first step whose best is a correct revisit of such a place
  int64_t steps_to_relocalize = -1;  // first_correct_step - first_mapped_step, at least 0
};

struct AppearanceRelocalization {
  int64_t step = 0;
  double t = 0;
  int64_t state_id = 0;
  int64_t previous_state_id = -1;
  double belief = 0;
  double position_error = 0;  // NaN when the state's true pose is unknown
  double heading_error = 0;
  bool correct = false;
};

struct AppearanceReport {
  std::string input;
  AppearanceEvalOptions options;
  std::vector<AppearanceStepRow> steps;
  std::vector<AppearanceHypothesisError> errors;  // every revisit hypothesis of every step
  std::vector<AppearanceRelocalization> relocalizations;
  int64_t relocalizations_correct = 0, relocalizations_wrong = 0;
  int64_t revisit_steps = 0;             // steps at a mapped place
  int64_t revisit_steps_recognized = 0;  // ... whose most believed is a correct revisit
  int64_t wrong_revisit_steps = 0;       // steps whose most believed is a wrong revisit
  std::vector<AppearanceKidnap> kidnaps;
  int64_t unknown_states = 0;  // revisit hypotheses whose state has no ground truth
  int64_t states_created = 0;  // distinct new-state ids seen (one per snapshot that had one)
  int64_t map_states = -1;     // states in the last map message; -1 if none
  int64_t map_links = -1;
  // The appearance process's cameras (from its map messages) include two
  // that face opposite ways (their calibration messages in the log;
  // appearance::turnedCameras): a state then counts as mapped facing either
  // way, for the nearest state, the mapped places and the heading errors.
  bool states_either_way = false;
  std::string either_way_cameras;  // e.g. "forward/backward"
  int max_hypotheses = 0;
  double mean_hypotheses = 0;
  // Over every revisit hypothesis of every step.
  double mean_position_error = 0, median_position_error = 0, max_position_error = 0;
  double mean_abs_heading_error = 0;  // radians
  double fraction_within_action = 0;  // position error below action_length_m
  // Steps whose most believed hypothesis is a revisit, and its error there.
  int64_t steps_best_revisit = 0;
  double mean_best_position_error = 0;
  // The floor of the position error: on the same steps as the revisit
  // hypotheses, the true distance from the robot to the nearest state made
  // before (heading within 45 degrees, either way if states_either_way), i.e. what the best
  // possible hypothesis would score. A second lap driven beside the first cannot do better than
  // this.
  double mean_nearest_state_distance = 0;
  // The same two weighted by each hypothesis' belief: where the tree
  // believes the robot is.
  double weighted_position_error = 0, weighted_nearest_state_distance = 0;
  double mean_step_seconds = 0, max_step_seconds = 0;  // the process's own timing
};

AppearanceReport evaluateAppearanceLog(const std::filesystem::path& log,
                                       const AppearanceEvalOptions& options);
void printAppearanceReport(std::ostream& out, const AppearanceReport& report);
void writeAppearanceJson(const std::filesystem::path& file, const AppearanceReport& report);
// hypotheses.png (Fig. 8), error_x.png, error_y.png, error_heading.png (Figs. 9-11).
std::vector<std::filesystem::path> writeAppearancePlots(const std::filesystem::path& dir,
                                                        const AppearanceReport& report,
                                                        cv::Size size);

// The --appearance mode of vslam-eval: its options, added to the mode's
// parser, and the run over them.
struct AppearanceEvalArgs {
  std::optional<std::filesystem::path> log, plot_dir, json;
  AppearanceEvalOptions options;
  cv::Size plot_size{1000, 800};
};
void addAppearanceEvalOptions(CLI::App& app, AppearanceEvalArgs& args);
int runAppearanceEval(const AppearanceEvalArgs& args, std::ostream& out);

}  // namespace vslam::eval
