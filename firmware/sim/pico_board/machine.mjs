// One emulated Pico: rp2040js's RP2040 with our bootrom, the image and the settings sector in its
// flash, UART0 replaced by the paced PL011 (uart.mjs), I2C0 on the virtual devices
// (i2c_bridge.mjs), the bootrom's flash functions modelled (flash.mjs). A watchdog reset starts a
// new chip with the same flash and SRAM contents, the watchdog's REASON and scratch registers
// (they survive it on the RP2040), while the devices, the line and device time go on (time base
// + the new clock).
import { RP2040 } from 'rp2040js';

import { FLASH_BYTES, FlashModel } from './flash.mjs';
import { I2cBridge } from './i2c_bridge.mjs';
import { PacedUart } from './uart.mjs';

// The image's stack is SCRATCH_Y (memmap.ld); the bootrom copies boot2 to its top 256 bytes.
const STACK_LOW = 0x20041000;
const STACK_TOP = 0x20042000;
const STACK_PAINT_END = 0x20041f00;
const STACK_PAINT = 0xa5;
const UART0_BASE_KEY = 0x40034; // rp2040js's peripheral table key (address >>> 14 << 2)
const UART0_IRQ = 20;

export class HaltError extends Error {}

export class Machine {
  /**
   * bootrom: Uint8Array; flash: Uint8Array(FLASH_BYTES) (kept: the machine writes into it);
   * devices: {sim, api} or null (no I2C0 devices); stretchUs: Map; onWire(byte);
   * onFlashWrite(offset, length); onBreak(code, chip): true when it answered a breakpoint the
   * bootrom model does not know (the cycle harness's markers).
   */
  constructor({ bootrom, flash, devices = null, stretchUs = new Map(), onWire = () => {},
    onFlashWrite = () => {}, lineBaud = 0, onBreak = () => false }) {
    this.bootromWords = new Uint32Array(bootrom.buffer.slice(bootrom.byteOffset,
      bootrom.byteOffset + (bootrom.length & ~3)));
    this.flash = flash;
    this.devices = devices;
    this.stretchUs = stretchUs;
    this.onWire = onWire;
    this.lineBaud = lineBaud;
    this.onBreak = onBreak;
    this.flashModel = new FlashModel((offset, length) => {
      this.flash.set(this.chip.flash.subarray(offset, offset + length), offset);
      onFlashWrite(offset, length);
    });
    this.timeBaseNs = 0;
    this.resets = 0;
    this.sleepNs = 0; // time with the core in WFI/WFE
    this.busyCycles = 0;
    this.busStats = { busyNs: 0 };
    this.boot(0, null);
  }

  boot(reason, scratch) {
    const chip = new RP2040();
    chip.logger = { debug() {}, info() {}, warn() {}, error: (tag, msg) => process.stderr.write(`pico: ${tag}: ${msg}\n`) };
    chip.loadBootrom(this.bootromWords);
    chip.flash.set(this.flash.subarray(0, FLASH_BYTES));
    const uart = new PacedUart(chip, 'UART0', UART0_IRQ, (b) => this.onWire(b));
    uart.lineBaud = this.lineBaud;
    chip.uart[0] = uart;
    chip.peripherals[UART0_BASE_KEY] = uart;
    if (this.devices) {
      this.i2c = new I2cBridge(chip.i2c[0], this.devices.sim, this.devices.api,
        () => this.deviceNs(), this.stretchUs, this.busStats);
    }
    chip.onBreak = (code) => {
      if (this.flashModel.handle(chip, code) || this.onBreak(code, chip)) return;
      throw new HaltError(`the image stopped at a breakpoint (bkpt/udf #${code}) at pc 0x`
        + `${((chip.core.PC - chip.core.breakRewind) >>> 0).toString(16)}`);
    };
    // XIP is back once the SSI is enabled again (boot2's last step, or flash_enter_cmd_xip).
    const ssi = chip.peripherals[0x18000];
    const ssiWrite = ssi.writeUint32.bind(ssi);
    ssi.writeUint32 = (offset, value) => {
      if (offset === 0x08 && value & 1) this.flashModel.xip = true; // SSIENR
      ssiWrite(offset, value);
    };
    const wd = chip.peripherals[0x40058];
    wd.reason = reason;
    if (scratch) wd.scratchData.set(scratch);
    wd.onWatchdogTrigger = () => { this.resetPending = true; };
    this.watchdog = wd;
    this.chip = chip;
    this.uart = uart;
    this.resetPending = false;
    chip.core.reset();
  }

  /** Fills the stack's RAM below boot2's copy with a pattern (before the image runs). */
  paintStack() {
    this.chip.sram.fill(STACK_PAINT, STACK_LOW - 0x20000000, STACK_PAINT_END - 0x20000000);
  }

  /** The deepest the stack reached since paintStack (bytes below its top), resets included. */
  stackPeakBytes() {
    let low = STACK_LOW;
    while (low < STACK_PAINT_END && this.chip.sram[low - 0x20000000] === STACK_PAINT) low++;
    return STACK_TOP - low;
  }

  deviceNs() { return this.timeBaseNs + this.chip.clock.nanos; }

  /** Runs the chip for `ns` of device time (interrupts, alarms and resets included). */
  run(ns) {
    const end = this.deviceNs() + ns;
    while (this.deviceNs() < end) {
      const chip = this.chip;
      const { core, clock } = chip;
      const until = end - this.timeBaseNs;
      const nsPerCycle = 1e9 / chip.clkSys;
      let cycles = 0;
      // The hot loop (most of the harness's time): the clock's counter is advanced in place and
      // SimulationClock.tick called only when an alarm falls due (what tick would do anyway).
      while (clock.nanosCounter < until && !this.resetPending) {
        if (core.waiting) {
          const toAlarm = clock.nanosToNextAlarm;
          const left = until - clock.nanosCounter;
          const dt = toAlarm > 0 ? Math.min(toAlarm, left) : left;
          clock.tick(dt);
          this.sleepNs += dt;
        } else {
          const c = core.executeInstruction();
          cycles += c;
          const dt = c * nsPerCycle;
          const alarm = clock.nextAlarm;
          if (alarm !== null && alarm.nanos <= clock.nanosCounter + dt) clock.tick(dt);
          else clock.nanosCounter += dt;
        }
      }
      this.busyCycles += cycles;
      if (this.resetPending) this.watchdogReset();
    }
  }

  watchdogReset() {
    const { reason, scratchData } = this.watchdog;
    this.timeBaseNs += this.chip.clock.nanos;
    this.resets++;
    const waiting = this.uart.rxWaiting.slice();
    const sram = this.chip.sram;
    this.boot(reason, scratchData.slice());
    this.chip.sram.set(sram); // a watchdog reset leaves the SRAM's contents as they were
    for (const b of waiting) this.uart.feed(b);
  }

  /** A byte from the host on UART0's RX line. */
  feed(byte) { this.uart.feed(byte); }
}
