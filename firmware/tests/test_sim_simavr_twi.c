/* The simavr TWI bridge (firmware/sim/devices/simavr_twi.c) on a real simavr ATmega2560 core:
 * bus events raised on TWI_IRQ_OUTPUT exactly as simavr's master raises them must get the
 * replies simavr expects on TWI_IRQ_INPUT (docs/sensors.md §D2), and device time must follow the
 * AVR's cycle counter. No firmware image is needed: the test plays the TWI master. */
#include <avr_twi.h>
#include <sim_avr.h>
#include <sim_io.h>
#include <sim_irq.h>
#include <stdio.h>
#include <string.h>

#include "sim/devices/ja_sim_devices.h"
#include "sim/devices/simavr_twi.h"

static int failures;
#define EXPECT(cond)                                                           \
  do {                                                                         \
    if (!(cond)) {                                                             \
      ++failures;                                                              \
      fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond); \
    }                                                                          \
  } while (0)

static uint8_t last_msg, last_data;
static int replies;

static void capture(struct avr_irq_t* irq, uint32_t value, void* param) {
  avr_twi_msg_irq_t v;
  (void)irq;
  (void)param;
  v.u.v = value;
  last_msg = v.u.twi.msg;
  last_data = v.u.twi.data;
  ++replies;
}

/* Raises one master event; returns 1 if it was ACKed (address/write) or the byte (read). */
static int event(ja_simavr_twi* b, uint8_t msg, uint8_t addr, uint8_t data) {
  replies = 0;
  last_msg = 0;
  avr_raise_irq(b->output, avr_twi_irq_msg(msg, addr, data));
  if (msg & TWI_COND_READ) return replies == 1 && (last_msg & TWI_COND_READ) ? last_data : -1;
  return replies == 1 && (last_msg & TWI_COND_ACK) && (last_data & 1);
}

static int read_reg(ja_simavr_twi* b, uint8_t addr7, uint8_t reg) {
  int v;
  EXPECT(event(b, TWI_COND_START, (uint8_t)(addr7 << 1), 0) == 1);
  EXPECT(event(b, TWI_COND_WRITE, (uint8_t)(addr7 << 1), reg) == 1);
  EXPECT(event(b, TWI_COND_START, (uint8_t)(addr7 << 1 | 1), 0) == 1); /* repeated START */
  v = event(b, TWI_COND_READ, (uint8_t)(addr7 << 1 | 1), 0);           /* NACKed: last */
  event(b, TWI_COND_STOP, (uint8_t)(addr7 << 1 | 1), 1);
  return v;
}

static void write_reg(ja_simavr_twi* b, uint8_t addr7, uint8_t reg, uint8_t value) {
  EXPECT(event(b, TWI_COND_START, (uint8_t)(addr7 << 1), 0) == 1);
  EXPECT(event(b, TWI_COND_WRITE | TWI_COND_ACK, (uint8_t)(addr7 << 1), reg) == 1);
  EXPECT(event(b, TWI_COND_WRITE | TWI_COND_ACK, (uint8_t)(addr7 << 1), value) == 1);
  event(b, TWI_COND_STOP, (uint8_t)(addr7 << 1), 1);
}

int main(void) {
  avr_t* avr = avr_make_mcu_by_name("atmega2560");
  ja_sim* sim = ja_sim_create();
  ja_simavr_twi bridge;
  const double pose[3] = {0.5 * 9.80665, 0.0, 9.80665};
  int a0, lo, hi;
  ja_sim_device_counters c;
  ja_sim_bus_counters bc;
  if (!avr || !sim) return 1;
  avr_init(avr);
  avr->frequency = 16000000;
  EXPECT(ja_sim_attach_rig(sim, "a.0 adxl345 0x53 0\n") == 1);
  a0 = ja_sim_find_device(sim, "a.0");
  EXPECT(ja_sim_set_constant_motion(sim, a0, pose, NULL) == JA_SIM_OK);
  EXPECT(ja_simavr_twi_attach(&bridge, avr, sim, 0) == 0);
  avr_irq_register_notify(bridge.input, capture, NULL);

  /* Nothing selected on the mux: the sensor NACKs its address (no reply = NACK). */
  EXPECT(event(&bridge, TWI_COND_START, 0x53 << 1, 0) == 0);
  event(&bridge, TWI_COND_STOP, 0x53 << 1, 1);
  /* Select channel 0 (one byte to the mux), read it back. */
  EXPECT(event(&bridge, TWI_COND_START, 0x70 << 1, 0) == 1);
  EXPECT(event(&bridge, TWI_COND_WRITE, 0x70 << 1, 0x01) == 1);
  event(&bridge, TWI_COND_STOP, 0x70 << 1, 1);
  EXPECT(event(&bridge, TWI_COND_START, 0x70 << 1 | 1, 0) == 1);
  EXPECT(event(&bridge, TWI_COND_READ, 0x70 << 1 | 1, 0) == 0x01);
  event(&bridge, TWI_COND_STOP, 0x70 << 1 | 1, 1);
  EXPECT(read_reg(&bridge, 0x53, 0x00) == 0xE5);

  /* Full resolution, 800 Hz, measure; 2 ms of AVR cycles later a conversion is ready. */
  write_reg(&bridge, 0x53, 0x31, 0x08);
  write_reg(&bridge, 0x53, 0x2C, 0x0D);
  write_reg(&bridge, 0x53, 0x2D, 0x08);
  EXPECT((read_reg(&bridge, 0x53, 0x30) & 0x80) == 0);
  avr->cycle += 32000; /* 2 ms at 16 MHz */
  EXPECT(read_reg(&bridge, 0x53, 0x30) & 0x80);
  EXPECT(ja_sim_time_ns(sim) >= 2000000u);
  /* A two-byte read with master ACK on the first byte: X = 128 (0.5 g / 3.9 mg). */
  EXPECT(event(&bridge, TWI_COND_START, 0x53 << 1, 0) == 1);
  EXPECT(event(&bridge, TWI_COND_WRITE, 0x53 << 1, 0x32) == 1);
  EXPECT(event(&bridge, TWI_COND_START, 0x53 << 1 | 1, 0) == 1);
  lo = event(&bridge, TWI_COND_READ | TWI_COND_ACK, 0x53 << 1 | 1, 0);
  hi = event(&bridge, TWI_COND_READ, 0x53 << 1 | 1, 0);
  event(&bridge, TWI_COND_STOP, 0x53 << 1 | 1, 1);
  EXPECT(lo == 128 && hi == 0);

  EXPECT(ja_sim_get_device_counters(sim, a0, &c, sizeof c) == JA_SIM_OK);
  EXPECT(c.address_nacks == 0); /* unreachable behind the mux: the bus NACKed, not the part */
  EXPECT(ja_sim_get_bus_counters(sim, &bc, sizeof bc) == JA_SIM_OK);
  EXPECT(bc.address_nacks == 1);
  EXPECT(c.samples_read == 1);
  ja_sim_destroy(sim);
  avr_terminate(avr);
  if (failures) {
    fprintf(stderr, "test_sim_simavr_twi: %d check(s) failed\n", failures);
    return 1;
  }
  printf("test_sim_simavr_twi: all checks passed\n");
  return 0;
}
