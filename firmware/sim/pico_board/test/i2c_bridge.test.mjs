// The I2C0 bridge (i2c_bridge.mjs): bus events take their SCL time at the programmed rate, the
// device sees each byte, and the register fixes rp2040js needs (IC_INTR_MASK, IC_FS_SPKLEN).
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { RP2040 } from 'rp2040js';

import { I2cBridge } from '../i2c_bridge.mjs';

const IC_CON = 0x00, IC_TAR = 0x04, IC_DATA_CMD = 0x10, IC_FS_SCL_HCNT = 0x1c;
const IC_FS_SCL_LCNT = 0x20, IC_INTR_STAT = 0x2c, IC_INTR_MASK = 0x30, IC_ENABLE = 0x6c;
const IC_FS_SPKLEN = 0xa0, IC_RAW_INTR_STAT = 0x34;
const STOP = 1 << 9, CMD_READ = 1 << 8, RESTART = 1 << 10;
const R_STOP_DET = 1 << 9, R_TX_ABRT = 1 << 6;
const I2C0_IRQ = 23;

/** A chip whose I2C0 is bridged to a recording fake of the ja_sim bus calls. */
function bridged({ ackAddress = true } = {}) {
  const chip = new RP2040();
  const events = [];
  const api = {
    setTimeNs: () => 0,
    busStart: () => { events.push(['start', chip.clock.nanos]); return 0; },
    busWriteByte: (_sim, b) => {
      events.push(['write', b, chip.clock.nanos]);
      return events.filter((e) => e[0] === 'write').length === 1 && !ackAddress ? 0 : 1;
    },
    busReadByte: (_sim, ack) => { events.push(['read', ack, chip.clock.nanos]); return 0x5a; },
    busStop: () => { events.push(['stop', chip.clock.nanos]); return 0; },
  };
  const stats = { busyNs: 0 };
  const i2c = chip.i2c[0];
  const bridge = new I2cBridge(i2c, null, api, () => chip.clock.nanos, new Map(), stats);
  // 125 MHz: fast mode, LCNT 186 (low 187), SPKLEN 6, HCNT 113 (high 126): 313 clocks a period.
  i2c.writeUint32(IC_ENABLE, 0);
  i2c.writeUint32(IC_CON, 0x65 | (2 << 1));
  i2c.writeUint32(IC_FS_SCL_LCNT, 186);
  i2c.writeUint32(IC_FS_SPKLEN, 7); // odd: rp2040js alone refuses it
  i2c.writeUint32(IC_FS_SPKLEN, 6);
  i2c.writeUint32(IC_FS_SCL_HCNT, 113);
  i2c.writeUint32(IC_TAR, 0x53);
  i2c.writeUint32(IC_ENABLE, 1);
  return { chip, i2c, bridge, events, stats };
}

test('a register read takes 1 + 9 + 9 + 1 + 9 + 9 n + 1 SCL periods at the programmed rate', () => {
  const { chip, i2c, bridge, events, stats } = bridged();
  const period = bridge.sclPeriodNs();
  assert.ok(Math.abs(period - (313 * 1e9) / 125e6) < 1e-9, `period ${period}`);
  i2c.writeUint32(IC_DATA_CMD, 0x32); // register
  for (let k = 0; k < 6; k++) {
    i2c.writeUint32(IC_DATA_CMD, CMD_READ | (k === 0 ? RESTART : 0) | (k === 5 ? STOP : 0));
  }
  chip.clock.tick(1e6);
  const bits = 1 + 9 + 9 + 1 + 9 + 9 * 6 + 1;
  assert.ok(Math.abs(stats.busyNs - bits * period) < 1e-6, `${stats.busyNs} vs ${bits * period}`);
  const kinds = events.map((e) => e[0]);
  assert.deepEqual(kinds, ['start', 'write', 'write', 'start', 'write', 'read', 'read', 'read',
    'read', 'read', 'read', 'stop']);
  assert.equal(events[1][1], 0x53 << 1);
  assert.equal(events[4][1], (0x53 << 1) | 1);
  assert.deepEqual(events.filter((e) => e[0] === 'read').map((e) => e[1]), [1, 1, 1, 1, 1, 0]);
  const stopAt = events.at(-1)[1]; // the STOP's device call at the end of its period
  assert.ok(Math.abs(stopAt - bits * period) < 1e-6, `STOP at ${stopAt}`);
  for (let k = 0; k < 6; k++) assert.equal(i2c.readUint32(IC_DATA_CMD) & 0xff, 0x5a);
});

test('IC_INTR_MASK takes effect: STOP_DET raises I2C0_IRQ only when unmasked', () => {
  const { chip, i2c } = bridged();
  i2c.writeUint32(IC_DATA_CMD, STOP | 0x00);
  chip.clock.tick(1e6);
  assert.ok(i2c.readUint32(IC_RAW_INTR_STAT) & R_STOP_DET);
  assert.equal(chip.core.pendingInterrupts & (1 << I2C0_IRQ), 0);
  i2c.writeUint32(IC_INTR_MASK, R_STOP_DET);
  assert.equal(i2c.readUint32(IC_INTR_MASK), R_STOP_DET);
  assert.ok(i2c.readUint32(IC_INTR_STAT) & R_STOP_DET);
  assert.ok(chip.core.pendingInterrupts & (1 << I2C0_IRQ));
});

test('an absent address aborts with TX_ABRT after its nine bits', () => {
  const { chip, i2c, bridge, stats } = bridged({ ackAddress: false });
  i2c.writeUint32(IC_DATA_CMD, STOP | 0x00);
  chip.clock.tick(1e6);
  assert.ok(i2c.readUint32(IC_RAW_INTR_STAT) & R_TX_ABRT);
  assert.ok(Math.abs(stats.busyNs - 11 * bridge.sclPeriodNs()) < 1e-6); // START, address, STOP
});
