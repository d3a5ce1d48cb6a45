#include "platform/pico/board/clock.hpp"

namespace ja {
namespace pico {

namespace {

using namespace hw;

TimerClock g_clock;

}  // namespace

namespace detail {
volatile bool g_reached = true;
}  // namespace detail

TimerClock& SystemClock() { return g_clock; }

void TimerClock::Init() {
  Reg(kTimerArmed) = kTimerAlarm0Bit;  // disarm (write 1)
  Reg(kTimerIntr) = kTimerAlarm0Bit;   // clear (write 1)
  Reg(kTimerInte) = kTimerAlarm0Bit;
  EnableIrq(kIrqTimer0);
}

void TimerClock::WakeAt(uint32_t deadline_us) {
  const uint32_t primask = SaveAndDisableInterrupts();
  detail::g_reached = false;
  // A fire of the previous deadline still pending would end this wait early: cleared.
  Reg(kTimerIntr) = kTimerAlarm0Bit;
  Reg(kNvicIcpr) = 1u << kIrqTimer0;
  Reg(kTimerAlarm0) = deadline_us;  // arms it, replacing any earlier deadline
  if (static_cast<int32_t>(deadline_us - NowUs()) < static_cast<int32_t>(kMarginUs)) {
    Reg(kTimerArmed) = kTimerAlarm0Bit;  // would fire only after the counter wraps
    detail::g_reached = true;
  }
  RestoreInterrupts(primask);
}

}  // namespace pico
}  // namespace ja

// ALARM0 fires only when the counter reaches the deadline WakeAt armed (WakeAt cleared any
// earlier fire with interrupts off), so this is the deadline, without reading the counter:
// rp2040js 1.4.1 schedules an alarm from the fractional microsecond and fires it up to 1 us
// early, where TIMERAWL still reads deadline - 1.
extern "C" void isr_timer_0() {
  ja::pico::hw::Reg(ja::pico::hw::kTimerIntr) = ja::pico::hw::kTimerAlarm0Bit;
  ja::pico::detail::g_reached = true;
}
