/* A small ATmega2560 image that exercises the AVR virtual board (ja_avr_board) until the real
 * firmware image exists: the same hardware contract (issue 6) on a few hundred bytes.
 *
 * - USART0 at 500 000 baud (U2X0, UBRR0 = 3), interrupt-driven TX ring; every received byte is
 *   echoed back, and some are commands: 'R' = watchdog reset, 'W' = store the next byte at
 *   EEPROM addresses 4000 and 4001 (past the configuration image) and answer "E <us hex>", the
 *   time the two writes took; 'S' = sleep with interrupts off (the simulation ends); 'P' = the
 *   TWSR codes after SLA+W to the ADXL345, SLA+W and SLA+R to the absent 0x11: "P <hex> <hex>
 *   <hex>" (an ATmega2560: 18 20 48; simavr 1.6 alone: 28 30 48).
 * - TWI master at 400 kHz (TWBR = 12), interrupt-driven: at boot it selects channel 0 of the
 *   TCA9548A at 0x70, reads the ADXL345's DEVID (0x53, register 0x00) and sets POWER_CTL = 0x08;
 *   on every 500 Hz tick (Timer1 CTC) it reads DATAX0..DATAZ1 (6 bytes from 0x32).
 * - Boot line: "BOOT <eeprom[4000] hex> <MCUSR hex> <DEVID hex>", then "T <ticks>": one 6-byte
 *   register read timed by Timer1 (0.5 us ticks, hex); per tick: "D <x> <y> <z>" (hex int16, the
 *   raw counts).
 * - Activity ids in GPIOR1 (1 TWI ISR, 2 USART ISRs, 3 "filter" (a dummy product loop),
 *   5 framing, 6 timer ISR); idle time asleep (SLEEP_MODE_IDLE).
 * TWI states accept simavr 1.6's 0x28 for an acknowledged SLA+W (docs/sensors.md §D2). */
#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <avr/wdt.h>
#include <stdint.h>

#include "avr_mcu_section.h"
AVR_MCU(F_CPU, "atmega2560");

#define ACT(id) (GPIOR1 = (id))

/* ---- USART0 ---- */
static volatile uint8_t tx_buf[256];
static volatile uint8_t tx_head, tx_tail;
static volatile uint8_t rx_buf[32];
static volatile uint8_t rx_head, rx_tail;

ISR(USART0_UDRE_vect) {
  uint8_t s = GPIOR1;
  ACT(2);
  if (tx_head == tx_tail) {
    UCSR0B &= (uint8_t)~_BV(UDRIE0);
  } else {
    UDR0 = tx_buf[tx_tail++];
  }
  GPIOR1 = s;
}

ISR(USART0_RX_vect) {
  uint8_t s = GPIOR1;
  ACT(2);
  rx_buf[rx_head++ & 31] = UDR0;
  GPIOR1 = s;
}

static void put(uint8_t c) {
  while ((uint8_t)(tx_head + 1) == tx_tail) {
  }
  tx_buf[tx_head++] = c;
  UCSR0B |= _BV(UDRIE0);
}

static void put_hex(uint16_t v, uint8_t digits) {
  while (digits--) put("0123456789abcdef"[(v >> (4 * digits)) & 15]);
}

/* ---- TWI: one transaction at a time (write w[0..nw), then read nr bytes into r). ---- */
static volatile uint8_t twi_addr, twi_nw, twi_nr, twi_i, twi_busy, twi_err;
static volatile uint8_t twi_sla_sent, twi_sla_status; /* TWSR after the last SLA byte */
static volatile uint8_t twi_w[4], twi_r[8];

#define TWI_GO(extra) (TWCR = _BV(TWINT) | _BV(TWEN) | _BV(TWIE) | (extra))

ISR(TWI_vect) {
  uint8_t s = GPIOR1;
  ACT(1);
  if (twi_sla_sent) twi_sla_status = TWSR & 0xF8, twi_sla_sent = 0;
  switch (TWSR & 0xF8) {
    case 0x08: /* START */
    case 0x10: /* repeated START */
      twi_i = 0;
      TWDR = (uint8_t)(twi_addr << 1) | (twi_nw ? 0 : 1);
      twi_sla_sent = 1;
      TWI_GO(0);
      break;
    case 0x18: /* SLA+W ACK */
    case 0x28: /* data ACK (and simavr 1.6's SLA+W ACK) */
      if (twi_i < twi_nw) {
        TWDR = twi_w[twi_i++];
        TWI_GO(0);
      } else if (twi_nr) {
        twi_nw = 0;
        TWI_GO(_BV(TWSTA));
      } else {
        TWI_GO(_BV(TWSTO));
        twi_busy = 0;
      }
      break;
    case 0x40: /* SLA+R ACK */
      TWI_GO(twi_nr > 1 ? _BV(TWEA) : 0);
      break;
    case 0x50: /* data received, ACK sent */
      twi_r[twi_i++] = TWDR;
      TWI_GO(twi_i + 1 < twi_nr ? _BV(TWEA) : 0);
      break;
    case 0x58: /* last byte received, NACK sent */
      twi_r[twi_i++] = TWDR;
      TWI_GO(_BV(TWSTO));
      twi_busy = 0;
      break;
    default: /* NACK or bus error */
      twi_err = 1;
      TWI_GO(_BV(TWSTO));
      twi_busy = 0;
      break;
  }
  GPIOR1 = s;
}

static void idle(void) {
  cli();
  sleep_enable();
  sei();
  sleep_cpu();
  sleep_disable();
}

static uint8_t twi(uint8_t addr, uint8_t nw, uint8_t w0, uint8_t w1, uint8_t nr) {
  twi_addr = addr;
  twi_nw = nw;
  twi_w[0] = w0;
  twi_w[1] = w1;
  twi_nr = nr;
  twi_err = 0;
  twi_busy = 1;
  TWI_GO(_BV(TWSTA));
  while (twi_busy) idle();
  return !twi_err;
}

/* ---- Timer1: 500 Hz sample clock. ---- */
static volatile uint8_t tick;
static volatile uint16_t ticks;
ISR(TIMER1_COMPA_vect) {
  uint8_t s = GPIOR1;
  ACT(6);
  tick = 1;
  ++ticks;
  GPIOR1 = s;
}

/* Microseconds since boot modulo 2^32 (Timer1 at 2 MHz wraps every 2 ms). */
static uint32_t now_us(void) {
  cli();
  uint16_t t = ticks, c = TCNT1;
  if (TIFR1 & _BV(OCF1A)) ++t, c = TCNT1; /* a wrap not yet counted */
  sei();
  return (uint32_t)t * 2000u + c / 2u;
}

int main(void) {
  const uint8_t mcusr = MCUSR;
  MCUSR = 0;
  wdt_disable();
  UCSR0A = _BV(U2X0); /* U2X and the frame format before UBRR (simavr reads them then) */
  UCSR0C = _BV(UCSZ01) | _BV(UCSZ00);
  UBRR0H = 0;
  UBRR0L = 3;
  UCSR0B = _BV(RXEN0) | _BV(TXEN0) | _BV(RXCIE0);
  TWSR = 0;
  TWBR = 12; /* 16 MHz / (16 + 2 * 12) = 400 kHz */
  TCCR1A = 0;
  TCCR1B = _BV(WGM12) | _BV(CS11); /* CTC, clk/8: 2 MHz */
  OCR1A = 3999;                    /* 2 MHz / 4000 = 500 Hz */
  TIMSK1 = _BV(OCIE1A);
  set_sleep_mode(SLEEP_MODE_IDLE);
  sei();

  twi(0x70, 1, 0x01, 0, 0);                    /* mux channel 0 */
  const uint8_t ok = twi(0x53, 1, 0x00, 0, 1); /* DEVID */
  const uint8_t devid = ok ? twi_r[0] : 0;
  twi(0x53, 2, 0x2D, 0x08, 0); /* POWER_CTL: measure */
  twi(0x53, 2, 0x2C, 0x0D, 0); /* BW_RATE: 800 Hz */
  /* Before any UART traffic: one 6-byte register read timed with Timer1 (2 MHz, wraps at 4000): "T
   * <ticks hex>". */
  const uint16_t t0 = TCNT1;
  twi(0x53, 1, 0x32, 0, 6);
  const uint16_t t1 = TCNT1;
  put('B'), put('O'), put('O'), put('T'), put(' ');
  put_hex(eeprom_read_byte((const uint8_t*)4000), 2);
  put(' ');
  put_hex(mcusr, 2);
  put(' ');
  put_hex(devid, 2);
  put('\n');
  put('T'), put(' ');
  put_hex((uint16_t)((t1 + 4000u - t0) % 4000u), 4);
  put('\n');

  uint8_t pending_write = 0;
  volatile int32_t acc = 0;
  for (;;) {
    ACT(0);
    while (rx_tail != rx_head) {
      const uint8_t c = rx_buf[rx_tail++ & 31];
      put(c);
      if (pending_write) {
        /* Two byte writes and the wait for the second: 2 x 3.4 ms on the chip. */
        const uint32_t t0 = now_us();
        eeprom_write_byte((uint8_t*)4000, c);
        eeprom_write_byte((uint8_t*)4001, c);
        eeprom_busy_wait();
        const uint16_t us = (uint16_t)(now_us() - t0);
        put('E'), put(' ');
        put_hex(us, 4);
        put('\n');
        pending_write = 0;
      } else if (c == 'W') {
        pending_write = 1;
      } else if (c == 'R') {
        while (tx_head != tx_tail) idle();
        wdt_enable(WDTO_15MS);
        for (;;) {
        }
      } else if (c == 'P') {
        uint8_t st[3];
        twi(0x53, 1, 0x00, 0, 0);
        st[0] = twi_sla_status;
        twi(0x11, 1, 0x00, 0, 0);
        st[1] = twi_sla_status;
        twi(0x11, 0, 0, 0, 1);
        st[2] = twi_sla_status;
        put('P');
        for (uint8_t i = 0; i < 3; ++i) put(' '), put_hex(st[i], 2);
        put('\n');
      } else if (c == 'S') {
        while (tx_head != tx_tail) idle();
        cli();
        sleep_enable();
        sleep_cpu();
      }
    }
    if (!tick) {
      idle();
      continue;
    }
    tick = 0;
    twi(0x53, 1, 0x32, 0, 6);
    ACT(3);
    for (uint8_t i = 0; i < 40; ++i) acc += (int32_t)twi_r[i & 7] * (int32_t)(i + 1);
    ACT(5);
    put('D');
    for (uint8_t i = 0; i < 6; i += 2) {
      put(' ');
      put_hex((uint16_t)(twi_r[i] | (twi_r[i + 1] << 8)), 4);
    }
    put('\n');
  }
}
