#include "util/alternation.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace vslam {
namespace {

constexpr int kMaxSlots = 1000;
constexpr Utime kMaxPeriodUs = 1000000000000000;  // 1e9 s

void checkSlots(int slots) {
  if (slots < 1 || slots > kMaxSlots) {
    throw std::invalid_argument("slots must be in 1.." + std::to_string(kMaxSlots) + ", not " +
                                std::to_string(slots));
  }
}

}  // namespace

Utime alternationPeriodUs(double rate_hz, int slots) {
  if (!std::isfinite(rate_hz) || rate_hz <= 0) {
    throw std::invalid_argument("rate_hz must be a finite number > 0, not " +
                                std::to_string(rate_hz));
  }
  checkSlots(slots);
  const double period_us = std::round(static_cast<double>(slots) * 1e6 / rate_hz);
  if (period_us < slots) {
    throw std::invalid_argument("slots: " + std::to_string(slots) + " slots at " +
                                std::to_string(rate_hz) + " Hz are shorter than a microsecond");
  }
  if (period_us > static_cast<double>(kMaxPeriodUs)) {
    throw std::invalid_argument("rate_hz: " + std::to_string(rate_hz) + " Hz is too slow");
  }
  return static_cast<Utime>(period_us);
}

AlternationTurn alternationTurn(Utime t, Utime period_us, int slots) {
  checkSlots(slots);
  if (period_us < slots || period_us > kMaxPeriodUs) {
    throw std::invalid_argument("period " + std::to_string(period_us) + " us is shorter than " +
                                std::to_string(slots) + " slots of a microsecond, or too long");
  }
  AlternationTurn turn;
  turn.period = t / period_us;
  Utime phase = t % period_us;
  if (phase < 0) {  // floor, not truncation, before the epoch
    phase += period_us;
    --turn.period;
  }
  // phase < kMaxPeriodUs and slots <= kMaxSlots: the product fits in int64.
  turn.slot = static_cast<int>(phase * slots / period_us);
  return turn;
}

void checkAlternation(const Alternation& alternation, double rate_hz) {
  alternationPeriodUs(rate_hz, alternation.slots);
  if (alternation.slot < 0 || alternation.slot >= alternation.slots) {
    throw std::invalid_argument("slot must be in 0.." + std::to_string(alternation.slots - 1) +
                                " (slots: " + std::to_string(alternation.slots) + "), not " +
                                std::to_string(alternation.slot));
  }
}

AlternationGate::AlternationGate(Alternation alternation, double rate_hz)
    : alternation_(alternation), period_us_(alternationPeriodUs(rate_hz, alternation.slots)) {
  checkAlternation(alternation, rate_hz);
}

bool AlternationGate::take(Utime t) {
  const AlternationTurn turn = alternationTurn(t, period_us_, alternation_.slots);
  if (turn.slot != alternation_.slot) return false;
  if (taken_any_ && turn.period <= last_period_) return false;
  taken_any_ = true;
  last_period_ = turn.period;
  return true;
}

}  // namespace vslam
