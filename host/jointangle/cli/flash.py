"""`jointangle flash [--port P] [--dry-run] [--hex FILE]`: write the firmware to an Arduino Mega.

The Mega 2560's bootloader speaks STK500v2, which avrdude calls `wiring` (the Arduino IDE's
boards.txt: `mega.upload.protocol=wiring`, 115200 baud; `-D` keeps the chip erase out, as the
bootloader erases page by page). The command is

    avrdude -p atmega2560 -c wiring -P PORT -b 115200 -D -U flash:w:FILE.hex:i

The image is `jointangle_mega2560.hex`, built by CMake (`avr_images`) into `<build>/avr/`; it is
built first when a configured build tree exists. The port is `--port` or the first Mega found
by USB VID:PID (`transport.KNOWN_BOARDS`); a port whose VID:PID is not a Mega or one of the
USB-serial bridges of Mega clones is refused unless `--force`.
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
from jointangle.transport import KNOWN_BOARDS, DetectedPort, detect_boards, list_serial_ports

IMAGE_HEX = "jointangle_mega2560.hex"
IMAGE_TARGET = "avr_images"
HEX_ENV = "JOINTANGLE_AVR_HEX"
PORT_PLACEHOLDER = "PORT"
EXIT_INPUT = 2


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "flash", help="write the firmware to an Arduino Mega 2560 with avrdude",
        description="Build the AVR image if needed and write it through the Mega's bootloader: "
        "avrdude -p atmega2560 -c wiring -P PORT -b 115200 -D -U flash:w:FILE.hex:i. "
        "Without --port the first Arduino Mega (or Mega-clone USB bridge) found by USB VID:PID "
        "is used; no board is an error (exit status 2).")
    p.add_argument("--port", help="serial port of the Mega (default: detected by USB VID:PID)")
    p.add_argument("--hex", type=Path, help=f"Intel HEX image to write (default: {IMAGE_HEX} "
                   f"from the CMake build, built if needed; or ${HEX_ENV})")
    p.add_argument("--dry-run", action="store_true",
                   help="print the avrdude command and do nothing")
    p.add_argument("--force", action="store_true",
                   help="flash a port whose USB VID:PID is not a known Mega or bridge")
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


def run(args: argparse.Namespace) -> int:
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
