// Shared pieces of the accelerometer models: the conversion clock and physical -> counts.
#pragma once

#include <stdint.h>

#include <cmath>

namespace ja {
namespace sim {

constexpr double kStandardGravity = 9.80665;  // m/s^2 per g

/// A part's own oscillator: its frequency error (ppm, + = fast; |ppm| < 100000) and the phase of
/// its conversion grid (a fraction of one period, [0, 1)). Real parts convert on free-running
/// on-chip oscillators, so each has its own phase and rate: their grids drift against each other
/// and against the board's loop. ppm = phase = 0 is the ideal part (the grid t = j * P_nom).
struct Oscillator {
  double ppm = 0.0;
  double phase = 0.0;
};

/// The oscillators a part may have (ja_sim_set_clock, the rig spec's clock=, rig TOML's
/// sim_clock_*): a frequency error below 10 %, a phase within one period.
constexpr double kMaxClockPpm = 100000.0;  // |ppm| below this
inline bool ValidClockPpm(double ppm) {
  return std::isfinite(ppm) && std::fabs(ppm) < kMaxClockPpm;
}
inline bool ValidClockPhase(double phase) {
  return std::isfinite(phase) && phase >= 0.0 && phase < 1.0;
}

/// The period (ns) a part runs for a nominal period: P = floor(P_nom / (1 + ppm * 1e-6) + 0.5)
/// in double (the host's sim/sensor_timing.py `part_clock` computes the same, bit for bit).
inline uint64_t EffectivePeriodNs(uint64_t nominal_ns, double ppm) {
  const double p = std::floor(static_cast<double>(nominal_ns) / (1.0 + ppm * 1e-6) + 0.5);
  return p >= 1.0 ? static_cast<uint64_t>(p) : 1u;
}

/// The grid's offset (ns) for a period: O = floor(phase * P + 0.5).
inline uint64_t GridOffsetNs(uint64_t period_ns, double phase) {
  return static_cast<uint64_t>(std::floor(phase * static_cast<double>(period_ns) + 0.5));
}

/// Conversions at t_j = O + j * P (j = 0, 1, ...) in device time, counted from device time 0
/// (none before O): the part's oscillator runs free, a sample is made at every grid instant
/// while measuring. P and O come from the nominal period the registers select and the part's
/// Oscillator (EffectivePeriodNs, GridOffsetNs); the ideal part has O = 0, P = P_nom.
class SampleClock {
 public:
  /// The part's oscillator; used from the next Start (Restart applies it to a running clock).
  void set_oscillator(const Oscillator& o) { osc_ = o; }
  const Oscillator& oscillator() const { return osc_; }
  /// (Re)starts at now: the first conversion is the next grid instant after now.
  void Start(uint64_t now_ns, uint64_t nominal_period_ns) {
    nominal_ns_ = nominal_period_ns ? nominal_period_ns : 1;
    period_ns_ = EffectivePeriodNs(nominal_ns_, osc_.ppm);
    offset_ns_ = GridOffsetNs(period_ns_, osc_.phase);
    passed_ = Passed(now_ns);
    running_ = true;
  }
  /// A running clock starts again at now on the grid of its oscillator (same nominal period).
  void Restart(uint64_t now_ns) {
    if (running_) Start(now_ns, nominal_ns_);
  }
  void Stop() { running_ = false; }
  bool running() const { return running_; }
  /// The nominal period (what the registers select) and the one the part runs.
  uint64_t nominal_period_ns() const { return nominal_ns_; }
  uint64_t period_ns() const { return period_ns_; }
  uint64_t offset_ns() const { return offset_ns_; }
  /// Number of conversions due since the last call; *t_ns = the newest one's instant.
  uint64_t Advance(uint64_t now_ns, uint64_t* t_ns) {
    if (!running_) return 0;
    const uint64_t passed = Passed(now_ns);
    if (passed <= passed_) return 0;
    const uint64_t n = passed - passed_;
    passed_ = passed;
    *t_ns = offset_ns_ + (passed - 1) * period_ns_;
    return n;
  }

 private:
  /// Grid instants at or before now.
  uint64_t Passed(uint64_t now_ns) const {
    return now_ns < offset_ns_ ? 0 : (now_ns - offset_ns_) / period_ns_ + 1;
  }

  Oscillator osc_;
  uint64_t nominal_ns_ = 1;
  uint64_t period_ns_ = 1;
  uint64_t offset_ns_ = 0;
  uint64_t passed_ = 0;
  bool running_ = false;
};

/// value / per_count rounded to nearest (halves away from zero), clamped to [lo, hi]; NaN -> 0.
inline int32_t ToCounts(double value, double per_count, int32_t lo, int32_t hi) {
  if (!(value == value)) return 0;
  const double c = std::round(value / per_count);
  if (c <= static_cast<double>(lo)) return lo;
  if (c >= static_cast<double>(hi)) return hi;
  return static_cast<int32_t>(c);
}

/// The rail a saturated axis sticks to: hi for non-negative input, lo otherwise.
inline int32_t Rail(double value, int32_t lo, int32_t hi) { return value < 0.0 ? lo : hi; }

}  // namespace sim
}  // namespace ja
