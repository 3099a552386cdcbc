#include "bus/lockstep_replay.hpp"

#include <cstdio>
#include <deque>
#include <filesystem>
#include <optional>
#include <set>
#include <stdexcept>

#include "bus/log_reader.hpp"
#include "util/log.hpp"
#include "util/progress.hpp"

namespace vslam::bus {
namespace {

struct OwnedEvent {
  int64_t timestamp = 0;
  std::string channel;
  std::vector<uint8_t> data;
};

}  // namespace

LockstepReplay::LockstepReplay(ReplayOptions options) : options_(std::move(options)) {
  lcm_ = std::make_unique<lcm::LCM>("memq://");
  if (!lcm_->good()) throw std::runtime_error("cannot create the memq:// LCM provider");
  runner_ = std::make_unique<StageRunner>(
      *lcm_, clock_, ExecutionMode::kLockstep,
      RunnerOptions{"vslam-replay", options_.health_channel, options_.health_period_s});
  if (options_.loss.active()) {
    loss_ = std::make_shared<LossInjector>(options_.loss);
    runner_->setLossInjector(loss_);
  }
}

LockstepReplay::~LockstepReplay() = default;

void LockstepReplay::addStage(std::string instance, std::unique_ptr<Stage> stage) {
  runner_->add(std::move(instance), std::move(stage));
}

void LockstepReplay::onAnyMessage(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
  const bool is_input = next_is_input_;
  next_is_input_ = false;
  if (!is_input) ++stats_.messages_published;
  if (!out_) return;
  if (is_input && !options_.keep_inputs) return;
  if (!is_input && !options_.keep_health && channel == options_.health_channel) return;
  out_->write(clock_.now(), channel, rbuf->data, rbuf->data_size);
  ++stats_.events_written;
}

void LockstepReplay::dispatchUntilQuiet() {
  // A handler may publish; memq queues it and the loop dispatches it too.
  // Stages' background work is drained so nothing is left in flight.
  for (;;) {
    while (lcm_->handleTimeout(0) > 0) {
    }
    runner_->drainAll();
    if (lcm_->handleTimeout(0) <= 0) break;
  }
}

ReplayStats LockstepReplay::run() {
  // Stages are started and stopped once: a replay object runs one log.
  if (ran_) throw std::logic_error("LockstepReplay::run() called twice");
  ran_ = true;
  stats_ = ReplayStats{};
  std::unique_ptr<LogReader> in;
  try {
    in = std::make_unique<LogReader>(options_.input, LogDamage::kSkip);
  } catch (const LogError&) {
    throw std::runtime_error("cannot open input log " + options_.input.string());
  }
  if (!options_.output.empty()) {
    out_ = std::make_unique<LogWriter>(options_.output);
  }
  lcm_->subscribeFunction(
      ".*",
      +[](const lcm::ReceiveBuffer* rbuf, const std::string& channel, LockstepReplay* self) {
        self->onAnyMessage(rbuf, channel);
      },
      this);

  // Re-running a stage replaces its recorded output instead of mixing with it.
  const auto outputs = runner_->outputChannels();
  const std::set<std::string> stage_outputs(outputs.begin(), outputs.end());
  const std::regex input_filter(options_.input_channels);

  const Utime wall_start = monotonicUtime();
  std::error_code size_error;
  const auto input_bytes = std::filesystem::file_size(options_.input, size_error);
  ProgressMeter progress("replay", size_error ? 0.0 : static_cast<double>(input_bytes),
                         ProgressMeter::kBytes,
                         options_.show_progress && ProgressMeter::stderrIsTerminal());
  Utime first_ts = 0, last_ts = 0;
  bool started = false;
  auto is_input = [&](const std::string& channel) {
    return !stage_outputs.count(channel) && std::regex_match(channel, input_filter);
  };
  // The next event of the log, copied (LCM's reader reuses its buffer), or
  // nothing at the end. The reader skips damaged bytes to the next event.
  auto read_event = [&]() -> std::optional<OwnedEvent> {
    const lcm::LogEvent* ev = in->next();
    if (!ev) return std::nullopt;
    const auto* bytes = static_cast<const uint8_t*>(ev->data);
    return OwnedEvent{ev->timestamp, ev->channel, std::vector<uint8_t>(bytes, bytes + ev->datalen)};
  };
  // Events read but not yet delivered: each input among them has been offered
  // to the stages to prefetch (Stage::prefetch) once they were started.
  std::deque<OwnedEvent> ahead;
  bool at_end = false;
  auto fill_ahead = [&] {
    while (!at_end && ahead.size() < options_.prefetch_events + 1) {
      std::optional<OwnedEvent> ev = read_event();
      if (!ev) {
        at_end = true;
        break;
      }
      if (started && is_input(ev->channel)) {
        runner_->prefetch(ev->channel, ev->data.data(), ev->data.size());
      }
      ahead.push_back(std::move(*ev));
    }
  };
  for (;;) {
    if (ahead.empty()) {
      if (at_end) break;
      std::optional<OwnedEvent> first = read_event();
      if (!first) break;
      ahead.push_back(std::move(*first));
    }
    OwnedEvent ev = std::move(ahead.front());
    ahead.pop_front();
    if (!started) {
      first_ts = ev.timestamp;
      clock_.set(ev.timestamp);
      runner_->startAll();
      dispatchUntilQuiet();
      started = true;
    }
    fill_ahead();
    // Log time never runs backwards for the stages, even if the log's does.
    if (ev.timestamp > clock_.now()) clock_.set(ev.timestamp);
    last_ts = std::max(last_ts, ev.timestamp);
    runner_->tick(clock_.now());
    dispatchUntilQuiet();
    if (!is_input(ev.channel)) {
      ++stats_.events_dropped;
      continue;
    }
    next_is_input_ = true;
    lcm_->publish(ev.channel, ev.data.data(), static_cast<unsigned int>(ev.data.size()));
    ++stats_.events_fed;
    dispatchUntilQuiet();
    progress.update(static_cast<double>(in->eventOffset()), [&] {
      const double log_s = toSeconds(last_ts - first_ts);
      const double wall_s = toSeconds(monotonicUtime() - wall_start);
      char text[64];
      std::snprintf(text, sizeof(text), "%.0f s of log, %.1fx real time", log_s,
                    wall_s > 0 ? log_s / wall_s : 0.0);
      return std::string(text);
    });
  }
  progress.finish();
  const LogReadStats& read = in->stats();
  stats_.events_read = read.events_read;
  stats_.events_missing = read.events_missing;
  stats_.bytes_skipped = read.bytes_skipped;
  if (read.tail_bytes > 0) {
    stats_.input_truncated = true;
    stats_.input_bytes_unread = read.tail_bytes;
    log::warn("input log ", options_.input.string(), " ends with ", read.tail_bytes,
              " bytes that are not a complete event (cut or corrupt); replayed the ",
              stats_.events_read, " complete events before them");
  }
  if (started && loss_) {
    // Messages held back to be reordered: nothing comes after them now.
    runner_->releaseHeldMessages();
    dispatchUntilQuiet();
  }
  if (started) {
    runner_->stopAll();
    dispatchUntilQuiet();
  }
  if (loss_) {
    stats_.loss = loss_->total();
    stats_.loss_per_channel = loss_->perChannel();
  }
  out_.reset();  // closes and flushes the output log
  stats_.log_seconds = toSeconds(last_ts - first_ts);
  stats_.wall_seconds = toSeconds(monotonicUtime() - wall_start);
  return stats_;
}

}  // namespace vslam::bus
