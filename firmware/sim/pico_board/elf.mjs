// The image's bytes as the flash holds them: an ELF32 (little-endian, ARM) read by its program
// headers, every PT_LOAD segment at its physical (load) address. Symbols from .symtab for the
// harness's reports (e.g. the stack's lowest address).
import { readFileSync } from 'node:fs';

const PT_LOAD = 1;
const SHT_SYMTAB = 2;

export class ElfError extends Error {}

/** Reads `path`; returns {segments: [{paddr, bytes}], symbols: Map(name -> value), entry}. */
export function readElf(path) {
  const buf = readFileSync(path);
  if (buf.length < 52 || buf.readUInt32BE(0) !== 0x7f454c46) {
    throw new ElfError(`${path}: not an ELF file`);
  }
  if (buf[4] !== 1 || buf[5] !== 1 || buf.readUInt16LE(18) !== 40) {
    throw new ElfError(`${path}: not a 32-bit little-endian ARM ELF (the RP2040 image)`);
  }
  const phoff = buf.readUInt32LE(28);
  const shoff = buf.readUInt32LE(32);
  const phentsize = buf.readUInt16LE(42);
  const phnum = buf.readUInt16LE(44);
  const shentsize = buf.readUInt16LE(46);
  const shnum = buf.readUInt16LE(48);
  const segments = [];
  for (let i = 0; i < phnum; i++) {
    const at = phoff + i * phentsize;
    if (buf.readUInt32LE(at) !== PT_LOAD) continue;
    const offset = buf.readUInt32LE(at + 4);
    const paddr = buf.readUInt32LE(at + 12);
    const filesz = buf.readUInt32LE(at + 16);
    if (filesz === 0) continue;
    if (offset + filesz > buf.length) throw new ElfError(`${path}: segment ${i} past the file's end`);
    segments.push({ paddr, bytes: buf.subarray(offset, offset + filesz) });
  }
  const symbols = new Map();
  for (let i = 0; i < shnum; i++) {
    const at = shoff + i * shentsize;
    if (buf.readUInt32LE(at + 4) !== SHT_SYMTAB) continue;
    const symOff = buf.readUInt32LE(at + 16);
    const symSize = buf.readUInt32LE(at + 20);
    const strAt = shoff + buf.readUInt32LE(at + 24) * shentsize;
    const strOff = buf.readUInt32LE(strAt + 16);
    for (let s = symOff; s + 16 <= symOff + symSize; s += 16) {
      const nameOff = buf.readUInt32LE(s);
      if (!nameOff) continue;
      const end = buf.indexOf(0, strOff + nameOff);
      symbols.set(buf.toString('latin1', strOff + nameOff, end), buf.readUInt32LE(s + 4));
    }
  }
  return { segments, symbols, entry: buf.readUInt32LE(24) };
}

/** Copies the segments that lie in flash (base .. base + flash.length) into `flash`. */
export function placeInFlash(elf, flash, base, path) {
  let placed = 0;
  for (const { paddr, bytes } of elf.segments) {
    if (paddr < base || paddr + bytes.length > base + flash.length) {
      throw new ElfError(
        `${path}: a segment at 0x${paddr.toString(16)} (${bytes.length} bytes) is outside the flash`);
    }
    flash.set(bytes, paddr - base);
    placed += bytes.length;
  }
  if (!placed) throw new ElfError(`${path}: nothing to load into the flash`);
  return placed;
}
