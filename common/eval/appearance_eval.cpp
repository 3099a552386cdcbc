#include "eval/appearance_eval.hpp"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <map>
#include <optional>
#include <ostream>
#include <sstream>
#include <vslam/appearance_event_t.hpp>
#include <vslam/appearance_hypotheses_t.hpp>
#include <vslam/appearance_map_t.hpp>
#include <vslam/camera_calibration_t.hpp>
#include <vslam/ground_truth_pose_t.hpp>

#include "appearance/path_hypotheses.hpp"
#include "eval/command_line.hpp"
#include "eval/errors.hpp"
#include "eval/json_report.hpp"
#include "eval/log_events.hpp"
#include "eval/plot.hpp"
#include "odometry/pose2.hpp"
#include "util/angles.hpp"
#include "util/log.hpp"
#include "util/statistics.hpp"

namespace vslam::eval {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct TruePose {
  int64_t utime;
  double x, y, theta;
};

// Ground truth at a time, linearly interpolated; false outside the log's span.
bool truthAt(const std::vector<TruePose>& truth, int64_t utime, TruePose* out) {
  if (truth.empty() || utime < truth.front().utime || utime > truth.back().utime) return false;
  const auto it = std::lower_bound(truth.begin(), truth.end(), utime,
                                   [](const TruePose& p, int64_t t) { return p.utime < t; });
  if (it->utime == utime || it == truth.begin()) {
    *out = *it;
    return true;
  }
  const TruePose& a = *std::prev(it);
  const TruePose& b = *it;
  const double s = static_cast<double>(utime - a.utime) / static_cast<double>(b.utime - a.utime);
  const Pose2 p = interpolate({a.x, a.y, a.theta}, {b.x, b.y, b.theta}, s);
  *out = {utime, p.x, p.y, p.theta};
  return true;
}

std::string fmt(double v, int decimals = 3) {
  if (!std::isfinite(v)) return "-";
  std::ostringstream os;
  os << std::fixed << std::setprecision(decimals) << v;
  return os.str();
}

// Carries and kidnappings: where consecutive ground-truth poses are farther
// apart than options.carry_step_m; a restart: the first step already has a
// revisit hypothesis (a loaded map). For each, the steps from the first at
// a place mapped before it to the first whose most believed hypothesis is a
// correct revisit of a state made before it.
template <typename NearestState>
std::vector<AppearanceKidnap> findKidnaps(const std::vector<vslam::appearance_hypotheses_t>& steps,
                                          const std::vector<TruePose>& truth,
                                          const std::map<int64_t, int64_t>& state_utime,
                                          const std::vector<AppearanceStepRow>& rows,
                                          const AppearanceEvalOptions& options,
                                          NearestState nearest_state) {
  std::vector<std::pair<int64_t, AppearanceKidnap::Kind>> events;
  const auto& first = steps.front();
  if (std::any_of(first.hypotheses.begin(), first.hypotheses.end(),
                  [](const auto& h) { return !h.is_new_state; })) {
    events.emplace_back(first.utime, AppearanceKidnap::Kind::kRestart);
  }
  for (size_t i = 1; i < truth.size(); ++i) {
    const double jump = std::hypot(truth[i].x - truth[i - 1].x, truth[i].y - truth[i - 1].y);
    if (jump > options.carry_step_m && truth[i].utime > first.utime) {
      events.emplace_back(truth[i].utime, AppearanceKidnap::Kind::kCarry);
    }
  }
  std::vector<AppearanceKidnap> out;
  for (size_t e = 0; e < events.size(); ++e) {
    const int64_t at = events[e].first;
    const int64_t until =
        e + 1 < events.size() ? events[e + 1].first : std::numeric_limits<int64_t>::max();
    AppearanceKidnap k;
    k.kind = events[e].second;
    bool any_step = false;
    for (size_t i = 0; i < steps.size(); ++i) {
      const auto& s = steps[i];
      if (s.utime < at || s.utime >= until) continue;
      if (!any_step) {
        any_step = true;
        k.step = s.step;
        k.t = 1e-6 * static_cast<double>(s.utime - first.utime);
      }
      if (k.first_mapped_step < 0 && nearest_state(s.utime, at) < options.revisit_radius_m) {
        k.first_mapped_step = s.step;
      }
      if (k.first_correct_step < 0 && rows[i].best_correct) {
        const auto made = state_utime.find(s.best_state_id);
        if (made != state_utime.end() && made->second < at) k.first_correct_step = s.step;
      }
    }
    if (!any_step) continue;  // the log ends before another step
    if (k.first_correct_step >= 0) {
      k.status = AppearanceKidnap::Status::kRelocalized;
      const int64_t from = k.first_mapped_step >= 0 ? k.first_mapped_step : k.first_correct_step;
      k.steps_to_relocalize = std::max<int64_t>(0, k.first_correct_step - from);
    } else {
      k.status = k.first_mapped_step >= 0 ? AppearanceKidnap::Status::kNotRelocalized
                                          : AppearanceKidnap::Status::kNoMappedPlaceReached;
    }
    out.push_back(k);
  }
  return out;
}

const char* kindName(AppearanceKidnap::Kind kind) {
  return kind == AppearanceKidnap::Kind::kRestart ? "restart" : "carry";
}

const char* statusName(AppearanceKidnap::Status status) {
  switch (status) {
    case AppearanceKidnap::Status::kRelocalized:
      return "relocalized";
    case AppearanceKidnap::Status::kNotRelocalized:
      return "not relocalized";
    case AppearanceKidnap::Status::kNoMappedPlaceReached:
      break;
  }
  return "no mapped place reached";
}

// A step index; null for none (-1).
Json jsonStep(int64_t step) { return step < 0 ? Json(nullptr) : Json(step); }

// What the evaluation reads from the log.
struct AppearanceLog {
  std::vector<TruePose> truth;  // sorted by time
  std::vector<vslam::appearance_hypotheses_t> steps;
  std::vector<vslam::appearance_event_t> events;
  std::map<int64_t, int64_t> state_utime;  // state id -> time its snapshot was taken
  std::vector<std::string> cameras;        // the appearance process's, from its map messages
  std::map<std::string, vslam::camera_calibration_t> calibrations;  // by camera name
  bool either_way = false;  // AppearanceReport::states_either_way
};

// Whether two of the appearance process's cameras face opposite ways, as
// the process itself decides it (appearance::turnedCameras); their names.
std::optional<std::string> oppositeCameras(const AppearanceLog& in) {
  std::vector<appearance::CameraView> views;
  for (const auto& name : in.cameras) {
    const auto it = in.calibrations.find(name);
    if (it == in.calibrations.end()) return std::nullopt;
    const auto& c = it->second;
    const Eigen::Quaterniond q(c.robot_q_camera[0], c.robot_q_camera[1], c.robot_q_camera[2],
                               c.robot_q_camera[3]);
    views.push_back(appearance::cameraView(q.normalized().toRotationMatrix(), c.width, c.fx));
  }
  const auto turned = appearance::turnedCameras(views);
  for (size_t i = 0; i < turned.size(); ++i) {
    if (turned[i] >= 0) return in.cameras[i] + "/" + in.cameras[static_cast<size_t>(turned[i])];
  }
  return std::nullopt;
}

// Reads the log's channels; DataError without steps or ground truth. Sets
// the report's map counts from the last map message.
AppearanceLog readAppearanceLog(const fs::path& log, const AppearanceEvalOptions& options,
                                AppearanceReport* r) {
  AppearanceLog in;
  const auto counts = forEachLogEvent(log, [&](const LogEventRef& e) {
    const std::string& ch = e.event.channel;
    if (ch == options.ref_channel) {
      const auto m = decodeEvent<vslam::ground_truth_pose_t>(e, "vslam.ground_truth_pose_t");
      in.truth.push_back({m.utime, m.x, m.y, m.theta});
    } else if (ch == options.hypotheses_channel) {
      in.steps.push_back(
          decodeEvent<vslam::appearance_hypotheses_t>(e, "vslam.appearance_hypotheses_t"));
    } else if (ch == options.event_channel) {
      in.events.push_back(decodeEvent<vslam::appearance_event_t>(e, "vslam.appearance_event_t"));
    } else if (ch == options.map_channel) {
      const auto m = decodeEvent<vslam::appearance_map_t>(e, "vslam.appearance_map_t");
      for (const auto& s : m.states) in.state_utime.emplace(s.state_id, s.utime);
      if (!m.states.empty()) in.cameras = m.states.front().cameras;
      r->map_states = m.num_states;
      r->map_links = m.num_links;
    } else if (isEventOf<vslam::camera_calibration_t>(e)) {
      // Only says whether states count either way: a damaged one is named
      // and skipped, not a reason to judge nothing.
      try {
        const auto c = decodeEvent<vslam::camera_calibration_t>(e, "vslam.camera_calibration_t");
        in.calibrations[c.camera] = c;
      } catch (const DataError& err) {
        log::warn(err.what(), ": skipped");
      }
    }
  });
  if (in.steps.empty()) {
    throw DataError(log.string() + ": no " + options.hypotheses_channel +
                    " messages (channels: " + channelList(counts) + ")");
  }
  if (in.truth.empty()) {
    throw DataError(log.string() + ": no ground truth on " + options.ref_channel +
                    " (channels: " + channelList(counts) + ")");
  }
  std::sort(in.truth.begin(), in.truth.end(),
            [](const TruePose& a, const TruePose& b) { return a.utime < b.utime; });
  if (const auto names = oppositeCameras(in)) {
    in.either_way = true;
    r->states_either_way = true;
    r->either_way_cameras = *names;
  }
  // The new-state hypothesis of each step names the state its snapshot made.
  for (const auto& s : in.steps) {
    for (const auto& h : s.hypotheses) {
      if (h.is_new_state) in.state_utime[h.state_id] = s.utime;
    }
  }
  return in;
}

// The ground truth of the robot and of the states, as the measures need it.
class StateTruth {
 public:
  explicit StateTruth(const AppearanceLog& in) : in_(in) {
    for (const auto& [id, utime] : in.state_utime) {
      TruePose p;
      if (truthAt(in.truth, utime, &p)) state_truth_.emplace_back(utime, p);
    }
  }

  // Error of "the robot is in state k" at time t: state's true pose minus
  // the robot's; false if either is unknown.
  bool errorOf(int64_t state_id, int64_t utime, AppearanceHypothesisError* e) const {
    const auto it = in_.state_utime.find(state_id);
    TruePose now, then;
    if (it == in_.state_utime.end() || !truthAt(in_.truth, utime, &now) ||
        !truthAt(in_.truth, it->second, &then)) {
      return false;
    }
    e->ex = then.x - now.x;
    e->ey = then.y - now.y;
    e->eheading = wrapAngle(then.theta - now.theta);
    // A state revisited turned around: its error from the turned heading.
    if (in_.either_way && std::abs(e->eheading) > M_PI / 2) {
      e->eheading = wrapAngle(e->eheading - M_PI);
    }
    return true;
  }

  // The robot's true distance at `utime` to the nearest state made before
  // `made_before` and facing within 45 degrees of it (or of it turned
  // around, if the states count either way); NaN if none.
  double nearestState(int64_t utime, int64_t made_before) const {
    TruePose now;
    if (!truthAt(in_.truth, utime, &now)) return kNaN;
    double best = kNaN;
    for (const auto& [t, p] : state_truth_) {
      const double turn = std::abs(wrapAngle(p.theta - now.theta));
      const bool facing = turn <= M_PI / 4 || (in_.either_way && turn >= 3 * M_PI / 4);
      if (t >= made_before || !facing) continue;
      const double d = std::hypot(p.x - now.x, p.y - now.y);
      if (!(d >= best)) best = d;
    }
    return best;
  }

 private:
  const AppearanceLog& in_;
  std::vector<std::pair<int64_t, TruePose>> state_truth_;
};

// Sums over the steps, for the report's averages.
struct StepTotals {
  std::vector<double> pos, heading, best_pos, step_seconds, nearest;
  double weight_sum = 0, weighted_pos_sum = 0, weighted_nearest_sum = 0;
  int64_t within = 0;
  double hyp_sum = 0;
};

// One step's row: its revisit hypotheses' errors (added to r->errors and
// the totals), whether the robot is at a mapped place and the best is right.
AppearanceStepRow scoreStep(const vslam::appearance_hypotheses_t& s, int64_t t0,
                            int64_t previous_utime, const StateTruth& truth,
                            const AppearanceEvalOptions& options, AppearanceReport* r,
                            StepTotals* totals) {
  AppearanceStepRow row;
  row.step = s.step;
  row.t = 1e-6 * static_cast<double>(s.utime - t0);
  row.hypotheses = static_cast<int>(s.hypotheses.size());
  row.mean_position_error = kNaN;
  row.best_position_error = kNaN;
  std::vector<double> step_pos;
  double step_weight = 0, step_weighted_pos = 0;
  for (size_t i = 0; i < s.hypotheses.size(); ++i) {
    const auto& h = s.hypotheses[i];
    if (h.is_new_state) continue;
    ++row.revisits;
    AppearanceHypothesisError e;
    e.step = s.step;
    e.state_id = h.state_id;
    e.belief = h.belief;
    if (!truth.errorOf(h.state_id, s.utime, &e)) {
      ++r->unknown_states;
      continue;
    }
    r->errors.push_back(e);
    step_pos.push_back(e.position());
    step_weight += h.belief;
    step_weighted_pos += h.belief * e.position();
    totals->pos.push_back(e.position());
    totals->heading.push_back(std::abs(e.eheading));
    totals->within += e.position() < options.action_length_m;
    if (h.state_id == s.best_state_id && i == 0) row.best_position_error = e.position();
  }
  row.best_is_revisit = !s.hypotheses.empty() && !s.hypotheses.front().is_new_state;
  row.nearest_state_distance = truth.nearestState(s.utime, s.utime);
  // The state of the step before is where the robot just came from, not a
  // place it came back to.
  row.at_mapped_place = truth.nearestState(s.utime, previous_utime) < options.revisit_radius_m;
  if (row.best_is_revisit && std::isfinite(row.best_position_error)) {
    row.best_correct = row.best_position_error < options.action_length_m;
    row.best_wrong = !row.best_correct;
  }
  r->revisit_steps += row.at_mapped_place;
  r->revisit_steps_recognized += row.at_mapped_place && row.best_correct;
  r->wrong_revisit_steps += row.best_wrong;
  if (!step_pos.empty() && std::isfinite(row.nearest_state_distance)) {
    for (size_t k = 0; k < step_pos.size(); ++k) {
      totals->nearest.push_back(row.nearest_state_distance);
    }
    totals->weight_sum += step_weight;
    totals->weighted_pos_sum += step_weighted_pos;
    totals->weighted_nearest_sum += step_weight * row.nearest_state_distance;
  }
  row.mean_position_error = mean(step_pos);
  if (row.best_is_revisit && std::isfinite(row.best_position_error)) {
    ++r->steps_best_revisit;
    totals->best_pos.push_back(row.best_position_error);
  }
  return row;
}

// The report's averages over the steps.
void summarizeSteps(const StepTotals& t, std::size_t steps, AppearanceReport* r) {
  r->mean_hypotheses = t.hyp_sum / static_cast<double>(steps);
  r->mean_position_error = mean(t.pos);
  r->weighted_position_error = t.weight_sum > 0 ? t.weighted_pos_sum / t.weight_sum : kNaN;
  r->weighted_nearest_state_distance =
      t.weight_sum > 0 ? t.weighted_nearest_sum / t.weight_sum : kNaN;
  r->median_position_error = median(t.pos);
  r->max_position_error = t.pos.empty() ? kNaN : *std::max_element(t.pos.begin(), t.pos.end());
  r->mean_abs_heading_error = mean(t.heading);
  r->fraction_within_action =
      t.pos.empty() ? kNaN : static_cast<double>(t.within) / static_cast<double>(t.pos.size());
  r->mean_best_position_error = mean(t.best_pos);
  r->mean_nearest_state_distance = mean(t.nearest);
  r->mean_step_seconds = mean(t.step_seconds);
  r->max_step_seconds = *std::max_element(t.step_seconds.begin(), t.step_seconds.end());
}

// Each re-localisation event, judged by the true distance to its state.
void scoreRelocalizations(const std::vector<vslam::appearance_event_t>& events, int64_t t0,
                          const StateTruth& truth, const AppearanceEvalOptions& options,
                          AppearanceReport* r) {
  for (const auto& ev : events) {
    if (ev.event != vslam::appearance_event_t::EVENT_RELOCALIZED) continue;
    AppearanceRelocalization rl;
    rl.step = ev.step;
    rl.t = 1e-6 * static_cast<double>(ev.utime - t0);
    rl.state_id = ev.state_id;
    rl.previous_state_id = ev.previous_state_id;
    rl.belief = ev.belief;
    AppearanceHypothesisError e;
    if (truth.errorOf(ev.state_id, ev.utime, &e)) {
      rl.position_error = e.position();
      rl.heading_error = e.eheading;
      rl.correct = rl.position_error < options.action_length_m;
    } else {
      rl.position_error = rl.heading_error = kNaN;
    }
    r->relocalizations.push_back(rl);
    r->relocalizations_correct += rl.correct;
    r->relocalizations_wrong += std::isfinite(rl.position_error) && !rl.correct;
  }
}

}  // namespace

double AppearanceHypothesisError::position() const { return std::hypot(ex, ey); }

AppearanceReport evaluateAppearanceLog(const fs::path& log, const AppearanceEvalOptions& options) {
  AppearanceReport r;
  r.input = log.string();
  r.options = options;
  const AppearanceLog in = readAppearanceLog(log, options, &r);
  std::map<int64_t, bool> created;
  for (const auto& s : in.steps) {
    for (const auto& h : s.hypotheses) {
      if (h.is_new_state) created[h.state_id] = true;
    }
  }
  r.states_created = static_cast<int64_t>(created.size());

  const int64_t t0 = in.steps.front().utime;
  const StateTruth truth(in);
  StepTotals totals;
  int64_t previous_utime = std::numeric_limits<int64_t>::min();
  for (const auto& s : in.steps) {
    const AppearanceStepRow row = scoreStep(s, t0, previous_utime, truth, options, &r, &totals);
    previous_utime = s.utime;
    r.max_hypotheses = std::max(r.max_hypotheses, row.hypotheses);
    totals.hyp_sum += row.hypotheses;
    totals.step_seconds.push_back(s.step_seconds);
    r.steps.push_back(row);
  }
  summarizeSteps(totals, in.steps.size(), &r);
  scoreRelocalizations(in.events, t0, truth, options, &r);
  r.kidnaps = findKidnaps(in.steps, in.truth, in.state_utime, r.steps, options,
                          [&truth](int64_t utime, int64_t made_before) {
                            return truth.nearestState(utime, made_before);
                          });
  return r;
}

void printAppearanceReport(std::ostream& out, const AppearanceReport& r) {
  out << "appearance SLAM: " << r.input << "\n"
      << "  steps                 " << r.steps.size() << " (snapshots that became a new state in "
      << "some hypothesis: " << r.states_created << ")\n"
      << "  final map             "
      << (r.map_states < 0
              ? std::string("- (no map message)")
              : std::to_string(r.map_states) + " states, " + std::to_string(r.map_links) + " links")
      << "\n"
      << "  hypotheses            mean " << fmt(r.mean_hypotheses, 1) << ", max "
      << r.max_hypotheses << "\n"
      << "  revisit hypotheses    " << r.errors.size() << " (new-state hypotheses excluded"
      << (r.unknown_states ? ", " + std::to_string(r.unknown_states) + " without ground truth" : "")
      << ")\n"
      << "  position error        mean " << fmt(r.mean_position_error) << " m, median "
      << fmt(r.median_position_error) << " m, max " << fmt(r.max_position_error) << " m; "
      << fmt(100.0 * r.fraction_within_action, 1) << " % within "
      << fmt(r.options.action_length_m, 2) << " m (one action)\n"
      << "  nearest state         " << fmt(r.mean_nearest_state_distance)
      << " m on average: the floor of the position error (the robot's true distance to the\n"
      << "                        nearest earlier state, weighted as the hypotheses above)\n"
      << (r.states_either_way ? "                        states count facing either way: cameras " +
                                    r.either_way_cameras + " face opposite ways\n"
                              : std::string())
      << "  weighted by belief    position error " << fmt(r.weighted_position_error)
      << " m, nearest state " << fmt(r.weighted_nearest_state_distance)
      << " m (each hypothesis counted by its\n"
      << "                        belief: where the tree believes the robot is)\n"
      << "  heading error         mean |e| " << fmt(radToDeg(r.mean_abs_heading_error), 2)
      << " deg\n"
      << "  best is a revisit     " << r.steps_best_revisit << " steps, its mean position error "
      << fmt(r.mean_best_position_error) << " m\n"
      << "  step time             mean " << fmt(1e3 * r.mean_step_seconds, 2) << " ms, max "
      << fmt(1e3 * r.max_step_seconds, 2) << " ms (as the process measured it)\n"
      << "  recognized revisits   " << r.revisit_steps_recognized << " of the " << r.revisit_steps
      << " steps at a mapped place (within " << fmt(r.options.revisit_radius_m, 2)
      << " m of a state made before)\n"
      << "  wrong beliefs         " << r.wrong_revisit_steps
      << " steps whose most believed hypothesis is a revisit " << fmt(r.options.action_length_m, 2)
      << " m or more from the robot\n";
  for (const auto& k : r.kidnaps) {
    out << "  " << std::left << std::setw(22) << kindName(k.kind) << std::right << "before step "
        << k.step << " (t " << fmt(k.t, 1) << " s): " << statusName(k.status);
    if (k.status == AppearanceKidnap::Status::kRelocalized) {
      out << " at step " << k.first_correct_step << ", " << k.steps_to_relocalize
          << " steps after reaching a mapped place";
    } else if (k.status == AppearanceKidnap::Status::kNotRelocalized) {
      out << " (a mapped place reached at step " << k.first_mapped_step << ")";
    }
    out << "\n";
  }
  out << "  re-localizations      " << r.relocalizations.size() << " (" << r.relocalizations_correct
      << " correct, " << r.relocalizations_wrong << " wrong)\n";
  for (const auto& rl : r.relocalizations) {
    out << "    step " << std::setw(4) << rl.step << "  t " << std::setw(7) << fmt(rl.t, 1)
        << " s  -> state " << std::setw(5) << rl.state_id << " (from " << rl.previous_state_id
        << ")  belief " << fmt(rl.belief, 3) << "  true distance " << fmt(rl.position_error, 2)
        << " m, heading " << fmt(radToDeg(rl.heading_error), 1) << " deg  "
        << (std::isfinite(rl.position_error) ? (rl.correct ? "correct" : "WRONG") : "unknown")
        << "\n";
  }
}

void writeAppearanceJson(const fs::path& file, const AppearanceReport& r) {
  Json j;
  j["input"] = r.input;
  j["steps"] = r.steps.size();
  j["states_created"] = r.states_created;
  j["map_states"] = r.map_states;
  j["map_links"] = r.map_links;
  j["mean_hypotheses"] = jsonNumber(r.mean_hypotheses);
  j["max_hypotheses"] = r.max_hypotheses;
  j["revisit_hypotheses"] = r.errors.size();
  j["mean_position_error_m"] = jsonNumber(r.mean_position_error);
  j["weighted_position_error_m"] = jsonNumber(r.weighted_position_error);
  j["weighted_nearest_state_distance_m"] = jsonNumber(r.weighted_nearest_state_distance);
  j["median_position_error_m"] = jsonNumber(r.median_position_error);
  j["max_position_error_m"] = jsonNumber(r.max_position_error);
  j["mean_abs_heading_error_rad"] = jsonNumber(r.mean_abs_heading_error);
  j["fraction_within_action"] = jsonNumber(r.fraction_within_action);
  j["steps_best_revisit"] = r.steps_best_revisit;
  j["mean_best_position_error_m"] = jsonNumber(r.mean_best_position_error);
  j["mean_nearest_state_distance_m"] = jsonNumber(r.mean_nearest_state_distance);
  j["states_either_way"] = r.states_either_way;
  j["mean_step_seconds"] = jsonNumber(r.mean_step_seconds);
  j["revisit_steps"] = r.revisit_steps;
  j["revisit_steps_recognized"] = r.revisit_steps_recognized;
  j["wrong_revisit_steps"] = r.wrong_revisit_steps;
  j["relocalizations_correct"] = r.relocalizations_correct;
  j["relocalizations_wrong"] = r.relocalizations_wrong;
  Json& kidnaps = j["kidnaps"] = Json::array();
  for (const auto& k : r.kidnaps) {
    kidnaps.push_back({{"kind", kindName(k.kind)},
                       {"step", k.step},
                       {"t", jsonNumber(k.t)},
                       {"status", statusName(k.status)},
                       {"first_mapped_step", jsonStep(k.first_mapped_step)},
                       {"first_correct_step", jsonStep(k.first_correct_step)},
                       {"steps_to_relocalize", jsonStep(k.steps_to_relocalize)}});
  }
  Json& relocalizations = j["relocalizations"] = Json::array();
  for (const auto& rl : r.relocalizations) {
    relocalizations.push_back({{"step", rl.step},
                               {"t", jsonNumber(rl.t)},
                               {"state_id", rl.state_id},
                               {"previous_state_id", rl.previous_state_id},
                               {"belief", jsonNumber(rl.belief)},
                               {"position_error_m", jsonNumber(rl.position_error)},
                               {"heading_error_rad", jsonNumber(rl.heading_error)},
                               {"correct", rl.correct}});
  }
  writeJsonFile(file, j);
}

std::vector<fs::path> writeAppearancePlots(const fs::path& dir, const AppearanceReport& r,
                                           cv::Size size) {
  ensurePlotDirectory(dir);
  const cv::Scalar kBlack(0, 0, 0), kRed(40, 40, 220), kBlue(200, 90, 20), kGrey(150, 150, 150);

  Figure count(size, "Number of path hypotheses (Fig. 8)", "step", "hypotheses");
  PlotSeries all{"all hypotheses", kBlack, {}};
  PlotSeries revisits{"in visited states", kBlue, {}};
  for (const auto& s : r.steps) {
    all.points.emplace_back(static_cast<double>(s.step), s.hypotheses);
    revisits.points.emplace_back(static_cast<double>(s.step), s.revisits);
  }
  count.add(all);
  count.add(revisits);
  count.setYFromZero(true);
  if (!r.relocalizations.empty()) {
    PlotSeries marks{"re-localization", kRed, {}, PlotSeries::Style::kCircles, 2, 6};
    for (const auto& rl : r.relocalizations) {
      for (const auto& s : r.steps) {
        if (s.step == rl.step) marks.points.emplace_back(static_cast<double>(s.step), s.hypotheses);
      }
    }
    count.add(marks);
  }

  auto errorFigure = [&](const std::string& title, const std::string& unit, auto value) {
    Figure f(size, title, "step", unit);
    PlotSeries points{"each hypothesis", kGrey, {}, PlotSeries::Style::kCircles, 1, 3};
    for (const auto& e : r.errors)
      points.points.emplace_back(static_cast<double>(e.step), value(e));
    PlotSeries mean_line{"mean", kRed, {}};
    std::map<int64_t, std::pair<double, int>> per_step;
    for (const auto& e : r.errors) {
      auto& acc = per_step[e.step];
      acc.first += value(e);
      ++acc.second;
    }
    for (const auto& [step, acc] : per_step) {
      mean_line.points.emplace_back(static_cast<double>(step), acc.first / acc.second);
    }
    f.add(points);
    f.add(mean_line);
    return f.render();
  };
  const std::vector<std::pair<fs::path, cv::Mat>> plots = {
      {dir / "hypotheses.png", count.render()},
      {dir / "error_x.png", errorFigure("Error in x of the hypotheses (Fig. 9)", "x error (m)",
                                        [](const AppearanceHypothesisError& e) { return e.ex; })},
      {dir / "error_y.png", errorFigure("Error in y of the hypotheses (Fig. 10)", "y error (m)",
                                        [](const AppearanceHypothesisError& e) { return e.ey; })},
      {dir / "error_heading.png",
       errorFigure("Heading error of the hypotheses (Fig. 11)", "heading error (deg)",
                   [](const AppearanceHypothesisError& e) { return radToDeg(e.eheading); })}};
  return writePlotImages(plots);
}

void addAppearanceEvalOptions(CLI::App& app, AppearanceEvalArgs& a) {
  AppearanceEvalOptions& o = a.options;
  app.add_option("log", a.log, "an LCM log");
  app.add_option("--hypotheses-channel", o.hypotheses_channel, "vslam.appearance_hypotheses_t")
      ->capture_default_str();
  app.add_option("--event-channel", o.event_channel, "vslam.appearance_event_t")
      ->capture_default_str();
  app.add_option("--map-channel", o.map_channel, "vslam.appearance_map_t")->capture_default_str();
  app.add_option("--ref-channel", o.ref_channel, "vslam.ground_truth_pose_t")
      ->capture_default_str();
  app.add_option("--action-length", o.action_length_m,
                 "a re-localization is correct within M metres")
      ->check(positiveNumber())
      ->capture_default_str();
  app.add_option("--revisit-radius", o.revisit_radius_m,
                 "the robot is at a mapped place within M metres of a\nstate made before")
      ->check(positiveNumber())
      ->capture_default_str();
  app.add_option("--plot-dir", a.plot_dir,
                 "write hypotheses.png, error_x.png, error_y.png,\nerror_heading.png");
  addSizeOption(app, "--plot-size", &a.plot_size, "plot size in pixels", Figure::minimumSize());
  app.add_option("--json", a.json, "write the summary as JSON");
}

int runAppearanceEval(const AppearanceEvalArgs& a, std::ostream& out) {
  if (!a.log) throw UsageError("--appearance needs a LOG");
  const AppearanceReport report = evaluateAppearanceLog(*a.log, a.options);
  printAppearanceReport(out, report);
  if (a.json) {
    writeAppearanceJson(*a.json, report);
    log::info("wrote ", a.json->string());
  }
  if (a.plot_dir) {
    for (const auto& p : writeAppearancePlots(*a.plot_dir, report, a.plot_size)) {
      log::info("wrote ", p.string());
    }
  }
  return kExitOk;
}

}  // namespace vslam::eval
