#include "sim/avr_board/twi_timing.hpp"

#include <avr_twi.h>
#include <sim_avr.h>
#include <sim_cycle_timers.h>
#include <sim_interrupts.h>
#include <sim_io.h>
#include <sim_irq.h>

namespace ja {
namespace avrboard {

bool TwiTiming::Attach(avr_t* avr, uint32_t scl_hz) {
  avr_ = avr;
  const uint32_t ctl = AVR_IOCTL_TWI_GETIRQ(0);
  for (avr_io_t* io = avr->io_port; io; io = io->next) {
    if (io->irq_ioctl_get == ctl) twi_ = io;
  }
  if (!twi_) return false;
  if (scl_hz == 0) return true;  // simavr's own timing
  // One byte + ACK = 9 SCL periods: cycles = 9 * F_CPU / f_SCL.
  byte_cycles_ = (9ull * avr->frequency + scl_hz / 2) / scl_hz;
  avr_irq_register_notify(avr_io_getirq(avr, ctl, TWI_IRQ_OUTPUT), OnOutput, this);
  return true;
}

void TwiTiming::OnOutput(avr_irq_t*, uint32_t value, void* param) {
  TwiTiming* t = static_cast<TwiTiming*>(param);
  avr_twi_msg_irq_t v;
  v.u.v = value;
  // START carries the address byte (SLA+R/W); WRITE and READ a data byte. STOP: no wait.
  if (v.u.twi.msg & (TWI_COND_START | TWI_COND_WRITE | TWI_COND_READ)) {
    t->pending_ = true;
    t->event_cycle_ = t->avr_->cycle;
    t->extra_cycles_ = 0;
    const uint8_t sla = v.u.twi.addr;
    if ((v.u.twi.msg & TWI_COND_START) && (sla & 1) && t->stretch_us_[sla >> 1]) {
      t->extra_cycles_ = uint64_t(t->stretch_us_[sla >> 1]) * t->avr_->frequency / 1000000u;
    }
  }
}

void TwiTiming::SetStretch(uint8_t addr7, uint32_t us) { stretch_us_[addr7 & 0x7F] = us; }

avr_cycle_count_t TwiTiming::RaiseLater(avr_t* avr, avr_cycle_count_t, void* param) {
  avr_raise_interrupt(avr, &static_cast<avr_twi_t*>(param)->twi);
  return 0;
}

void TwiTiming::Stretch() {
  pending_ = false;
  const uint64_t due = event_cycle_ + byte_cycles_ + extra_cycles_;
  const uint64_t wait = due > avr_->cycle ? due - avr_->cycle : 0;
  for (avr_cycle_timer_slot_t* s = avr_->cycle_timers.timer; s; s = s->next) {
    if (s->param != twi_) continue;
    if (s->when < due) {
      const avr_cycle_timer_t fn = s->timer;
      avr_cycle_timer_cancel(avr_, fn, twi_);
      avr_cycle_timer_register(avr_, wait, fn, twi_);
      ++stretched_;
    }
    return;
  }
  // No wait pending: simavr 1.6 gives SLA+W no delay, so TWINT is already up. Take it back and
  // raise it when the byte would have ended.
  avr_twi_t* t = static_cast<avr_twi_t*>(twi_);
  if (wait > 0 && avr_regbit_get(avr_, t->twi.raised)) {
    avr_clear_interrupt(avr_, &t->twi);
    avr_cycle_timer_register(avr_, wait, RaiseLater, twi_);
    ++stretched_;
  }
}

}  // namespace avrboard
}  // namespace ja
