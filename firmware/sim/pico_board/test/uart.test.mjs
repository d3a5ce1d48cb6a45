// The PL011 model's timing and interrupt rules (uart.mjs), on a bare rp2040js chip.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { RP2040 } from 'rp2040js';

import { PacedUart } from '../uart.mjs';

const DR = 0x00, FR = 0x18, IBRD = 0x24, FBRD = 0x28, LCR_H = 0x2c, CR = 0x30, IFLS = 0x34;
const IMSC = 0x38, RIS = 0x3c, ICR = 0x44;
const INT_RX = 1 << 4, INT_TX = 1 << 5, INT_RT = 1 << 6, INT_OE = 1 << 10;
const FR_TXFF = 1 << 5, FR_RXFE = 1 << 4, FR_BUSY = 1 << 3;

function uart({ fifo = true } = {}) {
  const chip = new RP2040();
  const wire = [];
  const u = new PacedUart(chip, 'UART0', 20, (b) => wire.push([b, chip.clock.nanos]));
  // 115 200 baud at clk_peri 125 MHz: divisor 125e6 / (16 * 115200) = 67.817 -> 67 + 52/64.
  u.writeUint32(IBRD, 67);
  u.writeUint32(FBRD, 52);
  u.writeUint32(LCR_H, (3 << 5) | (fifo ? 1 << 4 : 0)); // 8N1
  u.writeUint32(CR, (1 << 0) | (1 << 8) | (1 << 9));
  return { chip, u, wire };
}

test('each byte takes its 8N1 frame time at the programmed rate', () => {
  const { chip, u, wire } = uart();
  const frameNs = (10 * 1e9) / (125e6 / (16 * (67 + 52 / 64)));
  for (const b of [1, 2, 3]) u.writeUint32(DR, b);
  assert.ok(u.readUint32(FR) & FR_BUSY);
  chip.clock.tick(frameNs * 3 + 1);
  assert.deepEqual(wire.map(([b]) => b), [1, 2, 3]);
  wire.forEach(([, t], i) => assert.ok(Math.abs(t - frameNs * (i + 1)) < 1, `byte ${i} at ${t}`));
  assert.equal(u.readUint32(FR) & FR_BUSY, 0);
});

test('a full transmit FIFO says so and loses what is written to it', () => {
  const { chip, u, wire } = uart();
  for (let i = 0; i < 40; i++) u.writeUint32(DR, i);
  assert.ok(u.readUint32(FR) & FR_TXFF);
  chip.clock.tick(1e9);
  assert.equal(wire.length, 33); // the shift register and 32 in the FIFO
});

test('the TX interrupt is a transition to the trigger level, not a level', () => {
  const { chip, u } = uart();
  u.writeUint32(IFLS, 0); // TX at 1/8 (4 bytes)
  u.writeUint32(IMSC, INT_TX);
  assert.equal(u.readUint32(RIS) & INT_TX, 0, 'an empty FIFO raises nothing when enabled');
  for (let i = 0; i < 10; i++) u.writeUint32(DR, i);
  assert.equal(u.readUint32(RIS) & INT_TX, 0);
  const frameNs = 10 * 1e9 / u.baud;
  chip.clock.tick(frameNs * 5 + 1); // 1 in the shift register at first, 9 queued; 5 sent -> 4 left
  assert.ok(u.readUint32(RIS) & INT_TX);
  assert.ok(chip.core.pendingInterrupts & (1 << 20));
  u.writeUint32(ICR, INT_TX);
  assert.equal(u.readUint32(RIS) & INT_TX, 0);
  assert.equal(chip.core.pendingInterrupts & (1 << 20), 0);
});

test('RX at its trigger level, RT after 32 bit periods, OE on a full FIFO', () => {
  const { chip, u } = uart();
  u.writeUint32(IFLS, 2 << 3); // RX at 1/2 (16 bytes)
  u.writeUint32(IMSC, INT_RX | INT_RT | INT_OE);
  const frameNs = 10 * 1e9 / u.baud;
  for (let i = 0; i < 15; i++) u.feed(i);
  chip.clock.tick(frameNs * 15 + 1);
  assert.equal(u.readUint32(RIS) & INT_RX, 0);
  chip.clock.tick(frameNs * 3.2); // 32 bit periods of silence
  assert.ok(u.readUint32(RIS) & INT_RT);
  u.feed(15);
  chip.clock.tick(frameNs + 1);
  assert.ok(u.readUint32(RIS) & INT_RX);
  for (let i = 0; i < 16; i++) assert.equal(u.readUint32(DR) & 0xff, i);
  assert.equal(u.readUint32(RIS) & (INT_RX | INT_RT), 0, 'read empty: both clear');
  assert.ok(u.readUint32(FR) & FR_RXFE);
  for (let i = 0; i < 33; i++) u.feed(i);
  chip.clock.tick(frameNs * 34);
  assert.ok(u.readUint32(RIS) & INT_OE);
  assert.equal(u.overruns, 1);
});

test('with FIFOs off the holding register is one byte deep', () => {
  const { chip, u, wire } = uart({ fifo: false });
  for (let i = 0; i < 5; i++) u.writeUint32(DR, i);
  chip.clock.tick(1e9);
  assert.deepEqual(wire.map(([b]) => b), [0, 1]);
});
