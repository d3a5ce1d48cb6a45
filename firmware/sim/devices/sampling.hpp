// Shared pieces of the accelerometer models: the conversion clock and physical -> counts.
#pragma once

#include <stdint.h>

#include <cmath>

namespace ja {
namespace sim {

constexpr double kStandardGravity = 9.80665;  // m/s^2 per g

/// Conversions at t = k * period (k integer) in device time, counted from device time 0: the
/// part's oscillator runs free, a sample is made at every grid instant while measuring.
class SampleClock {
 public:
  /// (Re)starts at now: the first conversion is the next grid instant after now.
  void Start(uint64_t now_ns, uint64_t period_ns) {
    period_ns_ = period_ns ? period_ns : 1;
    k_ = now_ns / period_ns_;
    running_ = true;
  }
  void Stop() { running_ = false; }
  bool running() const { return running_; }
  uint64_t period_ns() const { return period_ns_; }
  /// Number of conversions due since the last call; *t_ns = the newest one's instant.
  uint64_t Advance(uint64_t now_ns, uint64_t* t_ns) {
    if (!running_) return 0;
    const uint64_t k = now_ns / period_ns_;
    if (k <= k_) return 0;
    const uint64_t n = k - k_;
    k_ = k;
    *t_ns = k * period_ns_;
    return n;
  }

 private:
  uint64_t period_ns_ = 1;
  uint64_t k_ = 0;
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
