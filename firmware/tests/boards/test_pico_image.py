"""ctests firmware.pico_image_*: the Raspberry Pi Pico (RP2040) image as the bootrom sees it.

  boot2    the first 256 bytes of jointangle_pico.bin: bytes 252..255 (little-endian) are the
           CRC-32 the bootrom checks over bytes 0..251 (polynomial 0x04C11DB7, init 0xFFFFFFFF,
           unreflected, no final XOR: CRC-32/MPEG-2). Computed here from zlib's reflected CRC-32
           on bit-reversed bytes, not with the build's firmware/tools/pico_boot2.py; the check
           itself must reject the image with any one of those bytes changed.
  vectors  the vector table at 0x10000100 (.bin offset 0x100, the ELF's .vectors): initial SP
           8-byte aligned in SRAM (0x20000000 < SP <= 0x20042000); the reset vector and every
           handler odd (Thumb) and inside the image in flash; the reserved entries zero.
  size     the image within the Pico's flash (2 MB) and the RAM (256 KB striped; the stack in
           SCRATCH_Y), the ELF's allocated sections where memmap.ld puts them; prints the use.
  uf2      jointangle_pico.uf2 (made by the build with host/jointangle/flash/uf2.py), decoded
           here on its own (the UF2 specification's 512-byte blocks: both start magics, the end
           magic, flags with familyID present, the RP2040's family 0xE48BFF56, 256-byte payloads,
           blockNo 0..numBlocks-1 in order): its pages, contiguous from 0x10000000, are exactly
           jointangle_pico.bin padded with zeros to a whole page.
  tool     firmware/tools/pico_boot2.py pads 252 bytes of code (with a CRC this file's
           implementation agrees with) and refuses 253 without writing its output.

usage: test_pico_image.py boot2|vectors|size PATH/TO/jointangle_pico.elf PATH/TO/jointangle_pico.bin
       test_pico_image.py uf2 PATH/TO/jointangle_pico.elf PATH/TO/jointangle_pico.bin PATH/TO/.uf2
       test_pico_image.py tool PATH/TO/firmware/tools/pico_boot2.py
"""

from __future__ import annotations

import struct
import subprocess
import sys
import tempfile
import zlib
from pathlib import Path
from typing import NamedTuple

FLASH_BASE, FLASH_SIZE = 0x10000000, 2 * 1024 * 1024  # the Pico's W25Q16
RAM_BASE, RAM_SIZE = 0x20000000, 256 * 1024  # SRAM0-3, striped
SRAM_END = 0x20042000  # the end of SCRATCH_Y (SRAM5)
VECTORS = 0x10000100
N_VECTORS = 16 + 26  # initial SP and the Cortex-M0+ exceptions 1..15, then RP2040 IRQ 0..25
RESERVED = {4, 5, 6, 7, 8, 9, 10, 12, 13}  # reserved exception numbers on ARMv6-M
SHF_ALLOC = 0x2
SHT_NOBITS = 8


def _reverse_bits(value: int, width: int) -> int:
    return int(f"{value:0{width}b}"[::-1], 2)


def crc32_mpeg2(data: bytes) -> int:
    """CRC-32/MPEG-2 through zlib: the reflected CRC-32 of the bit-reversed bytes is the
    bit-reversed unreflected CRC (same polynomial, same all-ones start), less zlib's final XOR."""
    reflected = zlib.crc32(bytes(_reverse_bits(b, 8) for b in data)) ^ 0xFFFFFFFF
    return _reverse_bits(reflected, 32)


class Section(NamedTuple):
    name: str
    addr: int
    size: int
    flags: int
    type: int


def elf_sections(path: Path) -> list[Section]:
    """The section headers of a 32-bit little-endian ELF."""
    data = path.read_bytes()
    assert data[:4] == b"\x7fELF" and data[4] == 1 and data[5] == 1, f"{path}: not an ELF32 LE"
    shoff = struct.unpack_from("<I", data, 0x20)[0]
    shentsize, shnum, shstrndx = struct.unpack_from("<HHH", data, 0x2E)
    raw = [struct.unpack_from("<IIIIIIIIII", data, shoff + i * shentsize) for i in range(shnum)]
    strtab_off = raw[shstrndx][4]

    def name(off: int) -> str:
        end = data.index(b"\0", strtab_off + off)
        return data[strtab_off + off : end].decode()

    return [Section(name(s[0]), s[3], s[5], s[2], s[1]) for s in raw]


def check_boot2(elf: Path, image: bytes) -> list[str]:
    errors = []
    assert crc32_mpeg2(b"123456789") == 0x0376E6E7, "CRC-32/MPEG-2 catalogue check value"
    boot2 = [s for s in elf_sections(elf) if s.name == ".boot2"]
    if not boot2 or boot2[0].addr != FLASH_BASE or boot2[0].size != 256:
        errors.append(f".boot2 must be 256 bytes at 0x{FLASH_BASE:08x}: {boot2}")

    def valid(block: bytes) -> bool:
        return crc32_mpeg2(block[:252]) == int.from_bytes(block[252:256], "little")

    block = image[:256]
    stored = int.from_bytes(block[252:256], "little")
    computed = crc32_mpeg2(block[:252])
    print(f"boot2 CRC-32: stored 0x{stored:08x}, computed 0x{computed:08x}")
    if len(block) < 256 or not valid(block):
        errors.append(f"boot2 CRC mismatch: stored 0x{stored:08x}, computed 0x{computed:08x}")
    # The check can fail: one changed bit anywhere in the 256 bytes is caught.
    for i in range(len(block)):
        corrupted = bytearray(block)
        corrupted[i] ^= 0x01
        if valid(bytes(corrupted)):
            errors.append(f"the CRC check accepts boot2 with byte {i} changed")
    return errors


def check_vectors(elf: Path, image: bytes) -> list[str]:
    errors = []
    sections = elf_sections(elf)
    vectors = [s for s in sections if s.name == ".vectors"]
    if not vectors or vectors[0].addr != VECTORS or vectors[0].size != 4 * N_VECTORS:
        errors.append(f".vectors must be {4 * N_VECTORS} bytes at 0x{VECTORS:08x}: {vectors}")
    table = struct.unpack_from(f"<{N_VECTORS}I", image, VECTORS - FLASH_BASE)
    text = next(s for s in sections if s.name == ".text")
    sp, reset = table[0], table[1]
    print(f"initial SP 0x{sp:08x}, reset handler 0x{reset:08x}")
    if not (RAM_BASE < sp <= SRAM_END and sp % 8 == 0):
        errors.append(f"initial SP 0x{sp:08x} not 8-byte aligned in SRAM")
    for number, handler in enumerate(table[1:], start=1):
        if number in RESERVED:
            if handler != 0:
                errors.append(f"reserved vector {number} is 0x{handler:08x}, not 0")
            continue
        if handler & 1 == 0:
            errors.append(f"vector {number} 0x{handler:08x} is not a Thumb address (odd)")
        if not text.addr <= handler - 1 < text.addr + text.size:
            errors.append(f"vector {number} 0x{handler:08x} is outside .text in flash")
        if not FLASH_BASE <= handler - 1 < FLASH_BASE + len(image):
            errors.append(f"vector {number} 0x{handler:08x} is outside the image")
    return errors


def check_size(elf: Path, image: bytes) -> list[str]:
    errors = []
    flash_end, ram_use = FLASH_BASE, 0
    for s in elf_sections(elf):
        if not s.flags & SHF_ALLOC or s.size == 0:
            continue
        end = s.addr + s.size
        if FLASH_BASE <= s.addr < FLASH_BASE + FLASH_SIZE:
            flash_end = max(flash_end, end)
            if end > FLASH_BASE + FLASH_SIZE:
                errors.append(f"{s.name} ends at 0x{end:08x}, past the 2 MB flash")
        elif RAM_BASE <= s.addr < RAM_BASE + RAM_SIZE:
            ram_use += s.size
            if end > RAM_BASE + RAM_SIZE:
                errors.append(f"{s.name} ends at 0x{end:08x}, past the 256 KB RAM")
        elif s.name == ".stack":
            if not (s.addr >= RAM_BASE + RAM_SIZE and end <= SRAM_END):
                errors.append(f".stack at 0x{s.addr:08x}..0x{end:08x} is not in SCRATCH_X/Y")
        else:
            errors.append(f"{s.name} at 0x{s.addr:08x} is in neither flash nor RAM")
    if len(image) > FLASH_SIZE:
        errors.append(f"the image is {len(image)} bytes, more than the 2 MB flash")
    # .data's initial values follow the sections in flash: the .bin covers them all.
    if len(image) < flash_end - FLASH_BASE:
        errors.append(f"the .bin ({len(image)} bytes) ends before the flash sections")
    print(
        f"flash {len(image)} of {FLASH_SIZE} bytes ({100 * len(image) / FLASH_SIZE:.1f} %), "
        f"RAM {ram_use} of {RAM_SIZE} bytes ({100 * ram_use / RAM_SIZE:.1f} %) + 4 KB stack"
    )
    return errors


def check_tool(tool: Path) -> list[str]:
    errors = []
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        for n, ok in ((252, True), (253, False), (10, True)):
            code = d / f"code{n}.bin"
            code.write_bytes(bytes((7 * i + 1) & 0xFF for i in range(n)))
            out_s, out_bin = d / f"out{n}.S", d / f"out{n}.bin"
            run = subprocess.run(
                [sys.executable, str(tool), str(code), str(out_s), str(out_bin)],
                capture_output=True,
                text=True,
                check=False,
            )
            if ok:
                block = out_bin.read_bytes() if out_bin.exists() else b""
                if run.returncode != 0 or len(block) != 256:
                    errors.append(f"{n} bytes of code: exit {run.returncode}, {len(block)} bytes")
                elif block[:n] != code.read_bytes() or any(block[n:252]):
                    errors.append(f"{n} bytes of code: not the code then zero padding")
                elif crc32_mpeg2(block[:252]) != int.from_bytes(block[252:], "little"):
                    errors.append(f"{n} bytes of code: the tool's CRC disagrees")
            elif run.returncode == 0 or out_s.exists() or out_bin.exists():
                errors.append(f"{n} bytes of code accepted (exit {run.returncode})")
            else:
                print(f"{n} bytes refused: {run.stderr.strip()}")
    return errors


UF2_MAGIC_START0, UF2_MAGIC_START1, UF2_MAGIC_END = 0x0A324655, 0x9E5D5157, 0x0AB16F30
UF2_FAMILY_ID_PRESENT, RP2040_FAMILY = 0x00002000, 0xE48BFF56


def check_uf2(uf2: bytes, image: bytes) -> list[str]:
    """The UF2's blocks decoded independently of the converter; their pages against the .bin."""
    errors: list[str] = []
    if not uf2 or len(uf2) % 512:
        return [f"{len(uf2)} bytes is not a whole number of 512-byte UF2 blocks"]
    n = len(uf2) // 512
    flash = bytearray()
    for i in range(n):
        block = uf2[512 * i:512 * (i + 1)]
        m0, m1, flags, addr, size, number, total, family = struct.unpack_from("<8I", block)
        (end,) = struct.unpack_from("<I", block, 508)
        where = f"block {i}"
        if (m0, m1, end) != (UF2_MAGIC_START0, UF2_MAGIC_START1, UF2_MAGIC_END):
            errors.append(f"{where}: magics 0x{m0:08X} 0x{m1:08X} 0x{end:08X}")
        if not flags & UF2_FAMILY_ID_PRESENT or family != RP2040_FAMILY:
            errors.append(f"{where}: flags 0x{flags:08X}, family 0x{family:08X}")
        if (number, total, size) != (i, n, 256):
            errors.append(f"{where}: blockNo {number}/{total}, payload {size} bytes")
        if addr != FLASH_BASE + 256 * i:
            errors.append(f"{where}: address 0x{addr:08X}, expected 0x{FLASH_BASE + 256 * i:08X}")
        flash += block[32:32 + 256]
    want = image + bytes(-len(image) % 256)
    if bytes(flash) != want:
        diff = next((k for k in range(min(len(flash), len(want))) if flash[k] != want[k]),
                    min(len(flash), len(want)))
        errors.append(f"the UF2's {len(flash)} bytes differ from the padded image's {len(want)} "
                      f"from offset 0x{diff:X}")
    print(f"uf2: {n} blocks, 0x{FLASH_BASE:08X}..0x{FLASH_BASE + len(flash):08X}")
    return errors


def main(argv: list[str]) -> int:
    if len(argv) == 3 and argv[1] == "tool":
        errors = check_tool(Path(argv[2]))
    elif len(argv) == 5 and argv[1] == "uf2":
        missing = [p for p in argv[2:5] if not Path(p).is_file()]
        if missing:
            print(f"FAIL: {', '.join(missing)} not built (the pico_images target builds them; "
                  "the UF2 needs the project's .venv: scripts/setup.sh)")
            return 1
        errors = check_uf2(Path(argv[4]).read_bytes(), Path(argv[3]).read_bytes())
    elif len(argv) == 4 and argv[1] in ("boot2", "vectors", "size"):
        missing = [p for p in argv[2:4] if not Path(p).is_file()]
        if missing:
            print(f"FAIL: {', '.join(missing)} not built (the pico_images target builds them)")
            return 1
        elf, image = Path(argv[2]), Path(argv[3]).read_bytes()
        check = {"boot2": check_boot2, "vectors": check_vectors, "size": check_size}[argv[1]]
        errors = check(elf, image)
    else:
        print(__doc__)
        return 2
    for e in errors:
        print(f"FAIL: {e}")
    print("ok" if not errors else f"{len(errors)} failure(s)")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
