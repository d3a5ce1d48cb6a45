#!/usr/bin/env node
// The Pico virtual board (sim://pico): the RP2040 image run in rp2040js, its I2C0 on the virtual
// devices, its UART0 on a pty; options, rig, faults, line and settings file as the other virtual
// boards (libja_sim_board: firmware/sim/board_common/ja_sim_board.h). README.md beside this file.
import { closeSync, openSync, readFileSync, writeSync, writeFileSync } from 'node:fs';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

import { ElfError, placeInFlash, readElf } from './elf.mjs';
import { BootError, FLASH_BASE, FLASH_BYTES, SECTOR_BYTES } from './flash.mjs';
import { HaltError, Machine } from './machine.mjs';
import {
  LINE_PULLED, SETTINGS_ERASED, WIRE_MAX, bindSimBoard, bindSimDevices,
} from './native.mjs';

const NAME = 'ja_pico_board';
const HERE = dirname(fileURLToPath(import.meta.url));
const BUILD_SIM = resolve(HERE, '../../../build/native/firmware/sim');
const SLICE_NS = 500_000; // the line, faults and pacing are serviced every 0.5 ms simulated
const SETTINGS_OFFSET = FLASH_BYTES - SECTOR_BYTES; // the last sector (the image's settings)
const FAST_STREAM_NS = 100e6; // --fast: ahead of real time while a byte left within 100 ms
const DRAIN_TAIL_NS = 50e6;

const USAGE =
  '  [--report FILE.json] [--seconds S] [--measure-from S] [--measure-seconds W]\n'
  + '  [--clock-stretch ADDR=US]... [--uart-log FILE] [--no-pty]\n'
  + '  [--bootrom FILE] [--board-lib FILE] IMAGE.elf\n'
  + '  (or --elf IMAGE.elf: any RP2040 image; its settings sector starts erased)\n';

function fail(message, status = 2) {
  process.stderr.write(`${NAME}: ${message}\n`);
  process.exit(status);
}

/** Takes the Pico board's own options out of argv; the rest are the common ones. */
function parseOwnArgs(argv) {
  const own = {
    image: '', userImage: false, report: '', seconds: -1, measureFromS: 0, measureSeconds: -1,
    stretchUs: new Map(), uartLog: '', pty: true,
    bootrom: join(BUILD_SIM, 'pico_bootrom.bin'), boardLib: join(BUILD_SIM, 'libja_sim_board.so'),
  };
  const common = [];
  const seconds = (flag, text) => {
    const s = Number(text);
    if (text === undefined || text === '' || !Number.isFinite(s) || s < 0) {
      fail(`${flag} ${text ?? ''}: expected seconds >= 0`);
    }
    return s;
  };
  for (let i = 0; i < argv.length; i++) {
    const a = argv[i];
    const value = () => {
      if (i + 1 >= argv.length) fail(`${a} needs a value\nusage: ${NAME} [common options]\n${USAGE}`);
      return argv[++i];
    };
    if (a === '--help' || a === '-h') {
      process.stdout.write(`usage: ${NAME} --rig RIG.toml --motion DATA.csv [common options]\n${USAGE}`);
      process.exit(0);
    } else if (a === '--elf') { own.image = value(); own.userImage = true; common.push('--cold-start'); }
    else if (a === '--report') own.report = value();
    else if (a === '--seconds') own.seconds = seconds(a, value());
    else if (a === '--measure-from') own.measureFromS = seconds(a, value());
    else if (a === '--measure-seconds') own.measureSeconds = seconds(a, value());
    else if (a === '--uart-log') own.uartLog = value();
    else if (a === '--no-pty') own.pty = false;
    else if (a === '--bootrom') own.bootrom = value();
    else if (a === '--board-lib') own.boardLib = value();
    else if (a === '--clock-stretch') {
      const v = value();
      const m = /^(0x[0-9a-fA-F]+|\d+)=(\d+)$/.exec(v);
      const addr = m ? Number(m[1]) : -1;
      if (!m || addr > 0x7f || Number(m[2]) > 100000) fail(`--clock-stretch ${v}: expected ADDR=US`);
      own.stretchUs.set(addr, Number(m[2]));
    } else if (!a.startsWith('-') && !own.image && !(i > 0 && takesValue(argv[i - 1]))) {
      own.image = a;
    } else {
      common.push(a);
    }
  }
  if (!own.image) fail(`no image given\nusage: ${NAME} --rig RIG.toml --motion DATA.csv [common options]\n${USAGE}`);
  return { own, common };
}

/** Common options with a value (their value is not the image). */
function takesValue(flag) {
  return ['--rig', '--motion', '--eeprom', '--link', '--baud', '--corrupt-every', '--drop-every',
    '--disconnect-after', '--reconnect-after', '--fault'].includes(flag);
}

function loadFile(path, what) {
  try {
    return readFileSync(path);
  } catch (e) {
    return fail(`cannot read ${what} ${path} (${e.code ?? e.message}); scripts/setup.sh and the `
      + 'native build (cmake --build build/native) make it');
  }
}

async function main() {
  const { own, common } = parseOwnArgs(process.argv.slice(2));
  loadFile(own.boardLib, 'the board library');
  let board;
  let dev;
  try {
    board = bindSimBoard(own.boardLib);
    dev = bindSimDevices(own.boardLib);
  } catch (e) {
    fail(`${e.message}`);
  }
  const handle = board.open(common.length + 1, [NAME, ...common], USAGE);
  if (!handle) process.exit(2); // the library said what is wrong
  const sim = board.sim(handle);
  const bootrom = loadFile(own.bootrom, 'the bootrom');

  const flash = new Uint8Array(FLASH_BYTES).fill(0xff);
  try {
    placeInFlash(readElf(own.image), flash, FLASH_BASE, own.image);
  } catch (e) {
    if (e instanceof ElfError || e.code) fail(e.message);
    throw e;
  }
  const settings = new Uint8Array(SECTOR_BYTES);
  if (board.settingsOpen(handle, settings, SECTOR_BYTES, own.userImage ? SETTINGS_ERASED : 0) < 0) {
    fail(board.lastError(handle));
  }
  flash.set(settings, SETTINGS_OFFSET);

  let uartLog = -1;
  if (own.uartLog) {
    try { uartLog = openSync(own.uartLog, 'w'); } catch (e) { fail(`cannot open --uart-log ${own.uartLog}: ${e.code}`); }
  }
  const logged = [];
  let txBytes = 0;
  let lastTxNs = -Infinity;
  const machine = new Machine({
    bootrom, flash, devices: { sim, api: dev }, stretchUs: own.stretchUs,
    lineBaud: board.baud(handle),
    onWire: (byte) => {
      txBytes++;
      lastTxNs = machine.deviceNs();
      if (uartLog >= 0) logged.push(byte);
      board.linePut(handle, byte, lastTxNs);
    },
    onFlashWrite: (offset, length) => {
      if (offset + length > SETTINGS_OFFSET && offset < FLASH_BYTES) {
        if (board.settingsWrite(handle, flash.subarray(SETTINGS_OFFSET), SECTOR_BYTES) < 0) {
          process.stderr.write(`${NAME}: ${board.lastError(handle)}\n`);
        }
      }
    },
  });

  machine.paintStack();
  let stop = false;
  let measure = false;
  process.on('SIGTERM', () => { stop = true; });
  process.on('SIGINT', () => { stop = true; });
  process.on('SIGUSR1', () => { measure = true; });
  process.on('SIGHUP', () => {});

  board.applyFaults(handle, 0);
  if (own.pty) {
    if (board.lineOpen(handle) < 0) fail(board.lastError(handle), 1);
  } else {
    process.stdout.write('NOPTY\n');
  }

  const fast = board.fast(handle) === 1;
  const stopAt = own.seconds >= 0 ? own.seconds * 1e9 : Infinity;
  let endAt = stopAt;
  const window = { open: own.measureFromS === 0, closed: false, startNs: 0, endNs: Infinity,
    sleep0: 0, busy0: 0, bus0: null, result: null };
  const openWindow = () => {
    window.open = true;
    window.startNs = machine.deviceNs();
    window.sleep0 = machine.sleepNs;
    window.busy0 = machine.busyCycles;
    window.bus0 = busCounters();
    if (own.measureSeconds >= 0) window.endNs = window.startNs + own.measureSeconds * 1e9;
  };
  const busCounters = () => {
    const c = {};
    dev.busCounters(sim, c, dev.busCountersSize);
    return { ...c, bus_ns: machine.busStats.busyNs };
  };
  const closeWindow = () => {
    window.closed = true;
    const ns = machine.deviceNs() - window.startNs;
    window.result = { startNs: window.startNs, ns, sleepNs: machine.sleepNs - window.sleep0,
      busyCycles: machine.busyCycles - window.busy0, bus0: window.bus0, bus1: busCounters() };
  };
  if (window.open) openWindow();

  let wallStart = process.hrtime.bigint();
  let ranFast = false;
  let exitCode = 0;
  let slices = 0;
  let warnedBaud = false;
  const take = new Uint8Array(64);
  try {
    while (!stop) {
      machine.run(SLICE_NS);
      const t = machine.deviceNs();
      if (!warnedBaud && machine.uart.lineBaud && machine.uart.baud
          && Math.abs(machine.uart.baud / machine.uart.lineBaud - 1) > 0.03) {
        warnedBaud = true;
        process.stderr.write(`${NAME}: the image set UART0 to ${Math.round(machine.uart.baud)} baud; `
          + `the line runs at --baud ${machine.uart.lineBaud}\n`);
      }
      if (uartLog >= 0 && logged.length) { writeSync(uartLog, Uint8Array.from(logged)); logged.length = 0; }
      if (machine.uart.rxWaiting.length < 16) {
        const n = board.lineTake(handle, take, 16);
        for (let i = 0; i < n; i++) machine.feed(take[i]);
      }
      board.lineFlush(handle);
      board.applyFaults(handle, t);
      const line = board.lineService(handle, t);
      if (line < 0) { exitCode = 1; break; }
      if (line === LINE_PULLED) wallStart = process.hrtime.bigint() - BigInt(Math.round(t));
      if ((!window.open && t >= own.measureFromS * 1e9) || measure) { measure = false; openWindow(); }
      if (window.open && !window.closed && t >= window.endNs) {
        closeWindow();
        endAt = Math.min(endAt, t + DRAIN_TAIL_NS);
      }
      if (t >= endAt) break;
      if (++slices % 64 === 0) await new Promise((r) => setImmediate(r)); // signals
      const runFast = fast && t - lastTxNs < FAST_STREAM_NS;
      if (runFast !== ranFast) {
        ranFast = runFast;
        if (!runFast) wallStart = process.hrtime.bigint() - BigInt(Math.round(t));
      }
      if (runFast) {
        while (board.lineWaiting(handle) >= WIRE_MAX && board.lineConnected(handle) && !stop) {
          board.lineWait(handle, 20e6);
          board.lineFlush(handle);
          await new Promise((r) => setImmediate(r));
        }
        continue;
      }
      const wall = Number(process.hrtime.bigint() - wallStart);
      if (wall > t + 1e9) wallStart = process.hrtime.bigint() - BigInt(Math.round(t));
      else if (t > wall) board.lineWait(handle, Math.round(t - wall));
    }
  } catch (e) {
    if (e instanceof HaltError || e instanceof BootError) {
      process.stderr.write(`${NAME}: ${e.message}\n`);
      exitCode = 1;
    } else {
      throw e;
    }
  }
  board.lineFlush(handle);
  if (uartLog >= 0) { if (logged.length) writeSync(uartLog, Uint8Array.from(logged)); closeSync(uartLog); }
  if (!window.closed && window.open) closeWindow();
  const counters = {};
  board.lineCounters(handle, counters, board.lineCountersSize);
  const simS = machine.deviceNs() / 1e9;
  process.stderr.write(`${NAME}: ${simS.toFixed(3)} s simulated, ${machine.resets} resets, `
    + `${txBytes} bytes sent, ${counters.rx_bytes} received, injected: ${counters.dropped} dropped `
    + `${counters.corrupted} corrupted, bridge dropped ${counters.bridge_dropped}, flash sectors `
    + `erased ${machine.flashModel.erases}\n`);
  if (own.report) {
    try {
      writeFileSync(own.report, JSON.stringify(report(machine, window.result, counters, own)) + '\n');
    } catch (e) {
      process.stderr.write(`${NAME}: cannot write the report ${own.report}: ${e.code ?? e.message}\n`);
      exitCode = 1;
    }
  }
  board.close(handle);
  process.exit(exitCode);
}

/** The measurement window's accounting (firmware/sim/pico_board/README.md, "Report"). */
function report(machine, w, line, own) {
  const clk = machine.chip.clkSys;
  const seconds = w ? w.ns / 1e9 : 0;
  const diff = (k) => (w ? Number(w.bus1[k]) - Number(w.bus0[k]) : 0);
  const busNs = diff('bus_ns');
  const sclNs = machine.i2c.sclPeriodNs();
  return {
    elf: own.image,
    frequency_hz: clk,
    window_start_s: w ? w.startNs / 1e9 : 0,
    seconds,
    cycles: Math.round(seconds * clk),
    busy_cycles: w ? w.busyCycles : 0,
    sleep_cycles: w ? Math.round((w.sleepNs * clk) / 1e9) : 0,
    idle_fraction: w && w.ns ? w.sleepNs / w.ns : 0,
    resets: machine.resets,
    stack_peak_bytes: machine.stackPeakBytes(),
    uart: { baud: machine.uart.lineBaud || machine.uart.baud, tx_bytes: Number(line.tx_bytes),
      rx_bytes: Number(line.rx_bytes), bridge_dropped: Number(line.bridge_dropped),
      injected_dropped: Number(line.dropped), injected_corrupted: Number(line.corrupted) },
    bus: { scl_bits: Math.round(busNs / sclNs), starts: diff('starts') + diff('repeated_starts'),
      bytes: diff('bytes_written') + diff('bytes_read'),
      nacks: diff('address_nacks') + diff('data_nacks'),
      real_scl_hz: 1e9 / sclNs, busy_s: busNs / 1e9, occupancy: seconds ? busNs / 1e9 / seconds : 0 },
    flash: { sector_erases: machine.flashModel.erases, page_programs: machine.flashModel.programs },
  };
}

main().catch((e) => fail(e.stack ?? String(e), 1));
