#include "eval/appearance_eval.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <optional>
#include <ostream>
#include <sstream>
#include <vslam/appearance_event_t.hpp>
#include <vslam/appearance_hypotheses_t.hpp>
#include <vslam/appearance_map_t.hpp>
#include <vslam/ground_truth_pose_t.hpp>

#include "eval/cli_args.hpp"
#include "eval/errors.hpp"
#include "eval/log_reader.hpp"
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

std::string jsonNumber(double v) {
  if (!std::isfinite(v)) return "null";
  std::ostringstream os;
  os << std::setprecision(9) << v;
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

std::string jsonStep(int64_t step) { return step < 0 ? "null" : std::to_string(step); }

}  // namespace

double AppearanceHypothesisError::position() const { return std::hypot(ex, ey); }

AppearanceReport evaluateAppearanceLog(const fs::path& log, const AppearanceEvalOptions& options) {
  AppearanceReport r;
  r.input = log.string();
  r.options = options;
  std::vector<TruePose> truth;
  std::vector<vslam::appearance_hypotheses_t> steps;
  std::vector<vslam::appearance_event_t> events;
  std::map<int64_t, int64_t> state_utime;
  const auto counts = forEachLogEvent(log, [&](const LogEventRef& e) {
    const std::string& ch = e.event.channel;
    if (ch == options.ref_channel) {
      const auto m = decodeEvent<vslam::ground_truth_pose_t>(e, "vslam.ground_truth_pose_t");
      truth.push_back({m.utime, m.x, m.y, m.theta});
    } else if (ch == options.hypotheses_channel) {
      steps.push_back(
          decodeEvent<vslam::appearance_hypotheses_t>(e, "vslam.appearance_hypotheses_t"));
    } else if (ch == options.event_channel) {
      events.push_back(decodeEvent<vslam::appearance_event_t>(e, "vslam.appearance_event_t"));
    } else if (ch == options.map_channel) {
      const auto m = decodeEvent<vslam::appearance_map_t>(e, "vslam.appearance_map_t");
      for (const auto& s : m.states) state_utime.emplace(s.state_id, s.utime);
      r.map_states = m.num_states;
      r.map_links = m.num_links;
    }
  });
  if (steps.empty()) {
    throw DataError(log.string() + ": no " + options.hypotheses_channel +
                    " messages (channels: " + channelList(counts) + ")");
  }
  if (truth.empty()) {
    throw DataError(log.string() + ": no ground truth on " + options.ref_channel +
                    " (channels: " + channelList(counts) + ")");
  }
  std::sort(truth.begin(), truth.end(),
            [](const TruePose& a, const TruePose& b) { return a.utime < b.utime; });
  // The new-state hypothesis of each step names the state its snapshot made.
  for (const auto& s : steps) {
    for (const auto& h : s.hypotheses) {
      if (h.is_new_state) state_utime[h.state_id] = s.utime;
    }
  }
  std::map<int64_t, bool> created;
  for (const auto& s : steps) {
    for (const auto& h : s.hypotheses) {
      if (h.is_new_state) created[h.state_id] = true;
    }
  }
  r.states_created = static_cast<int64_t>(created.size());

  const int64_t t0 = steps.front().utime;
  // Error of "the robot is in state k" at time t: state's true pose minus the robot's.
  auto errorOf = [&](int64_t state_id, int64_t utime, AppearanceHypothesisError* e) {
    const auto it = state_utime.find(state_id);
    TruePose now, then;
    if (it == state_utime.end() || !truthAt(truth, utime, &now) ||
        !truthAt(truth, it->second, &then)) {
      return false;
    }
    e->ex = then.x - now.x;
    e->ey = then.y - now.y;
    e->eheading = wrapAngle(then.theta - now.theta);
    return true;
  };

  // True poses of the states, for the nearest-state floor.
  std::vector<std::pair<int64_t, TruePose>> state_truth;
  for (const auto& [id, utime] : state_utime) {
    TruePose p;
    if (truthAt(truth, utime, &p)) state_truth.emplace_back(utime, p);
  }
  // The robot's true distance at `utime` to the nearest state made before
  // `made_before` and facing within 45 degrees of it; NaN if none.
  auto nearestState = [&](int64_t utime, int64_t made_before) {
    TruePose now;
    if (!truthAt(truth, utime, &now)) return kNaN;
    double best = kNaN;
    for (const auto& [t, p] : state_truth) {
      if (t >= made_before || std::abs(wrapAngle(p.theta - now.theta)) > M_PI / 4) continue;
      const double d = std::hypot(p.x - now.x, p.y - now.y);
      if (!(d >= best)) best = d;
    }
    return best;
  };

  std::vector<double> pos, heading, best_pos, step_seconds, nearest;
  double weight_sum = 0, weighted_pos_sum = 0, weighted_nearest_sum = 0;
  int64_t within = 0;
  double hyp_sum = 0;
  int64_t previous_utime = std::numeric_limits<int64_t>::min();
  for (const auto& s : steps) {
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
      if (!errorOf(h.state_id, s.utime, &e)) {
        ++r.unknown_states;
        continue;
      }
      r.errors.push_back(e);
      step_pos.push_back(e.position());
      step_weight += h.belief;
      step_weighted_pos += h.belief * e.position();
      pos.push_back(e.position());
      heading.push_back(std::abs(e.eheading));
      within += e.position() < options.action_length_m;
      if (h.state_id == s.best_state_id && i == 0) row.best_position_error = e.position();
    }
    row.best_is_revisit = !s.hypotheses.empty() && !s.hypotheses.front().is_new_state;
    row.nearest_state_distance = nearestState(s.utime, s.utime);
    // The state of the step before is where the robot just came from, not a
    // place it came back to.
    row.at_mapped_place = nearestState(s.utime, previous_utime) < options.revisit_radius_m;
    previous_utime = s.utime;
    if (row.best_is_revisit && std::isfinite(row.best_position_error)) {
      row.best_correct = row.best_position_error < options.action_length_m;
      row.best_wrong = !row.best_correct;
    }
    r.revisit_steps += row.at_mapped_place;
    r.revisit_steps_recognized += row.at_mapped_place && row.best_correct;
    r.wrong_revisit_steps += row.best_wrong;
    if (!step_pos.empty() && std::isfinite(row.nearest_state_distance)) {
      for (size_t k = 0; k < step_pos.size(); ++k) nearest.push_back(row.nearest_state_distance);
      weight_sum += step_weight;
      weighted_pos_sum += step_weighted_pos;
      weighted_nearest_sum += step_weight * row.nearest_state_distance;
    }
    row.mean_position_error = mean(step_pos);
    if (row.best_is_revisit && std::isfinite(row.best_position_error)) {
      ++r.steps_best_revisit;
      best_pos.push_back(row.best_position_error);
    }
    r.max_hypotheses = std::max(r.max_hypotheses, row.hypotheses);
    hyp_sum += row.hypotheses;
    step_seconds.push_back(s.step_seconds);
    r.steps.push_back(row);
  }
  r.mean_hypotheses = hyp_sum / static_cast<double>(steps.size());
  r.mean_position_error = mean(pos);
  r.weighted_position_error = weight_sum > 0 ? weighted_pos_sum / weight_sum : kNaN;
  r.weighted_nearest_state_distance = weight_sum > 0 ? weighted_nearest_sum / weight_sum : kNaN;
  r.median_position_error = median(pos);
  r.max_position_error = pos.empty() ? kNaN : *std::max_element(pos.begin(), pos.end());
  r.mean_abs_heading_error = mean(heading);
  r.fraction_within_action =
      pos.empty() ? kNaN : static_cast<double>(within) / static_cast<double>(pos.size());
  r.mean_best_position_error = mean(best_pos);
  r.mean_nearest_state_distance = mean(nearest);
  r.mean_step_seconds = mean(step_seconds);
  r.max_step_seconds = *std::max_element(step_seconds.begin(), step_seconds.end());

  for (const auto& ev : events) {
    if (ev.event != vslam::appearance_event_t::EVENT_RELOCALIZED) continue;
    AppearanceRelocalization rl;
    rl.step = ev.step;
    rl.t = 1e-6 * static_cast<double>(ev.utime - t0);
    rl.state_id = ev.state_id;
    rl.previous_state_id = ev.previous_state_id;
    rl.belief = ev.belief;
    AppearanceHypothesisError e;
    if (errorOf(ev.state_id, ev.utime, &e)) {
      rl.position_error = e.position();
      rl.heading_error = e.eheading;
      rl.correct = rl.position_error < options.action_length_m;
    } else {
      rl.position_error = rl.heading_error = kNaN;
    }
    r.relocalizations.push_back(rl);
    r.relocalizations_correct += rl.correct;
    r.relocalizations_wrong += std::isfinite(rl.position_error) && !rl.correct;
  }
  r.kidnaps = findKidnaps(steps, truth, state_utime, r.steps, options, nearestState);
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
  std::ofstream os(file);
  if (!os) throw DataError(file.string() + ": cannot write");
  os << "{\n  \"input\": \"" << r.input << "\",\n"
     << "  \"steps\": " << r.steps.size() << ",\n"
     << "  \"states_created\": " << r.states_created << ",\n"
     << "  \"map_states\": " << r.map_states << ",\n"
     << "  \"map_links\": " << r.map_links << ",\n"
     << "  \"mean_hypotheses\": " << jsonNumber(r.mean_hypotheses) << ",\n"
     << "  \"max_hypotheses\": " << r.max_hypotheses << ",\n"
     << "  \"revisit_hypotheses\": " << r.errors.size() << ",\n"
     << "  \"mean_position_error_m\": " << jsonNumber(r.mean_position_error) << ",\n"
     << "  \"weighted_position_error_m\": " << jsonNumber(r.weighted_position_error) << ",\n"
     << "  \"weighted_nearest_state_distance_m\": " << jsonNumber(r.weighted_nearest_state_distance)
     << ",\n"
     << "  \"median_position_error_m\": " << jsonNumber(r.median_position_error) << ",\n"
     << "  \"max_position_error_m\": " << jsonNumber(r.max_position_error) << ",\n"
     << "  \"mean_abs_heading_error_rad\": " << jsonNumber(r.mean_abs_heading_error) << ",\n"
     << "  \"fraction_within_action\": " << jsonNumber(r.fraction_within_action) << ",\n"
     << "  \"steps_best_revisit\": " << r.steps_best_revisit << ",\n"
     << "  \"mean_best_position_error_m\": " << jsonNumber(r.mean_best_position_error) << ",\n"
     << "  \"mean_nearest_state_distance_m\": " << jsonNumber(r.mean_nearest_state_distance)
     << ",\n"
     << "  \"mean_step_seconds\": " << jsonNumber(r.mean_step_seconds) << ",\n"
     << "  \"revisit_steps\": " << r.revisit_steps << ",\n"
     << "  \"revisit_steps_recognized\": " << r.revisit_steps_recognized << ",\n"
     << "  \"wrong_revisit_steps\": " << r.wrong_revisit_steps << ",\n"
     << "  \"relocalizations_correct\": " << r.relocalizations_correct << ",\n"
     << "  \"relocalizations_wrong\": " << r.relocalizations_wrong << ",\n"
     << "  \"kidnaps\": [";
  for (size_t i = 0; i < r.kidnaps.size(); ++i) {
    const auto& k = r.kidnaps[i];
    os << (i ? "," : "") << "\n    {\"kind\": \"" << kindName(k.kind) << "\", \"step\": " << k.step
       << ", \"t\": " << jsonNumber(k.t) << ", \"status\": \"" << statusName(k.status)
       << "\", \"first_mapped_step\": " << jsonStep(k.first_mapped_step)
       << ", \"first_correct_step\": " << jsonStep(k.first_correct_step)
       << ", \"steps_to_relocalize\": " << jsonStep(k.steps_to_relocalize) << "}";
  }
  os << (r.kidnaps.empty() ? "" : "\n  ") << "],\n"
     << "  \"relocalizations\": [";
  for (size_t i = 0; i < r.relocalizations.size(); ++i) {
    const auto& rl = r.relocalizations[i];
    os << (i ? "," : "") << "\n    {\"step\": " << rl.step << ", \"t\": " << jsonNumber(rl.t)
       << ", \"state_id\": " << rl.state_id << ", \"previous_state_id\": " << rl.previous_state_id
       << ", \"belief\": " << jsonNumber(rl.belief)
       << ", \"position_error_m\": " << jsonNumber(rl.position_error)
       << ", \"heading_error_rad\": " << jsonNumber(rl.heading_error)
       << ", \"correct\": " << (rl.correct ? "true" : "false") << "}";
  }
  os << "\n  ]\n}\n";
  if (!os) throw DataError(file.string() + ": cannot write");
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

void printAppearanceUsage(std::ostream& os) {
  os << "--appearance LOG: appearance SLAM against ground truth (Lee & Sowmya Figs. 8-11)\n"
        "  --hypotheses-channel CH  vslam.appearance_hypotheses_t (default APPEARANCE_HYPOTHESES)\n"
        "  --event-channel CH       vslam.appearance_event_t (default APPEARANCE_EVENT)\n"
        "  --map-channel CH         vslam.appearance_map_t (default APPEARANCE_MAP)\n"
        "  --ref-channel CH         vslam.ground_truth_pose_t (default GROUND_TRUTH)\n"
        "  --action-length M        a re-localization is correct within M metres (default 1)\n"
        "  --revisit-radius M       the robot is at a mapped place within M metres of a\n"
        "                           state made before (default 0.5)\n"
        "  --plot-dir DIR           write hypotheses.png, error_x.png, error_y.png,\n"
        "                           error_heading.png\n"
        "  --plot-size WxH          plot size in pixels (default 1000x800)\n"
        "  --json FILE              write the summary as JSON\n";
}

int runAppearanceEval(const std::vector<std::string>& args, std::ostream& out) {
  AppearanceEvalOptions options;
  std::optional<fs::path> log, plot_dir, json;
  cv::Size plot_size{1000, 800};
  cli::ArgCursor cur(args);
  while (!cur.done()) {
    const std::string opt = cur.next();
    if (opt == "--hypotheses-channel") {
      options.hypotheses_channel = cur.value(opt);
    } else if (opt == "--event-channel") {
      options.event_channel = cur.value(opt);
    } else if (opt == "--map-channel") {
      options.map_channel = cur.value(opt);
    } else if (opt == "--ref-channel") {
      options.ref_channel = cur.value(opt);
    } else if (opt == "--action-length") {
      options.action_length_m = cli::parsePositive(opt, cur.value(opt));
    } else if (opt == "--revisit-radius") {
      options.revisit_radius_m = cli::parsePositive(opt, cur.value(opt));
    } else if (opt == "--plot-dir") {
      plot_dir = cur.value(opt);
    } else if (opt == "--plot-size") {
      plot_size = cli::parseSize(opt, cur.value(opt));
      const cv::Size min = Figure::minimumSize();
      if (plot_size.width < min.width || plot_size.height < min.height) {
        throw UsageError("--plot-size must be at least " + std::to_string(min.width) + "x" +
                         std::to_string(min.height));
      }
    } else if (opt == "--json") {
      json = cur.value(opt);
    } else if (!opt.empty() && opt[0] == '-') {
      throw UsageError("unknown option '" + opt + "' for --appearance");
    } else if (log) {
      throw UsageError("more than one log given ('" + log->string() + "' and '" + opt + "')");
    } else {
      log = opt;
    }
  }
  if (!log) throw UsageError("--appearance needs a LOG");
  const AppearanceReport report = evaluateAppearanceLog(*log, options);
  printAppearanceReport(out, report);
  if (json) {
    writeAppearanceJson(*json, report);
    log::info("wrote ", json->string());
  }
  if (plot_dir) {
    for (const auto& p : writeAppearancePlots(*plot_dir, report, plot_size)) {
      log::info("wrote ", p.string());
    }
  }
  return kExitOk;
}

}  // namespace vslam::eval
