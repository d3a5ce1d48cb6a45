"""UF2 for the RP2040 (jointangle.flash.uf2): a real ARM ELF built here with arm-none-eabi-gcc,
converted, checked field by field against the format, decoded back to exactly the bytes
`objcopy -O binary` loads, and corrupted UF2s refused naming the block."""

from __future__ import annotations

import shutil
import struct
import subprocess
from pathlib import Path

import pytest

from jointangle.cli.main import main
from jointangle.errors import InputError
from jointangle.flash import rp2_drive, uf2

FLASH = 0x10000000

# Code and read-only data in flash, initialised data running from RAM but loaded from flash
# (its LMA follows .text), zeroed data, and a second flash segment after a gap: three PT_LOAD
# segments in flash with partial pages, and a .bss that loads nothing.
SOURCE = r"""
const unsigned char table[700] = { 1, 2, 3, [350] = 0xA5, [699] = 0x5A };
int counter = 0x12345678;
int zeroed[32];
__attribute__((section(".tail"), used)) const unsigned int tail[3] = { 0xCAFEF00D, 7, 9 };
int entry(void) {
    for (int i = 0; i < 32; i++) zeroed[i] = table[i * 20] + counter;
    return zeroed[3];
}
"""

LINKER_SCRIPT = """
MEMORY {
    FLASH (rx) : ORIGIN = 0x10000000, LENGTH = 2048K
    RAM (rwx)  : ORIGIN = 0x20000000, LENGTH = 256K
}
ENTRY(entry)
SECTIONS {
    .text : { *(.text*) *(.rodata*) } > FLASH
    .data : { *(.data*) } > RAM AT > FLASH
    .bss (NOLOAD) : { *(.bss*) *(COMMON) } > RAM
    .tail 0x10001010 : { KEEP(*(.tail)) } > FLASH
}
"""

RAM_LINKER_SCRIPT = """
ENTRY(entry)
SECTIONS { .text 0x20000000 : { *(.text*) *(.rodata*) *(.data*) } }
"""


def tool(name: str) -> str:
    path = shutil.which(name)
    assert path, (f"{name} is missing: scripts/setup.sh installs it (Debian: "
                  f"gcc-arm-none-eabi); the UF2 tests need a real ARM ELF")
    return path


def build_elf(directory: Path, source: str, linker_script: str) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "image.c").write_text(source)
    (directory / "link.ld").write_text(linker_script)
    elf = directory / "image.elf"
    subprocess.run([tool("arm-none-eabi-gcc"), "-mcpu=cortex-m0plus", "-mthumb", "-Os",
                    "-nostdlib", "-nostartfiles", "-Wl,--build-id=none", "-T",
                    str(directory / "link.ld"), "-o", str(elf), str(directory / "image.c")],
                   check=True, capture_output=True, text=True)
    return elf


@pytest.fixture(scope="module")
def elf(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return build_elf(tmp_path_factory.mktemp("arm"), SOURCE, LINKER_SCRIPT)


def load_segments(elf: Path) -> list[tuple[int, int]]:
    """(load address, file size) of each PT_LOAD segment with bytes, read by readelf."""
    out = subprocess.run([tool("arm-none-eabi-readelf"), "-lW", str(elf)], check=True,
                         capture_output=True, text=True).stdout
    rows = [line.split() for line in out.splitlines() if line.split()[:1] == ["LOAD"]]
    return [(int(r[3], 16), int(r[4], 16)) for r in rows if int(r[4], 16) > 0]


def test_the_test_elf_has_three_flash_segments_one_loaded_for_ram(elf: Path) -> None:
    segments = load_segments(elf)
    assert len(segments) == 3, segments
    assert all(FLASH <= start < FLASH + 0x2000 for start, _ in segments)
    assert any(start % 256 for start, _ in segments)  # partial pages to pad


def test_every_block_has_the_fields_of_the_format(elf: Path) -> None:
    image = uf2.elf_to_uf2(elf.read_bytes())
    assert len(image) % 512 == 0
    n = len(image) // 512
    addresses = []
    for i in range(n):
        block = image[i * 512:(i + 1) * 512]
        # The UF2 specification's order, read here without the module's decoder.
        m0, m1, flags, address, size, block_no, num_blocks, family = struct.unpack_from(
            "<8I", block)
        assert (m0, m1) == (0x0A324655, 0x9E5D5157)
        assert struct.unpack_from("<I", block, 508) == (0x0AB16F30,)
        assert flags == 0x2000 and family == 0xE48BFF56
        assert size == 256 and address % 256 == 0
        assert (block_no, num_blocks) == (i, n)
        assert block[32 + 256:508] == bytes(476 - 256)
        addresses.append(address)
    assert addresses == sorted(addresses) and addresses[0] == FLASH
    # The pages the segments touch, each once: text+rodata+data from 0x10000000, the tail page.
    touched = {page for start, size in load_segments(elf)
               for page in range(start - start % 256, start + size, 256)}
    assert set(addresses) == touched and len(addresses) == len(touched)


def test_decoding_gives_back_exactly_the_bytes_objcopy_loads(elf: Path, tmp_path: Path) -> None:
    binary = tmp_path / "image.bin"  # from the lowest load address, gaps filled with 0
    subprocess.run([tool("arm-none-eabi-objcopy"), "-O", "binary", str(elf), str(binary)],
                   check=True)
    expected = binary.read_bytes()
    ranges = uf2.uf2_to_flash(uf2.elf_to_uf2(elf.read_bytes()))
    assert len(ranges) == 2  # the gap before .tail is not written
    end = max(start + len(data) for start, data in ranges.items())
    flash = bytearray(end - FLASH)
    for start, data in ranges.items():
        flash[start - FLASH:start - FLASH + len(data)] = data
    assert len(flash) - len(expected) < 256  # the last page padded
    assert bytes(flash) == expected.ljust(len(flash), b"\x00")
    # What the program put there, in its place: the initialised .data word after .text.
    assert struct.pack("<I", 0x12345678) in ranges[FLASH]
    tail_page = max(ranges)
    assert ranges[tail_page][0x10:0x1C] == struct.pack("<3I", 0xCAFEF00D, 7, 9)


def test_conversion_is_deterministic_and_pads_with_zeros(elf: Path) -> None:
    data = elf.read_bytes()
    assert uf2.elf_to_uf2(data) == uf2.elf_to_uf2(data)
    tail = uf2.uf2_to_flash(uf2.elf_to_uf2(data))[0x10001000]
    assert tail[:0x10] == bytes(0x10) and tail[0x1C:] == bytes(256 - 0x1C)


def test_a_ram_only_elf_is_refused_naming_the_segment(tmp_path: Path) -> None:
    ram = build_elf(tmp_path, SOURCE.replace('section(".tail"), ', ""), RAM_LINKER_SCRIPT)
    with pytest.raises(InputError, match=r"segment \d+ .*0x20000000\) is outside the RP2040's "
                       r"flash 0x10000000\.\.0x11000000") as exc:
        uf2.elf_to_uf2(ram.read_bytes(), source=ram)
    assert str(ram) in str(exc.value)


def test_an_elf_with_no_loadable_bytes_is_refused(tmp_path: Path) -> None:
    empty = build_elf(tmp_path, "int zeroed[8];\n", LINKER_SCRIPT)
    with pytest.raises(InputError, match="no loadable bytes"):
        uf2.elf_to_uf2(empty.read_bytes())


def test_what_is_not_a_32_bit_little_endian_arm_elf_is_refused(elf: Path) -> None:
    with pytest.raises(InputError, match="not an ELF file"):
        uf2.elf_to_uf2(b"UF2\n not an elf")
    with pytest.raises(InputError, match="not a readable ELF"):
        uf2.elf_to_uf2(b"\x7fELF\x01\x01\x01" + bytes(9))
    x86 = bytearray(elf.read_bytes())
    struct.pack_into("<H", x86, 18, 62)  # e_machine = EM_X86_64
    with pytest.raises(InputError, match=r"not a 32-bit little-endian ARM ELF \(32-bit, "
                       r"little-endian, EM_X86_64\)"):
        uf2.elf_to_uf2(bytes(x86))
    big = bytearray(elf.read_bytes())
    big[5] = 2  # EI_DATA = ELFDATA2MSB
    with pytest.raises(InputError, match=r"not a 32-bit little-endian ARM ELF .*big-endian"):
        uf2.elf_to_uf2(bytes(big))
    wide = bytearray(elf.read_bytes())
    wide[4] = 2  # EI_CLASS = ELFCLASS64
    with pytest.raises(InputError, match=r"not a (32-bit little-endian ARM|readable) ELF"):
        uf2.elf_to_uf2(bytes(wide))


def _blocks(image: bytes) -> list[bytearray]:
    return [bytearray(image[i:i + 512]) for i in range(0, len(image), 512)]


def _set(block: bytearray, offset: int, value: int) -> None:
    struct.pack_into("<I", block, offset, value)


@pytest.mark.parametrize(("name", "block_no", "damage", "message"), [
    ("bad start magic", 1, lambda b: _set(b, 0, 0x0A324656), "start magic 0x0A324656"),
    ("bad end magic", 2, lambda b: _set(b, 508, 0), "end magic 0x00000000"),
    ("wrong family", 2, lambda b: _set(b, 28, 0x68ED2B88), "family ID 0x68ED2B88, not the "
     "RP2040's 0xE48BFF56"),
    ("no family flag", 0, lambda b: _set(b, 8, 0), "lack 0x00002000"),
    ("not main flash", 1, lambda b: _set(b, 8, 0x2001), "not main flash"),
    ("payload size", 1, lambda b: _set(b, 16, 476), "payload size 476"),
    ("unaligned", 1, lambda b: _set(b, 12, FLASH + 0x80), "not a 256-byte page"),
    ("outside flash", 0, lambda b: _set(b, 12, 0x20000000), "0x20000000 is not a 256-byte page"),
    ("block count", 2, lambda b: _set(b, 24, 99), "numBlocks is 99"),
])
def test_a_corrupted_block_is_refused_naming_it(
        elf: Path, name: str, block_no: int, damage: object, message: str) -> None:
    blocks = _blocks(uf2.elf_to_uf2(elf.read_bytes()))
    assert callable(damage)
    damage(blocks[block_no])
    with pytest.raises(InputError, match=rf"^x\.uf2: block {block_no} \(bytes "
                       rf"{block_no * 512}\.\.{block_no * 512 + 512}\): .*{message}"):
        uf2.uf2_to_flash(b"".join(blocks), source="x.uf2")


def test_blocks_out_of_order_are_refused_naming_the_first(elf: Path) -> None:
    blocks = _blocks(uf2.elf_to_uf2(elf.read_bytes()))
    blocks[0], blocks[1] = blocks[1], blocks[0]
    with pytest.raises(InputError, match=r"block 0 .*blockNo is 1, expected 0"):
        uf2.uf2_to_flash(b"".join(blocks))


def test_a_page_written_twice_or_a_cut_file_is_refused(elf: Path) -> None:
    image = uf2.elf_to_uf2(elf.read_bytes())
    blocks = _blocks(image)
    _set(blocks[1], 12, FLASH)
    with pytest.raises(InputError, match="block 1: target address 0x10000000 is written by an "
                       "earlier block"):
        uf2.uf2_to_flash(b"".join(blocks))
    with pytest.raises(InputError, match="not a whole number of 512-byte"):
        uf2.uf2_to_flash(image[:-1])
    with pytest.raises(InputError, match="0 bytes is not"):
        uf2.uf2_to_flash(b"")


def test_flash_converts_an_elf_and_copies_its_uf2_to_the_drive(
        elf: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    drive = tmp_path / "RPI-RP2"
    drive.mkdir()
    (drive / "INFO_UF2.TXT").write_text("UF2 Bootloader v3.0\nBoard-ID: RPI-RP2\n")
    monkeypatch.setattr(rp2_drive, "mount_patterns", lambda: (str(tmp_path / "*"),))
    assert main(["flash", "--board", "pico", "--dry-run", str(elf)]) == 0
    assert f"{elf} (converted from ELF" in capsys.readouterr().out
    assert main(["flash", "--board", "pico", str(elf)]) == 0
    assert (drive / "image.uf2").read_bytes() == uf2.elf_to_uf2(elf.read_bytes())
