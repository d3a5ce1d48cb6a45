#!/usr/bin/env node
// The Pico's cycle harness, the counterpart of firmware/sim/avr_cycles for the RP2040: runs a
// bench image (e.g. bench_filter built for the Pico) in rp2040js with no devices and reports, as
// avr_cycles does, its cycle regions (bkpt #0x20 id / #0x21: count, min, max, mean, net of the
// "empty" region's overhead), its console (bkpt #0x22; "@region <id> <name>" lines name regions),
// the input it read (bkpt #0x23, from --input), until it finishes (bkpt #0x24). Markers:
// firmware/platform/pico/bench/cycle_marker.hpp. Cycles are rp2040js's core cycle estimates.
//
//   node pico_cycles.mjs [--input FILE] [--max-cycles N] [--bootrom FILE] IMAGE.elf
import { readFileSync } from 'node:fs';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

import { placeInFlash, readElf } from './elf.mjs';
import { FLASH_BASE, FLASH_BYTES } from './flash.mjs';
import { Machine } from './machine.mjs';

const HERE = dirname(fileURLToPath(import.meta.url));

function fail(message) {
  process.stderr.write(`pico_cycles: ${message}\n`);
  process.exit(2);
}

function parse(argv) {
  const o = { input: '', maxCycles: 8e9, image: '',
    bootrom: resolve(HERE, '../../../build/native/firmware/sim/pico_bootrom.bin') };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    const value = () => (i + 1 < argv.length ? argv[++i] : fail(`${a} needs a value`));
    if (a === '--input') o.input = value();
    else if (a === '--max-cycles') o.maxCycles = Number(value());
    else if (a === '--bootrom') o.bootrom = value();
    else if (!a.startsWith('-') && !o.image) o.image = a;
    else fail(`unknown argument ${a}\nusage: pico_cycles.mjs [--input FILE] [--max-cycles N] [--bootrom FILE] IMAGE.elf`);
  }
  if (!o.image) fail('no image given');
  return o;
}

function main() {
  const o = parse(process.argv.slice(2));
  let elf;
  let input = new Uint8Array(0);
  let bootrom;
  const flash = new Uint8Array(FLASH_BYTES).fill(0xff);
  try {
    elf = readElf(o.image);
    placeInFlash(elf, flash, FLASH_BASE, o.image);
    if (o.input) input = readFileSync(o.input);
    bootrom = readFileSync(o.bootrom);
  } catch (e) {
    fail(e.message);
  }
  const regions = new Map();
  const names = new Map();
  const console = [];
  let line = '';
  let open = null;
  let markerErrors = 0;
  let inputAt = 0;
  let inputOverrun = 0;
  let done = false;
  const printed = (text) => {
    for (const ch of text) {
      if (ch !== '\n') { line += ch; continue; }
      const m = /^@region (\d+) (\S+)$/.exec(line);
      if (m) names.set(Number(m[1]), m[2]);
      else console.push(line);
      line = '';
    }
  };
  const onBreak = (code, chip) => {
    const { core } = chip;
    switch (code) {
      case 0x20:
        if (open) markerErrors++;
        open = { id: core.registers[0] & 0xff, cycle: core.cycles };
        return true;
      case 0x21: {
        if (!open) { markerErrors++; return true; }
        const d = core.cycles - open.cycle;
        const r = regions.get(open.id) ?? { count: 0, min: Infinity, max: 0, sum: 0 };
        r.count++; r.sum += d; r.min = Math.min(r.min, d); r.max = Math.max(r.max, d);
        regions.set(open.id, r);
        open = null;
        return true;
      }
      case 0x22: {
        let at = core.registers[0] >>> 0;
        let text = '';
        for (let c = chip.readUint8(at); c; c = chip.readUint8(++at)) text += String.fromCharCode(c);
        printed(text);
        return true;
      }
      case 0x23:
        if (inputAt < input.length) core.registers[0] = input[inputAt++];
        else { core.registers[0] = 0; inputOverrun++; }
        return true;
      case 0x24: done = true; return true;
      default: return false;
    }
  };
  const machine = new Machine({ bootrom: new Uint8Array(bootrom), flash, onBreak });
  machine.paintStack();
  const chunkNs = 10e6;
  while (!done && machine.busyCycles < o.maxCycles) machine.run(chunkNs);
  const sym = (n) => elf.symbols.get(n);
  const ramStart = sym('__data_start__');
  const ramEnd = sym('__bss_end__');
  const overhead = [...regions].find(([id]) => names.get(id) === 'empty')?.[1].min ?? 0;
  const out = {
    elf: o.image, mcu: 'rp2040', frequency_hz: machine.chip.clkSys,
    state: done ? 'done' : 'timeout', total_cycles: machine.busyCycles,
    marker_errors: markerErrors,
    static_ram_bytes: ramStart !== undefined && ramEnd !== undefined ? ramEnd - ramStart : null,
    stack_peak_bytes: machine.stackPeakBytes(), overhead_cycles: overhead, input_overrun: inputOverrun,
    regions: Object.fromEntries([...regions].sort(([a], [b]) => a - b).map(([id, r]) => [
      names.get(id) ?? `region${id}`,
      { id, count: r.count, min: r.min, max: r.max, mean: Math.round((r.sum / r.count) * 10) / 10,
        net_max: r.max - overhead }])),
    console,
  };
  process.stdout.write(JSON.stringify(out, null, 1) + '\n');
  process.exit(done && markerErrors === 0 ? 0 : 1);
}

main();
