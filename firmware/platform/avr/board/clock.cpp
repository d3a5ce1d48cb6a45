#include "platform/avr/board/clock.hpp"

#include <avr/io.h>
#include <util/atomic.h>

#include "platform/avr/board/activity.hpp"

namespace ja {
namespace avr {

namespace {

volatile uint32_t g_overflows = 0;
volatile uint32_t g_deadline_us = 0;
Timer1Clock g_clock;

/// Interrupts must be off.
inline uint32_t NowUsLocked() {
  const uint16_t t = TCNT1;
  uint32_t ov = g_overflows;
  // An overflow that happened after interrupts went off is pending, not counted yet: TCNT1 has
  // wrapped to a small value then.
  if ((TIFR1 & _BV(TOV1)) && t < 0x8000u) ++ov;
  // (ov << 15) | (t >> 1) from 16-bit halves: high = ov bits 1..16, low = ov bit 0 above
  // t / 2. avr-gcc 5.4 turns the 32-bit shift by 15 into a 15-pass loop (~105 cycles a call).
  const uint16_t low = static_cast<uint16_t>((static_cast<uint16_t>(ov) << 15) | (t >> 1));
  const uint16_t high = static_cast<uint16_t>(ov >> 1);
  return (static_cast<uint32_t>(high) << 16) | low;
}

}  // namespace

namespace detail {
volatile bool g_reached = true;
}  // namespace detail

Timer1Clock& SystemClock() { return g_clock; }

void Timer1Clock::Init() {
  // TCNT1 keeps counting from reset (ja_start_timer1_at_reset).
  TCCR1A = 0;  // normal mode (the Arduino core's init() sets PWM mode: undone here)
  TCCR1C = 0;
  TIMSK1 = _BV(TOIE1);
  TIFR1 = _BV(TOV1) | _BV(OCF1A) | _BV(OCF1B) | _BV(OCF1C) | _BV(ICF1);
  TCCR1B = _BV(CS11);  // clk/8
}

// Timer1 counts from the first instructions after reset (.init3 runs before avr-libc clears
// .bss and copies .data: ~1.6 ms with this image, estimated from its 4.9 KB; the Mega's HIL
// read-timing fit moved by 0.5 of a 4 ms period with it), not from BoardMain: t_us is then
// the time since reset, the same clock as the virtual board's sensors and motion (simavr's
// device time), so a frame's samples can be placed against the simulation's truth. Init keeps
// the count. (Naked and in .init3: no prologue, no stack or .bss used yet.)
extern "C" void ja_start_timer1_at_reset() __attribute__((naked, used, section(".init3")));
extern "C" void ja_start_timer1_at_reset() {
  TCCR1A = 0;
  TCNT1 = 0;
  TCCR1B = _BV(CS11);  // clk/8
}

uint32_t Timer1Clock::NowUs() {
  uint32_t now;
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) { now = NowUsLocked(); }
  return now;
}

void Timer1Clock::WakeAt(uint32_t deadline_us) {
  ATOMIC_BLOCK(ATOMIC_RESTORESTATE) {
    g_deadline_us = deadline_us;
    detail::g_reached = false;
    OCR1A = static_cast<uint16_t>(static_cast<uint16_t>(deadline_us) << 1);
    // A stale compare flag is left alone: it costs at most one early COMPA interrupt, which
    // sees the deadline not reached (below). Clearing it (TIFR1 = _BV(OCF1A)) made simavr 1.6
    // drop an overflow pending at that instant: the clock fell 32.768 ms behind the simulation
    // once every ~30-60 s of device time (frames stamped that much before their readings).
    TIMSK1 |= _BV(OCIE1A);
    // Too close (the match may already be behind TCNT1) or past: reached now.
    if (static_cast<int32_t>(deadline_us - NowUsLocked()) < static_cast<int32_t>(kMarginUs)) {
      detail::g_reached = true;
      TIMSK1 &= static_cast<uint8_t>(~_BV(OCIE1A));
    }
  }
}

}  // namespace avr
}  // namespace ja

ISR(TIMER1_OVF_vect) {
  ja::avr::IsrActivity a(ja::app::activity::kTimerIsr);
  ja::avr::g_overflows = ja::avr::g_overflows + 1;
}

// The compare matches once per 32.768 ms wrap: far deadlines are checked against the full time.
ISR(TIMER1_COMPA_vect) {
  ja::avr::IsrActivity a(ja::app::activity::kTimerIsr);
  if (static_cast<int32_t>(ja::avr::NowUsLocked() - ja::avr::g_deadline_us) >= -1) {
    ja::avr::detail::g_reached = true;
    TIMSK1 &= static_cast<uint8_t>(~_BV(OCIE1A));
    ja::avr::WakeMainLoop();
  }
}
