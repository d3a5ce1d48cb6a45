// Timer1 as the microsecond clock and the sample clock (ATmega2560, 16 MHz): clk/8 = 2 MHz,
// 0.5 us per tick; the overflow interrupt (every 32.768 ms) extends TCNT1 to 32 bits of
// microseconds: now_us = overflows * 2^15 + TCNT1 / 2 (wraps at 2^32 us like app::Clock).
// Output compare A wakes the CPU at a deadline (the app's next loop or a bus timeout).
#pragma once

#include <avr/interrupt.h>
#include <avr/sleep.h>
#include <stdint.h>

#include "app/hal.hpp"

namespace ja {
namespace avr {

namespace detail {
extern volatile bool g_reached;
}  // namespace detail

class Timer1Clock final : public app::Clock {
 public:
  /// Normal mode, clk/8, overflow interrupt on. Call once with interrupts off.
  void Init();
  uint32_t NowUs() override;
  /// Arms the compare interrupt so that Reached() turns true at `deadline_us` (at once when
  /// it is less than kMarginUs away or past).
  void WakeAt(uint32_t deadline_us);
  /// The armed deadline has passed (set by the compare interrupt).
  bool Reached() const { return detail::g_reached; }  // inline: tested after every interrupt

  static constexpr uint32_t kMarginUs = 8;
};

Timer1Clock& SystemClock();

/// Sleeps (SLEEP_MODE_IDLE: timers, TWI and USART keep running) until `done()` is true or the
/// deadline passes; true if `done()` came true. Race-free: the condition is tested with
/// interrupts off and `sei` takes effect after the next instruction, so `sleep` cannot miss
/// the interrupt that would have changed it.
template <class Done>
bool SleepUntil(uint32_t deadline_us, Done done) {
  Timer1Clock& clock = SystemClock();
  clock.WakeAt(deadline_us);
  set_sleep_mode(SLEEP_MODE_IDLE);
  // Every interrupt while asleep (~140 a loop at 500 Hz: TWI steps, UART bytes) comes back here,
  // so the loop is kept short: SE stays set for the whole wait (cleared once at the end) instead
  // of being set and cleared around each `sleep` (2 x in/andi-or/out per wake-up).
  bool result;
  for (;;) {
    cli();
    // Set on every pass: the receive and compare interrupts clear SE (SleepUntilWoken).
    sleep_enable();
    if (done()) {
      result = true;
      break;
    }
    if (clock.Reached()) {
      result = false;
      break;
    }
    sei();
    // `sleep; nop`: simavr 1.6 does not sleep when an interrupt is pending and takes it only
    // after the instruction behind `sleep`, so a `cli` right there (where the compiler puts the
    // next pass's) would starve every interrupt; one asm statement, so nothing moves between.
    asm volatile("sleep\n\tnop" ::: "memory");
  }
  sleep_disable();
  sei();
  return result;
}

/// The main loop's wait (board.cpp): asleep until the deadline or until `done()` (a received
/// byte) turns true. The USART receive interrupt and the compare interrupt at the deadline clear
/// SE (SMCR), which is what ends the wait: every other interrupt (~130 a loop at 500 Hz: TWI
/// steps, UART bytes) comes back to an 8-cycle `cli; in; sbrs; sei; sleep; rjmp` instead of
/// SleepUntil's condition tests (~14 cycles). SE is tested with interrupts off and `sei` takes
/// effect after the `sleep` behind it, so an interrupt that clears SE either comes before the
/// test (the loop ends) or wakes the `sleep`. (Testing SE with interrupts on, then sleeping, was
/// 3 cycles a pass cheaper and right on silicon, where `sleep` with SE clear does nothing; but
/// simavr 1.6 sleeps whatever SE says, so a deadline interrupt between the test and the `sleep`
/// left the CPU asleep until the next interrupt — with the UART idle up to a Timer1 wrap, 32 ms:
/// at 500 Hz on the Mega, loops 4-17 periods apart.) simavr 1.6 takes a pending interrupt only
/// after the instruction behind `sleep`: that is the `rjmp`, never the `cli`.
template <class Done>
void SleepUntilWoken(uint32_t deadline_us, Done done) {
  Timer1Clock& clock = SystemClock();
  clock.WakeAt(deadline_us);
  set_sleep_mode(SLEEP_MODE_IDLE);
  cli();
  sleep_enable();
  if (done() || clock.Reached()) {
    sleep_disable();
    sei();
    return;
  }
  asm volatile(
      "1: cli\n\t"
      "in   __tmp_reg__, %[smcr]\n\t"
      "sbrs __tmp_reg__, %[se]\n\t"
      "rjmp 2f\n\t"
      "sei\n\t"
      "sleep\n\t"
      "rjmp 1b\n"
      "2: sei" ::[smcr] "I"(_SFR_IO_ADDR(SMCR)),
      [se] "I"(SE)
      : "memory");
}

/// Ends a SleepUntilWoken wait (interrupts only: SE cleared, the next `sleep` does nothing).
inline void WakeMainLoop() { SMCR = static_cast<uint8_t>(SMCR & ~_BV(SE)); }

}  // namespace avr
}  // namespace ja
