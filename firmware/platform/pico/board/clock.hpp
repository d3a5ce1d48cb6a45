// TIMER as the microsecond clock and the sample clock (RP2040 datasheet 4.6): the 64-bit counter
// ticks once per us (the watchdog tick, chip.cpp); NowUs is its low word, TIMERAWL (wraps at
// 2^32 us like app::Clock). ALARM0 (TIMER_IRQ_0) wakes the CPU at a deadline: the app's next
// loop, or a bus transfer's timeout.
#pragma once

#include <stdint.h>

#include "app/hal.hpp"
#include "platform/pico/board/rp2040.hpp"

namespace ja {
namespace pico {

namespace detail {
extern volatile bool g_reached;
}  // namespace detail

class TimerClock final : public app::Clock {
 public:
  /// ALARM0's interrupt on. Call once after InitChip, before interrupts are needed.
  void Init();
  uint32_t NowUs() override { return hw::Reg(hw::kTimerRawL); }
  /// Arms ALARM0 so that Reached() turns true at `deadline_us` (at once when it is less than
  /// kMarginUs away or past: the alarm only fires when the counter equals it).
  void WakeAt(uint32_t deadline_us);
  /// The armed deadline has passed (set by the alarm's interrupt).
  bool Reached() const { return detail::g_reached; }

  static constexpr uint32_t kMarginUs = 2;
};

TimerClock& SystemClock();

/// Sleeps (WFE: clocks and peripherals run, the core stops) until `done()` is true or the
/// deadline passes; true if `done()` came true. Race-free without masking interrupts: every
/// interrupt's return sets the core's event register (ARMv6-M), so an interrupt that changes
/// `done()` or Reached() between their test and the WFE makes the WFE return at once.
/// (WFI with PRIMASK set would also be race-free on the chip, but rp2040js 1.4.1 does not end a
/// WFI for an interrupt that was already pending when it executed.)
template <class Done>
bool SleepUntil(uint32_t deadline_us, Done done) {
  TimerClock& clock = SystemClock();
  clock.WakeAt(deadline_us);
  for (;;) {
    if (done()) return true;
    if (clock.Reached()) return false;
    hw::WaitForEvent();
  }
}

}  // namespace pico
}  // namespace ja
