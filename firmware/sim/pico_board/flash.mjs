// The board's model of what bootrom.S leaves to breakpoints: the boot2 check the real bootrom
// makes, and the bootrom's flash functions (RP2040 datasheet 2.8.3.1.3) on the QSPI flash
// (a W25Q16JV: 2 MB, 4 KB sectors, 256-byte pages; erasing sets bytes to 0xFF, programming can
// only clear bits). Each function takes the flash's typical time (W25Q16JV datasheet: sector
// erase tSE 45 ms, page program tPP 0.4 ms), charged to the CPU, which waits in the bootrom.
// Rules the real chip enforces by crashing are errors here, named with the caller's address:
// erase/program out of range or misaligned, and a caller that runs from flash while XIP is off.

export const FLASH_BASE = 0x10000000;
export const FLASH_BYTES = 2 * 1024 * 1024;
export const SECTOR_BYTES = 4096;
const PAGE_BYTES = 256;
const BOOT2_SRAM = 0x20041f00;
const ERASE_NS_PER_SECTOR = 45e6;
const PROGRAM_NS_PER_PAGE = 0.4e6;

export class BootError extends Error {}

/** CRC-32/MPEG-2 (poly 0x04C11DB7, init 0xFFFFFFFF, not reflected, no final XOR): boot2's. */
export function crc32Mpeg2(bytes) {
  let crc = 0xffffffff;
  for (const b of bytes) {
    crc ^= b << 24;
    for (let i = 0; i < 8; i++) crc = crc & 0x80000000 ? (crc << 1) ^ 0x04c11db7 : crc << 1;
  }
  return crc >>> 0;
}

export class FlashModel {
  /** `onWrite(offset, length)` after an erase or program changed the flash. */
  constructor(onWrite) {
    this.onWrite = onWrite;
    this.xip = true;
    this.erases = 0;
    this.programs = 0;
  }

  /** rp2040.onBreak for the bootrom's breakpoints; false: not one of ours. */
  handle(rp2040, code) {
    const core = rp2040.core;
    const r = core.registers;
    const caller = (core.LR & ~1) >>> 0;
    const where = `(called from 0x${caller.toString(16)})`;
    const inFlash = caller >= FLASH_BASE && caller < 0x14000000;
    switch (code) {
      case 0x01: { // boot2's CRC, as the bootrom checks it before running it
        const boot2 = rp2040.sram.subarray(BOOT2_SRAM - 0x20000000, BOOT2_SRAM - 0x20000000 + 256);
        const want = boot2[252] | (boot2[253] << 8) | (boot2[254] << 16) | (boot2[255] << 24);
        const got = crc32Mpeg2(boot2.subarray(0, 252));
        if (want >>> 0 !== got) {
          throw new BootError(`boot2's CRC-32 is 0x${got.toString(16)}, its last word says `
            + `0x${(want >>> 0).toString(16)}: the bootrom would not run it (a real Pico shows its USB drive)`);
        }
        return true;
      }
      case 0x02:
        throw new BootError(`a fault in the bootrom before the image took over (pc 0x${core.PC.toString(16)})`);
      case 0x10: return true; // connect_internal_flash
      case 0x11: this.xip = false; this.checkCaller(inFlash, 'flash_exit_xip', where); return true;
      case 0x12: { // flash_range_erase(addr, count, block_size, block_cmd)
        this.checkCaller(inFlash, 'flash_range_erase', where);
        const [addr, count] = [r[0] >>> 0, r[1] >>> 0];
        this.checkRange('flash_range_erase', addr, count, SECTOR_BYTES, where);
        rp2040.flash.fill(0xff, addr, addr + count);
        this.erases += count / SECTOR_BYTES;
        this.charge(rp2040, (count / SECTOR_BYTES) * ERASE_NS_PER_SECTOR);
        this.onWrite(addr, count);
        return true;
      }
      case 0x13: { // flash_range_program(addr, data, count)
        this.checkCaller(inFlash, 'flash_range_program', where);
        const [addr, data, count] = [r[0] >>> 0, r[1] >>> 0, r[2] >>> 0];
        this.checkRange('flash_range_program', addr, count, PAGE_BYTES, where);
        for (let i = 0; i < count; i++) rp2040.flash[addr + i] &= rp2040.readUint8(data + i);
        this.programs += count / PAGE_BYTES;
        this.charge(rp2040, (count / PAGE_BYTES) * PROGRAM_NS_PER_PAGE);
        this.onWrite(addr, count);
        return true;
      }
      case 0x14: return true; // flash_flush_cache
      case 0x15: this.xip = true; return true; // flash_enter_cmd_xip
      default: return false;
    }
  }

  checkCaller(inFlash, name, where) {
    if (inFlash && !this.xip) {
      throw new BootError(`${name} ${where}: the caller runs from flash while XIP is off; `
        + 'the real chip would fetch garbage (run it from RAM)');
    }
  }

  checkRange(name, addr, count, unit, where) {
    if (addr % unit || count % unit || addr + count > FLASH_BYTES) {
      throw new BootError(`${name}(0x${addr.toString(16)}, ${count}) ${where}: the flash takes `
        + `whole ${unit}-byte blocks within its ${FLASH_BYTES} bytes`);
    }
  }

  /** The CPU waits in the bootrom while the flash works. */
  charge(rp2040, ns) {
    rp2040.core.cycles += Math.round((ns * rp2040.clkSys) / 1e9);
    rp2040.clock.tick(ns);
  }
}
