#include "bus/log_reader.hpp"

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <limits>
#include <sstream>

#include "util/log.hpp"

namespace vslam::bus {
namespace {

// Bytes of an event's framing: sync word, event number, timestamp, channel
// length, data length (lcm_eventlog format).
constexpr long kEventHeaderBytes = 4 + 8 + 8 + 4 + 4;

// Position of the next LCM event sync word (0xEDA1DA01, big-endian) at or
// after `from`, or -1.
constexpr unsigned char kSyncWord[4] = {0xED, 0xA1, 0xDA, 0x01};

long findNextSyncWord(FILE* file, long from) {
  if (from < 0 || std::fseek(file, from, SEEK_SET) != 0) return -1;
  unsigned char window[4] = {0, 0, 0, 0};
  long pos = from;
  int c;
  while ((c = std::fgetc(file)) != EOF) {
    window[0] = window[1];
    window[1] = window[2];
    window[2] = window[3];
    window[3] = static_cast<unsigned char>(c);
    ++pos;
    if (pos - from >= 4 && std::memcmp(window, kSyncWord, 4) == 0) return pos - 4;
  }
  return -1;
}

// Big-endian int32 (lcm_eventlog's byte order).
int32_t bigEndian32(const unsigned char* b) {
  return static_cast<int32_t>((uint32_t{b[0]} << 24) | (uint32_t{b[1]} << 16) |
                              (uint32_t{b[2]} << 8) | uint32_t{b[3]});
}

}  // namespace

LogReader::LogReader(const std::filesystem::path& log, LogDamage on_damage)
    : name_(log.string()), on_damage_(on_damage) {
  std::error_code ec;
  if (!std::filesystem::exists(log, ec)) throw LogError(name_ + ": no such file");
  if (std::filesystem::is_directory(log, ec)) throw LogError(name_ + ": is a directory, not a log");
  file_ = std::make_unique<lcm::LogFile>(name_, "r");
  if (!file_->good()) throw LogError(name_ + ": cannot open the log for reading");
  fp_ = file_->getFilePtr();
  end_of_last_event_ = std::ftell(fp_);
  std::fseek(fp_, 0, SEEK_END);
  file_size_ = std::ftell(fp_);
  std::fseek(fp_, end_of_last_event_, SEEK_SET);
}

// LCM 1.3.1's reader allocates an event's claimed data length + 1, computed
// in int, and reads into the allocation unchecked: a damaged header claiming
// 2^31 - 1 bytes makes it read into a failed allocation (a crash). So the
// header of the event it will read next (at the next sync word, as it
// searches) is checked against the file first. Returns that event's byte if
// it claims more than the file holds after it, else -1; the file position
// is left where it was.
long LogReader::nextOversizedEvent(int64_t* claimed) {
  const long pos = std::ftell(fp_);
  const long sync = findNextSyncWord(fp_, pos);
  long oversized = -1;
  unsigned char header[kEventHeaderBytes];
  if (sync >= 0 && std::fseek(fp_, sync, SEEK_SET) == 0 &&
      std::fread(header, 1, sizeof header, fp_) == sizeof header) {
    const int32_t channel_bytes = bigEndian32(header + 20);
    const int32_t data_bytes = bigEndian32(header + 24);
    // LCM itself refuses channel lengths outside 1..999 and negative data.
    if (channel_bytes > 0 && channel_bytes < 1000 && data_bytes >= 0 &&
        data_bytes > file_size_ - (sync + kEventHeaderBytes + channel_bytes)) {
      oversized = sync;
      *claimed = data_bytes;
    }
  }
  std::fseek(fp_, pos, SEEK_SET);
  return oversized;
}

LogReader::~LogReader() = default;

const lcm::LogEvent* LogReader::next() {
  while (!at_end_) {
    int64_t claimed = 0;
    const long oversized = nextOversizedEvent(&claimed);
    if (oversized >= 0) {
      // The last event, cut short: a damaged tail (finish says so).
      const bool last = findNextSyncWord(fp_, oversized + 1) < 0;
      std::fseek(fp_, end_of_last_event_, SEEK_SET);  // (the search moved it)
      if (on_damage_ != LogDamage::kSkip && !last) {
        std::ostringstream os;
        os << name_ << " is damaged: the event at byte " << oversized << " claims " << claimed
           << " data bytes, more than the " << file_size_ << "-byte file holds";
        throw LogError(os.str());
      }
      if (!last && skipToNextEvent(oversized + 1)) continue;
      finish();
      return nullptr;
    }
    const lcm::LogEvent* ev = file_->readNextEvent();
    if (!ev) {
      // LCM's reader stops at a damaged event header.
      if (on_damage_ == LogDamage::kSkip && skipToNextEvent(end_of_last_event_ + 1)) continue;
      finish();
      return nullptr;
    }
    const long end = std::ftell(fp_);
    const long size = kEventHeaderBytes + static_cast<long>(ev->channel.size()) + ev->datalen;
    if (on_damage_ != LogDamage::kSkip && end - end_of_last_event_ != size) {
      std::ostringstream os;
      os << name_ << " is damaged: " << (end - end_of_last_event_ - size) << " bytes at byte "
         << end_of_last_event_ << " are not an LCM event (before event " << ev->eventnum << " on "
         << ev->channel << ")";
      throw LogError(os.str());
    }
    event_offset_ = end - size;
    end_of_last_event_ = end;
    ++stats_.events_read;
    // lcm-logger numbers events consecutively: a gap is events lost to damage.
    // The numbers are the file's word, anything in 64 bits: no overflow.
    if (on_damage_ == LogDamage::kSkip && stats_.events_read > 1 && ev->eventnum > last_eventnum_ &&
        static_cast<uint64_t>(ev->eventnum) - static_cast<uint64_t>(last_eventnum_) > 1) {
      const auto gap = static_cast<int64_t>(std::min<uint64_t>(
          static_cast<uint64_t>(ev->eventnum) - static_cast<uint64_t>(last_eventnum_) - 1,
          static_cast<uint64_t>(std::numeric_limits<int64_t>::max() - stats_.events_missing)));
      stats_.events_missing += gap;
      log::warn("input log ", name_, ": ", gap, " event(s) missing before event ", ev->eventnum,
                "; continuing");
    }
    last_eventnum_ = ev->eventnum;
    return ev;
  }
  return nullptr;
}

// Skips damaged bytes to the next sync word at or after `from`, so one bad
// event does not lose the rest of the log; false if there is none.
bool LogReader::skipToNextEvent(long from) {
  const long resume = findNextSyncWord(fp_, from);
  if (resume < 0) return false;
  log::warn("input log ", name_, ": damaged data at bytes ", end_of_last_event_, "..", resume,
            "; skipped to the next event");
  stats_.bytes_skipped += resume - end_of_last_event_;
  std::fseek(fp_, resume, SEEK_SET);
  end_of_last_event_ = resume;
  return true;
}

// The bytes after the last complete event are the start of one event that
// claims more than is left (a recording cut short), not anything else. (LCM
// refuses an intact event followed by garbage, so that event is in the tail
// too: it starts with a sync word but is complete.)
bool LogReader::tailIsOneCutEvent() {
  const long tail = file_size_ - end_of_last_event_;
  unsigned char header[kEventHeaderBytes];
  if (std::fseek(fp_, end_of_last_event_, SEEK_SET) != 0) return false;
  const size_t got = std::fread(header, 1, std::min(sizeof header, static_cast<size_t>(tail)), fp_);
  if (got < 4 || std::memcmp(header, kSyncWord, 4) != 0) return false;
  if (got < sizeof header) return true;  // cut inside the header
  const int64_t channel_bytes = bigEndian32(header + 20);
  const int64_t data_bytes = bigEndian32(header + 24);
  return channel_bytes > 0 && channel_bytes < 1000 && data_bytes >= 0 &&
         kEventHeaderBytes + channel_bytes + data_bytes > tail;
}

// readNextEvent returns null at the end and on a damaged tail alike; bytes
// after the last complete event tell them apart.
void LogReader::finish() {
  at_end_ = true;
  const long file_size = file_size_;
  if (end_of_last_event_ < 0 || file_size <= end_of_last_event_) return;
  stats_.tail_bytes = file_size - end_of_last_event_;
  if (on_damage_ == LogDamage::kSkip) return;
  if (on_damage_ == LogDamage::kCutTail && stats_.events_read > 0 && tailIsOneCutEvent()) return;
  std::ostringstream os;
  if (stats_.events_read == 0) {
    os << name_ << ": not an LCM log (no complete event in its " << file_size << " bytes)";
  } else {
    os << name_ << " is damaged: the last " << stats_.tail_bytes << " bytes (from byte "
       << end_of_last_event_ << ", after " << stats_.events_read
       << " events) are not a complete LCM event (cut or corrupt)";
  }
  throw LogError(os.str());
}

}  // namespace vslam::bus
