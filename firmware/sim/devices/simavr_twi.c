#include "sim/devices/simavr_twi.h"

#include <avr_twi.h>
#include <sim_avr.h>
#include <sim_io.h>
#include <sim_irq.h>
#include <sim_time.h>

static void ja_simavr_twi_reply(ja_simavr_twi* b, uint8_t msg, uint8_t addr, uint8_t data) {
  avr_raise_irq(b->input, avr_twi_irq_msg(msg, addr, data));
}

static void ja_simavr_twi_output(struct avr_irq_t* irq, uint32_t value, void* param) {
  ja_simavr_twi* b = (ja_simavr_twi*)param;
  avr_twi_msg_irq_t v;
  (void)irq;
  v.u.v = value;
  ++b->events;
  ja_sim_set_time_ns(b->sim, avr_cycles_to_nsec(b->avr, b->avr->cycle));
  if (v.u.twi.msg & TWI_COND_STOP) {
    if (b->in_transaction) ja_sim_bus_stop(b->sim);
    b->in_transaction = 0;
    return;
  }
  if (v.u.twi.msg & TWI_COND_START) {
    ja_sim_bus_start(b->sim);
    b->in_transaction = 1;
    if (ja_sim_bus_write_byte(b->sim, v.u.twi.addr) == 1) {
      ja_simavr_twi_reply(b, TWI_COND_ACK, v.u.twi.addr, 1);
    }
  } else if (v.u.twi.msg & TWI_COND_WRITE) {
    if (ja_sim_bus_write_byte(b->sim, v.u.twi.data) == 1) {
      ja_simavr_twi_reply(b, TWI_COND_ACK, v.u.twi.addr, 1);
    }
  } else if (v.u.twi.msg & TWI_COND_READ) {
    const int byte = ja_sim_bus_read_byte(b->sim, (v.u.twi.msg & TWI_COND_ACK) != 0);
    ja_simavr_twi_reply(b, TWI_COND_READ, v.u.twi.addr, (uint8_t)(byte & 0xFF));
  }
}

int ja_simavr_twi_attach(ja_simavr_twi* bridge, struct avr_t* avr, ja_sim* sim, int twi) {
  bridge->avr = avr;
  bridge->sim = sim;
  bridge->in_transaction = 0;
  bridge->events = 0;
  bridge->input = avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(twi), TWI_IRQ_INPUT);
  bridge->output = avr_io_getirq(avr, AVR_IOCTL_TWI_GETIRQ(twi), TWI_IRQ_OUTPUT);
  if (!bridge->input || !bridge->output) return -1;
  avr_irq_register_notify(bridge->output, ja_simavr_twi_output, bridge);
  return 0;
}
