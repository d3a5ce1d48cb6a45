"""`jointangle flash [--board mega|pico] ...`: write the firmware to a board.

**Arduino Mega 2560** (`--board mega`, the default): `flash [--port P] [--dry-run] [--hex FILE]`.
The Mega 2560's bootloader speaks STK500v2, which avrdude calls `wiring` (the Arduino IDE's
boards.txt: `mega.upload.protocol=wiring`, 115200 baud; `-D` keeps the chip erase out, as the
bootloader erases page by page). The command is

    avrdude -p atmega2560 -c wiring -P PORT -b 115200 -D -U flash:w:FILE.hex:i

The image is `jointangle_mega2560.hex`, built by CMake (`avr_images`) into `<build>/avr/`; it is
built first when a configured build tree exists. The port is `--port` or the first Mega found
by USB VID:PID (`transport.KNOWN_BOARDS`); a port whose VID:PID is not a Mega or one of the
USB-serial bridges of Mega clones is refused unless `--force`.

**Raspberry Pi Pico** (`--board pico`): `flash --board pico [--dry-run] [--drive D] [IMAGE]`.
The RP2040's bootrom shows a USB drive, RPI-RP2, while BOOTSEL is held at power-up; copying a
UF2 file onto it writes the flash (`jointangle.flash.rp2_drive`). IMAGE is a `.uf2`, checked
block by block, or an ARM `.elf`, converted first (`jointangle.flash.uf2`); without it, the Pico
build's `pico/jointangle_pico.uf2` in a build tree (build/native first) or $JOINTANGLE_PICO_UF2.
The drive is `--drive` or the one mounted RPI-RP2 drive found under the usual mount points.
"""

from __future__ import annotations

import argparse
import os
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

from jointangle.built import REPO_ROOT, env_override, locate_built, search_build_trees
from jointangle.errors import InputError
from jointangle.flash import rp2_drive, uf2
from jointangle.transport import KNOWN_BOARDS, DetectedPort, detect_boards, list_serial_ports

IMAGE_HEX = "jointangle_mega2560.hex"
IMAGE_TARGET = "avr_images"
HEX_ENV = "JOINTANGLE_AVR_HEX"
PORT_PLACEHOLDER = "PORT"
EXIT_INPUT = 2
BOARDS = ("mega", "pico")
PICO_UF2 = "jointangle_pico.uf2"
PICO_PATTERN = f"pico/{PICO_UF2}"  # under a build tree: build/native/pico/jointangle_pico.uf2
PICO_ENV = "JOINTANGLE_PICO_UF2"
DRIVE_PLACEHOLDER = Path("DRIVE")


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "flash", help="write the firmware to a board: Arduino Mega 2560 (avrdude, the default) "
        "or Raspberry Pi Pico (--board pico: a UF2 copied to its BOOTSEL drive)",
        description="Write the firmware to a board. "
        "--board mega (the default): build the AVR image if needed and write it through the "
        "Mega's bootloader: avrdude -p atmega2560 -c wiring -P PORT -b 115200 -D "
        "-U flash:w:FILE.hex:i. Without --port the first Arduino Mega (or Mega-clone USB "
        "bridge) found by USB VID:PID is used; no board is an error (exit status 2). "
        "--board pico: copy a UF2 image to the Pico's RPI-RP2 drive (hold BOOTSEL while "
        "plugging the Pico in); IMAGE is a .uf2 or an ARM .elf (converted to UF2 first), by "
        f"default the Pico build's build/native/{PICO_PATTERN}. Without --drive the drive is "
        "found by its INFO_UF2.TXT under the usual mount points (/media, /run/media, /mnt, "
        "/Volumes); no drive is an error (exit status 2).")
    p.add_argument("--board", choices=BOARDS, default="mega",
                   help="the board: mega (Arduino Mega 2560, avrdude; the default) or pico "
                   "(Raspberry Pi Pico / RP2040, UF2 onto its BOOTSEL drive)")
    p.add_argument("image", nargs="?", type=Path, metavar="IMAGE",
                   help=f"pico: the .uf2 or .elf image to write (default: {PICO_UF2} from the "
                   f"Pico build, build/native/{PICO_PATTERN}; or ${PICO_ENV})")
    p.add_argument("--port", help="mega: serial port of the Mega (default: detected by USB "
                   "VID:PID)")
    p.add_argument("--hex", type=Path, help=f"mega: Intel HEX image to write (default: "
                   f"{IMAGE_HEX} from the CMake build, built if needed; or ${HEX_ENV})")
    p.add_argument("--drive", type=Path,
                   help="pico: the mounted RPI-RP2 drive (default: found by its INFO_UF2.TXT)")
    p.add_argument("--dry-run", action="store_true",
                   help="mega: print the avrdude command; pico: print which image goes to "
                   "which drive; write nothing")
    p.add_argument("--force", action="store_true",
                   help="mega: flash a port whose USB VID:PID is not a known Mega or bridge")
    p.set_defaults(func=run)


def avrdude_command(port: str, hex_path: Path, avrdude: str = "avrdude") -> list[str]:
    return [avrdude, "-p", "atmega2560", "-c", "wiring", "-P", port, "-b", "115200", "-D",
            "-U", f"flash:w:{hex_path}:i"]


def _same_device(a: str, b: str) -> bool:
    return os.path.realpath(a) == os.path.realpath(b)


def choose_port(port: str | None, force: bool) -> DetectedPort | None:
    """The board to flash: `port` checked against the known VID:PIDs, or the first one found.
    None only for a forced unknown port."""
    ports = list_serial_ports()
    boards = detect_boards(lambda: ports)
    known = ", ".join(sorted({f"{k.vid:04X}:{k.pid:04X}" for k in KNOWN_BOARDS}))
    if port is None:
        if not boards:
            raise InputError("no Arduino Mega 2560 found (no serial port with a known USB "
                             f"VID:PID: {known}); connect the board or name it with --port",
                             field="--port")
        return boards[0]
    for b in boards:
        if _same_device(b.device, port):
            return b
    if force:
        return None
    seen = next((p for p in ports if _same_device(str(p.device), port)), None)
    where = ("not a serial port on this machine" if seen is None
             else "no USB VID:PID" if seen.vid is None or seen.pid is None
             else f"USB {seen.vid:04X}:{seen.pid:04X}")
    raise InputError(f"{port} does not look like an Arduino Mega 2560 ({where}; known: "
                     f"{known}); use --force to flash it anyway", field="--port")


def _check_intel_hex(path: Path) -> None:
    """Refuse a file that is not an Intel HEX image (its records start with ':') before avrdude
    is asked to write it."""
    with path.open("rb") as f:
        head = f.read(64).lstrip()
    if not head.startswith(b":"):
        raise InputError("not an Intel HEX image (its first record should start with ':')",
                         path=path)


def find_image(hex_arg: Path | None, *, build: bool) -> tuple[Path, bool]:
    """(the HEX image, whether it exists). Builds `avr_images` in build/native when asked."""
    if hex_arg is not None:
        if not hex_arg.is_file():
            raise InputError("HEX image not found", path=hex_arg)
        _check_intel_hex(hex_arg)
        return hex_arg, True
    override = env_override(HEX_ENV)
    if override is not None:
        return override, True
    pattern = f"avr/{IMAGE_HEX}"
    found = search_build_trees(pattern, REPO_ROOT)
    if found is not None:
        return found, True
    tree = REPO_ROOT / "build" / "native"
    if not build:
        return tree / pattern, False
    how = (f"`cmake -S . -B build/native && cmake --build build/native --target {IMAGE_TARGET}`"
           f", or name one with --hex")
    print(f"building {IMAGE_TARGET} in {tree} ...", file=sys.stderr)
    return locate_built(pattern, env=HEX_ENV, target=IMAGE_TARGET, build=True, root=REPO_ROOT,
                        missing=lambda detail: InputError(
                            f"the AVR image {IMAGE_HEX} is not built{detail}: run {how}",
                            field="--hex")), True


def _refuse_other_board_options(args: argparse.Namespace) -> None:
    """Options of the other board are an error, not silently ignored."""
    other = ({"--port": args.port, "--hex": args.hex, "--force": args.force}
             if args.board == "pico" else {"IMAGE": args.image, "--drive": args.drive})
    for name, value in other.items():
        if value:
            hint = ("the Pico takes its image as IMAGE (.uf2 or .elf)" if name == "--hex"
                    else "the Mega takes its image as --hex; for a Pico add --board pico"
                    if name == "IMAGE"
                    else f"it belongs to --board {'mega' if args.board == 'pico' else 'pico'}")
            raise InputError(f"not an option of --board {args.board}: {hint}", field=name)


def pico_image(image: Path | None) -> tuple[bytes, Path, str]:
    """(the UF2 bytes, the file they come from, how they were made): IMAGE (a UF2, or an ELF
    converted), else the Pico build's image."""
    if image is None:
        image = env_override(PICO_ENV) or search_build_trees(PICO_PATTERN, REPO_ROOT)
        if image is None:
            raise InputError(
                f"the Pico image {PICO_UF2} is not built (looked for "
                f"{REPO_ROOT / 'build' / 'native' / PICO_PATTERN}): build the Pico firmware "
                f"(firmware/platform/pico; `bash scripts/setup.sh` installs the ARM toolchain) "
                f"or name an image: flash --board pico IMAGE.uf2|IMAGE.elf", field="IMAGE")
    if not image.is_file():
        raise InputError("image not found", path=image)
    data = image.read_bytes()
    if data.startswith(uf2.ELF_MAGIC):
        return uf2.elf_to_uf2(data, source=image), image, "converted from ELF"
    if not uf2.is_uf2(data):
        raise InputError("neither a UF2 nor an ELF image (the Pico takes IMAGE.uf2 or "
                         "IMAGE.elf)", path=image)
    return data, image, "UF2"


def run_pico(args: argparse.Namespace) -> int:
    data, source, how = pico_image(args.image)
    name = source.with_suffix(".uf2").name
    ranges = uf2.uf2_to_flash(data, source=source)  # every block checked before any copy
    span = ", ".join(f"0x{start:08X}..0x{start + len(r):08X}" for start, r in ranges.items())
    what = f"{source} ({how}, {len(data) // uf2.BLOCK_SIZE} UF2 blocks, flash {span})"
    try:
        drive = rp2_drive.choose_drive(args.drive, rp2_drive.mount_patterns())
    except InputError:
        if not (args.dry_run and args.drive is None):
            raise
        drive = DRIVE_PLACEHOLDER  # a dry run shows the plan even without a drive
        print("no RPI-RP2 drive found: DRIVE stands for it (hold BOOTSEL while plugging the "
              "Pico in)", file=sys.stderr)
    if args.dry_run:
        print(f"would copy {what} to {drive / name}")
        return 0
    print(f"flashing {what} to {drive}", file=sys.stderr)
    target = rp2_drive.copy_to_drive(data, drive, name)
    print(f"wrote {target}: the Pico restarts into the new firmware", file=sys.stderr)
    return 0


def run(args: argparse.Namespace) -> int:
    _refuse_other_board_options(args)
    if args.board == "pico":
        return run_pico(args)
    board = None
    try:
        board = choose_port(args.port, args.force)
        port = args.port or (board.device if board else PORT_PLACEHOLDER)
    except InputError:
        if not (args.dry_run and args.port is None):
            raise
        port = PORT_PLACEHOLDER  # a dry run shows the command even without a board
        print("no Arduino Mega found: PORT stands for its serial port", file=sys.stderr)
    hex_path, exists = find_image(args.hex, build=not args.dry_run)
    avrdude = shutil.which("avrdude")
    cmd = avrdude_command(port, hex_path, "avrdude" if args.dry_run or not avrdude else avrdude)
    if args.dry_run:
        if not exists:
            print(f"{hex_path} is not built yet: flash builds it (CMake target {IMAGE_TARGET})",
                  file=sys.stderr)
        print(shlex.join(cmd))  # pastes into a shell as printed
        return 0
    if avrdude is None:
        raise InputError("avrdude is not installed (Debian: apt-get install avrdude; "
                         "scripts/setup.sh installs it)", field="avrdude")
    what = board.what if board else "a port of unknown USB id (--force)"
    print(f"flashing {hex_path} to {port} ({what})", file=sys.stderr)
    res = subprocess.run(cmd, check=False)
    if res.returncode != 0:
        print(f"jointangle flash: avrdude failed with status {res.returncode}", file=sys.stderr)
        return 1
    return 0
