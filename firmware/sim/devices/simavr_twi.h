/* Bridge between simavr's TWI (docs/sensors.md §D, D2) and the virtual I2C bus (ja_sim_devices.h):
 * the AVR virtual board attaches the same device models the native board and the host use.
 *
 * simavr (1.6 and upstream) raises on TWI_IRQ_OUTPUT: START with the 8-bit SLA (a repeated
 * START arrives as another START), WRITE with a data byte, READ (with TWI_COND_ACK when the
 * master will acknowledge the byte), STOP. A slave must answer synchronously, from inside
 * the callback, on TWI_IRQ_INPUT: ACK for the address and written bytes, READ with the byte.
 * Before every event the bridge moves device time to the AVR's cycle counter, so sampling
 * follows simulated time exactly (bus time itself is simavr's: 1.6 ignores TWBR).
 *
 * C, for the simavr harness; needs simavr's headers and links with ja_sim_devices. */
#ifndef JA_SIMAVR_TWI_H
#define JA_SIMAVR_TWI_H

#include <stdint.h>

#include "sim/devices/ja_sim_devices.h"

#ifdef __cplusplus
extern "C" {
#endif

struct avr_t;
struct avr_irq_t;

typedef struct ja_simavr_twi {
  struct avr_t* avr;
  ja_sim* sim;
  struct avr_irq_t* input;  /* TWI_IRQ_INPUT: replies to the master */
  struct avr_irq_t* output; /* TWI_IRQ_OUTPUT: the master's bus events */
  int in_transaction;
  uint64_t events; /* bus events handled */
} ja_simavr_twi;

/* Attaches `sim`'s bus to TWI number `twi` (0 on the ATmega2560). Returns 0, or -1 if the core
 * has no such TWI. `bridge` must outlive the simulation. */
int ja_simavr_twi_attach(ja_simavr_twi* bridge, struct avr_t* avr, ja_sim* sim, int twi);

#ifdef __cplusplus
}
#endif

#endif /* JA_SIMAVR_TWI_H */
