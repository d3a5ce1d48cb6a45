"""UF2 images for the RP2040 (Raspberry Pi Pico): from an ARM ELF, and back to flash contents.

UF2 (Microsoft's USB Flashing Format, https://microsoft.github.io/uf2/) is a sequence of
self-contained 512-byte blocks, every field a little-endian uint32:

    offset  0  magicStart0  0x0A324655 ("UF2\\n")
    offset  4  magicStart1  0x9E5D5157
    offset  8  flags        0x00002000: familyID present (the only flag written here)
    offset 12  targetAddr   where the payload goes in flash
    offset 16  payloadSize  256 for the RP2040 (its bootrom writes 256-byte pages)
    offset 20  blockNo      0, 1, ... in file order
    offset 24  numBlocks    the number of blocks in the file
    offset 28  familyID     0xE48BFF56 for the RP2040 (the bootrom ignores other families)
    offset 32  data[476]    the payload, then zeros
    offset 508 magicEnd     0x0AB16F30

`elf_to_uf2` takes the loadable bytes of each PT_LOAD segment at its physical (load) address,
which for an XIP image lies in the RP2040's flash window 0x10000000..0x11000000 even where the
section runs from RAM (.data is copied out of flash at start-up). A 256-byte page the image
covers only in part is filled with 0x00: what the Pico SDK's elf2uf2 and picotool write, so an
image converted here is byte-for-byte the SDK's (the bootrom erases the 4 KB sector and
programs the whole page either way, so the filler is only ever gap bytes no code reads).
`uf2_to_flash` decodes and checks every block and returns the flash contents as contiguous
ranges; each refusal names the block.
"""

from __future__ import annotations

import io
import struct
import sys
from collections.abc import Mapping
from pathlib import Path

from elftools.common.exceptions import ELFError
from elftools.construct import ConstructError
from elftools.elf.elffile import ELFFile

from jointangle.errors import InputError

BLOCK_SIZE = 512
PAGE_SIZE = 256  # the RP2040 bootrom's payload size and flash page
DATA_AREA = 476
MAGIC_START0 = 0x0A324655
MAGIC_START1 = 0x9E5D5157
MAGIC_END = 0x0AB16F30
FLAG_NOT_MAIN_FLASH = 0x00000001
FLAG_FILE_CONTAINER = 0x00001000
FLAG_FAMILY_ID_PRESENT = 0x00002000
RP2040_FAMILY_ID = 0xE48BFF56
FLASH_START = 0x10000000  # the RP2040's XIP flash window, 16 MB
FLASH_END = 0x11000000
PAD_BYTE = 0x00

_HEADER = struct.Struct("<8I")
_END = struct.Struct("<I")
ELF_MAGIC = b"\x7fELF"


def is_uf2(data: bytes) -> bool:
    """Whether `data` starts like a UF2 file (its first block's two start magics)."""
    return len(data) >= 8 and struct.unpack_from("<2I", data) == (MAGIC_START0, MAGIC_START1)


def _flash_window() -> str:
    return f"0x{FLASH_START:08X}..0x{FLASH_END:08X}"


def elf_segments(elf_bytes: bytes, *, source: str | Path | None = None) -> dict[int, bytes]:
    """The ELF's loadable bytes, {load address: bytes}, one entry per PT_LOAD segment with
    bytes in the file (a .bss segment has none). Refuses (InputError) anything that is not a
    32-bit little-endian ARM ELF, a segment outside the RP2040's flash, overlapping segments
    and an image with no loadable bytes."""
    if not elf_bytes.startswith(ELF_MAGIC):
        raise InputError("not an ELF file (it does not start with 0x7F 'ELF')", path=source)
    try:
        elf = ELFFile(io.BytesIO(elf_bytes))
        machine = elf["e_machine"]
        if elf.elfclass != 32 or not elf.little_endian or machine != "EM_ARM":
            endian = "little-endian" if elf.little_endian else "big-endian"
            raise InputError(f"not a 32-bit little-endian ARM ELF ({elf.elfclass}-bit, {endian},"
                             f" {machine}): the RP2040 runs Cortex-M0+ code", path=source)
        segments: dict[int, bytes] = {}
        for index, seg in enumerate(elf.iter_segments()):
            if seg["p_type"] != "PT_LOAD" or seg["p_filesz"] == 0:
                continue
            start, size = int(seg["p_paddr"]), int(seg["p_filesz"])
            if start < FLASH_START or start + size > FLASH_END:
                raise InputError(
                    f"segment {index} (PT_LOAD, {size} bytes at load address 0x{start:08X}) "
                    f"is outside the RP2040's flash {_flash_window()}: only images that run "
                    f"from flash can be written as UF2 here", path=source)
            data = seg.data()
            if len(data) != size:
                raise InputError(f"segment {index} is cut short ({len(data)} of {size} bytes): "
                                 f"a truncated ELF", path=source)
            segments[start] = data
    except (ELFError, ConstructError, struct.error, ValueError) as exc:
        raise InputError(f"not a readable ELF file ({exc})", path=source) from None
    if not segments:
        raise InputError("the ELF has no loadable bytes (no PT_LOAD segment with file "
                         "contents): an empty image", path=source)
    previous_end, previous = 0, 0
    for start in sorted(segments):
        if start < previous_end:
            raise InputError(f"segments at 0x{previous:08X} and 0x{start:08X} overlap",
                             path=source)
        previous_end, previous = start + len(segments[start]), start
    return segments


def pages_of(segments: Mapping[int, bytes]) -> dict[int, bytes]:
    """{page address: 256 bytes}: the segments cut into 256-byte aligned pages, a page they
    cover in part filled with PAD_BYTE. The segments must not overlap."""
    pages: dict[int, bytearray] = {}
    for start, data in segments.items():
        end = start + len(data)
        for page in range(start - start % PAGE_SIZE, end, PAGE_SIZE):
            buf = pages.setdefault(page, bytearray([PAD_BYTE]) * PAGE_SIZE)
            lo, hi = max(start, page), min(end, page + PAGE_SIZE)
            buf[lo - page:hi - page] = data[lo - start:hi - start]
    return {page: bytes(pages[page]) for page in sorted(pages)}


def encode_uf2(pages: Mapping[int, bytes], family_id: int = RP2040_FAMILY_ID) -> bytes:
    """UF2 blocks of 256-byte pages, in address order, familyID present."""
    out = bytearray()
    for block_no, address in enumerate(sorted(pages)):
        payload = pages[address]
        out += _HEADER.pack(MAGIC_START0, MAGIC_START1, FLAG_FAMILY_ID_PRESENT, address,
                            len(payload), block_no, len(pages), family_id)
        out += payload.ljust(DATA_AREA, b"\x00")
        out += _END.pack(MAGIC_END)
    return bytes(out)


def elf_to_uf2(elf_bytes: bytes, *, source: str | Path | None = None) -> bytes:
    """The UF2 image of an RP2040 ELF: its PT_LOAD segments at their load addresses in flash,
    in 256-byte pages (partial pages filled with 0x00). `source` names the file in errors."""
    return encode_uf2(pages_of(elf_segments(elf_bytes, source=source)))


def _check_block(block: bytes, block_no: int, num_blocks: int) -> tuple[int, bytes]:
    """(target address, payload) of one block; InputError naming the block otherwise."""
    m0, m1, flags, address, size, number, total, family = _HEADER.unpack_from(block)
    (m_end,) = _END.unpack_from(block, BLOCK_SIZE - _END.size)
    where = f"block {block_no} (bytes {block_no * BLOCK_SIZE}..{(block_no + 1) * BLOCK_SIZE})"

    def refuse(reason: str) -> InputError:
        return InputError(f"{where}: {reason}")

    if (m0, m1) != (MAGIC_START0, MAGIC_START1):
        raise refuse(f"start magic 0x{m0:08X} 0x{m1:08X}, expected 0x{MAGIC_START0:08X} "
                     f"0x{MAGIC_START1:08X}: not a UF2 block")
    if m_end != MAGIC_END:
        raise refuse(f"end magic 0x{m_end:08X}, expected 0x{MAGIC_END:08X}: not a UF2 block")
    if not flags & FLAG_FAMILY_ID_PRESENT:
        raise refuse(f"flags 0x{flags:08X} lack 0x{FLAG_FAMILY_ID_PRESENT:08X} (familyID "
                     f"present): the RP2040 needs its family ID")
    if flags & (FLAG_NOT_MAIN_FLASH | FLAG_FILE_CONTAINER):
        raise refuse(f"flags 0x{flags:08X} mark it not main flash (0x1) or a file container "
                     f"(0x1000): not a flash image block")
    if family != RP2040_FAMILY_ID:
        raise refuse(f"family ID 0x{family:08X}, not the RP2040's 0x{RP2040_FAMILY_ID:08X}")
    if size != PAGE_SIZE:
        raise refuse(f"payload size {size}, the RP2040 takes {PAGE_SIZE}")
    if address % PAGE_SIZE or not FLASH_START <= address <= FLASH_END - PAGE_SIZE:
        raise refuse(f"target address 0x{address:08X} is not a {PAGE_SIZE}-byte page in the "
                     f"flash {_flash_window()}")
    if number != block_no:
        raise refuse(f"blockNo is {number}, expected {block_no} (blocks out of order)")
    if total != num_blocks:
        raise refuse(f"numBlocks is {total}, but the file holds {num_blocks} blocks")
    return address, block[_HEADER.size:_HEADER.size + size]


def uf2_to_flash(uf2_bytes: bytes, *, source: str | Path | None = None) -> dict[int, bytes]:
    """The flash contents a UF2 image writes, {start address: bytes} of contiguous ranges.

    Every block is checked (magics, flags, RP2040 family, payload size, page address in flash,
    blockNo and numBlocks); a refusal is an InputError naming the block (and `source`)."""
    if not uf2_bytes or len(uf2_bytes) % BLOCK_SIZE:
        raise InputError(f"{len(uf2_bytes)} bytes is not a whole number of {BLOCK_SIZE}-byte "
                         f"UF2 blocks", path=source)
    num_blocks = len(uf2_bytes) // BLOCK_SIZE
    pages: dict[int, bytes] = {}
    for block_no in range(num_blocks):
        block = uf2_bytes[block_no * BLOCK_SIZE:(block_no + 1) * BLOCK_SIZE]
        try:
            address, payload = _check_block(block, block_no, num_blocks)
        except InputError as exc:
            raise InputError(exc.reason, path=source) from None
        if address in pages:
            raise InputError(f"block {block_no}: target address 0x{address:08X} is written by "
                             f"an earlier block too", path=source)
        pages[address] = payload
    ranges: dict[int, bytearray] = {}
    start = end = -1
    for address in sorted(pages):
        if address != end:
            start = address
            ranges[start] = bytearray()
        ranges[start] += pages[address]
        end = address + PAGE_SIZE
    return {s: bytes(data) for s, data in ranges.items()}


def main(argv: list[str] | None = None) -> int:
    """`python -m jointangle.flash.uf2 IMAGE.elf OUT.uf2`: the Pico build's UF2 step."""
    import argparse

    p = argparse.ArgumentParser(prog="python -m jointangle.flash.uf2",
                                description="Convert an RP2040 ELF image to UF2 (the file a "
                                "Pico's RPI-RP2 drive takes): its loadable flash bytes in "
                                "256-byte pages, family ID RP2040.")
    p.add_argument("elf", type=Path, help="the linked image (ELF, flash at 0x10000000)")
    p.add_argument("out", type=Path, help="the UF2 file to write")
    args = p.parse_args(argv)
    try:
        uf2 = elf_to_uf2(args.elf.read_bytes(), source=args.elf)
    except (OSError, InputError) as exc:
        sys.stderr.write(f"uf2: {exc}\n")
        return 2
    args.out.write_bytes(uf2)
    sys.stdout.write(f"uf2: {args.out}: {len(uf2) // BLOCK_SIZE} blocks of {PAGE_SIZE} bytes\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
