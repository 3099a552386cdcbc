#include "bus/lockstep_replay.hpp"

#include <cstdio>
#include <cstring>
#include <deque>
#include <optional>
#include <set>
#include <stdexcept>

#include "util/log.hpp"

namespace vslam::bus {
namespace {

struct OwnedEvent {
  int64_t timestamp = 0;
  std::string channel;
  std::vector<uint8_t> data;
};

// Position of the next LCM event sync word (0xEDA1DA01, big-endian) at or
// after `from`, or -1.
long findNextSyncWord(FILE* file, long from) {
  if (from < 0 || std::fseek(file, from, SEEK_SET) != 0) return -1;
  const unsigned char sync[4] = {0xED, 0xA1, 0xDA, 0x01};
  unsigned char window[4] = {0, 0, 0, 0};
  long pos = from;
  int c;
  while ((c = std::fgetc(file)) != EOF) {
    window[0] = window[1];
    window[1] = window[2];
    window[2] = window[3];
    window[3] = static_cast<unsigned char>(c);
    ++pos;
    if (pos - from >= 4 && std::memcmp(window, sync, 4) == 0) return pos - 4;
  }
  return -1;
}

}  // namespace

LockstepReplay::LockstepReplay(ReplayOptions options) : options_(std::move(options)) {
  lcm_ = std::make_unique<lcm::LCM>("memq://");
  if (!lcm_->good()) throw std::runtime_error("cannot create the memq:// LCM provider");
  runner_ = std::make_unique<StageRunner>(
      *lcm_, clock_, ExecutionMode::kLockstep,
      RunnerOptions{"vslam-replay", options_.health_channel, options_.health_period_s});
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
  lcm::LogFile in(options_.input.string(), "r");
  if (!in.good()) throw std::runtime_error("cannot open input log " + options_.input.string());
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
  Utime first_ts = 0, last_ts = 0;
  bool started = false;
  FILE* file = in.getFilePtr();
  long end_of_last_event = std::ftell(file);
  int64_t last_eventnum = -1;
  auto is_input = [&](const std::string& channel) {
    return !stage_outputs.count(channel) && std::regex_match(channel, input_filter);
  };
  // The next event of the log, copied (LCM's reader reuses its buffer), or
  // nothing at the end. Skips damaged bytes to the next event.
  auto read_event = [&]() -> std::optional<OwnedEvent> {
    for (;;) {
      const lcm::LogEvent* ev = in.readNextEvent();
      if (!ev) {
        // LCM's reader stops at a damaged event header; skip to the next sync
        // word and go on, so one bad event does not lose the rest of the log.
        const long resume = findNextSyncWord(file, end_of_last_event + 1);
        if (resume < 0) return std::nullopt;
        log::warn("input log ", options_.input.string(), ": damaged data at bytes ",
                  end_of_last_event, "..", resume, "; skipped to the next event");
        stats_.bytes_skipped += resume - end_of_last_event;
        std::fseek(file, resume, SEEK_SET);
        end_of_last_event = resume;
        continue;
      }
      end_of_last_event = std::ftell(file);
      ++stats_.events_read;
      // lcm-logger numbers events consecutively: a gap is events lost to damage.
      if (stats_.events_read > 1 && ev->eventnum > last_eventnum + 1) {
        const int64_t gap = ev->eventnum - last_eventnum - 1;
        stats_.events_missing += gap;
        log::warn("input log ", options_.input.string(), ": ", gap,
                  " event(s) missing before event ", ev->eventnum, "; continuing");
      }
      last_eventnum = ev->eventnum;
      const auto* bytes = static_cast<const uint8_t*>(ev->data);
      return OwnedEvent{ev->timestamp, ev->channel,
                        std::vector<uint8_t>(bytes, bytes + ev->datalen)};
    }
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
  }
  // readNextEvent returns null at the end and on a damaged tail alike; bytes
  // after the last complete event tell them apart.
  std::fseek(file, 0, SEEK_END);
  const long end = std::ftell(file);
  const long pos = end_of_last_event;
  if (pos >= 0 && end > pos) {
    stats_.input_truncated = true;
    stats_.input_bytes_unread = end - pos;
    log::warn("input log ", options_.input.string(), " ends with ", end - pos,
              " bytes that are not a complete event (cut or corrupt); replayed the ",
              stats_.events_read, " complete events before them");
  }
  if (started) {
    runner_->stopAll();
    dispatchUntilQuiet();
  }
  out_.reset();  // closes and flushes the output log
  stats_.log_seconds = toSeconds(last_ts - first_ts);
  stats_.wall_seconds = toSeconds(monotonicUtime() - wall_start);
  return stats_;
}

}  // namespace vslam::bus
