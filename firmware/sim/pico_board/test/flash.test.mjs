// The bootrom model (flash.mjs): boot2's CRC rule and the flash functions' semantics.
import assert from 'node:assert/strict';
import { test } from 'node:test';

import { RP2040 } from 'rp2040js';

import { BootError, FlashModel, crc32Mpeg2 } from '../flash.mjs';

test('CRC-32/MPEG-2 of "123456789" is its check value 0x0376E6E7', () => {
  assert.equal(crc32Mpeg2(Buffer.from('123456789')), 0x0376e6e7);
});

function call(chip, model, code, args, lr = 0x20000101) {
  args.forEach((v, i) => { chip.core.registers[i] = v; });
  chip.core.LR = lr;
  return model.handle(chip, code);
}

test('erase sets a sector to 0xFF, program only clears bits, both reported and timed', () => {
  const chip = new RP2040();
  const writes = [];
  const model = new FlashModel((o, n) => writes.push([o, n]));
  chip.flash.fill(0x0f, 0x1000, 0x2000);
  call(chip, model, 0x11, []);
  const t0 = chip.clock.nanos;
  call(chip, model, 0x12, [0x1000, 4096, 4096, 0x20]);
  assert.ok(chip.clock.nanos - t0 >= 45e6);
  assert.ok(chip.flash.subarray(0x1000, 0x2000).every((b) => b === 0xff));
  chip.sram.fill(0xf0, 0, 256);
  chip.flash.fill(0x3c, 0x1000, 0x1100);
  call(chip, model, 0x13, [0x1000, 0x20000000, 256]);
  assert.equal(chip.flash[0x1000], 0x30);
  assert.deepEqual(writes, [[0x1000, 4096], [0x1000, 256]]);
});

test('misaligned, out-of-range and flash-resident callers are refused', () => {
  const chip = new RP2040();
  const model = new FlashModel(() => {});
  call(chip, model, 0x11, []);
  assert.throws(() => call(chip, model, 0x12, [0x800, 4096, 4096, 0x20]), BootError);
  assert.throws(() => call(chip, model, 0x13, [0x1ff000, 0x20000000, 8192]), BootError);
  assert.throws(() => call(chip, model, 0x12, [0x1000, 4096, 4096, 0x20], 0x10001235),
    /runs from flash while XIP is off/);
  call(chip, model, 0x15, []);
  assert.equal(model.handle(chip, 0x7f), false, 'not one of the bootrom\'s');
});

test('a boot2 whose CRC does not match stops the boot', () => {
  const chip = new RP2040();
  const model = new FlashModel(() => {});
  const at = 0x41f00;
  chip.sram.fill(0x11, at, at + 252);
  const crc = crc32Mpeg2(chip.sram.subarray(at, at + 252));
  new DataView(chip.sram.buffer).setUint32(at + 252, crc, true);
  assert.equal(model.handle(chip, 0x01), true);
  chip.sram[at + 7] ^= 1;
  assert.throws(() => model.handle(chip, 0x01), /CRC-32/);
});
