#include "sim/avr_board/twi_status.hpp"

#include <avr_twi.h>
#include <sim_avr.h>
#include <sim_io.h>
#include <sim_irq.h>
#include <sim_regbit.h>

namespace ja {
namespace avrboard {

namespace {
constexpr uint8_t kSlaWAck = 0x18, kSlaWNack = 0x20, kDataAck = 0x28, kDataNack = 0x30;
}  // namespace

bool TwiStatus::Attach(avr_t* avr) {
  avr_ = avr;
  const uint32_t ctl = AVR_IOCTL_TWI_GETIRQ(0);
  for (avr_io_t* io = avr->io_port; io; io = io->next) {
    if (io->irq_ioctl_get == ctl) twi_ = io;
  }
  if (!twi_) return false;
  avr_irq_register_notify(avr_io_getirq(avr, ctl, TWI_IRQ_OUTPUT), OnOutput, this);
  avr_irq_register_notify(avr_io_getirq(avr, ctl, TWI_IRQ_STATUS), OnStatus, this);
  return true;
}

void TwiStatus::OnOutput(avr_irq_t*, uint32_t value, void* param) {
  TwiStatus* t = static_cast<TwiStatus*>(param);
  avr_twi_msg_irq_t v;
  v.u.v = value;
  // START carries the address byte; R/W = 0 is SLA+W. Any other event ends the address phase.
  t->after_sla_w_ = (v.u.twi.msg & TWI_COND_START) && !(v.u.twi.addr & 1);
}

void TwiStatus::OnStatus(avr_irq_t*, uint32_t value, void* param) {
  TwiStatus* t = static_cast<TwiStatus*>(param);
  if (!t->after_sla_w_) return;
  t->after_sla_w_ = false;
  const uint8_t v = static_cast<uint8_t>(value & 0xF8u);
  const uint8_t fixed = v == kDataAck ? kSlaWAck : v == kDataNack ? kSlaWNack : v;
  if (fixed == v) return;
  avr_regbit_setto_raw(t->avr_, static_cast<avr_twi_t*>(t->twi_)->twsr, fixed);
  ++t->corrected_;
}

}  // namespace avrboard
}  // namespace ja
