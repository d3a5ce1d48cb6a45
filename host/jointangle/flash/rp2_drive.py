"""The Raspberry Pi Pico's BOOTSEL drive: a USB mass-storage volume named RPI-RP2 that the
RP2040's bootrom shows while BOOTSEL is held at power-up. Copying a UF2 file onto it writes the
flash; the board then restarts into the new firmware and the drive goes away.

The drive is recognised by its INFO_UF2.TXT, which the bootrom fills with lines such as

    UF2 Bootloader v3.0
    Model: Raspberry Pi RP2
    Board-ID: RPI-RP2
"""

from __future__ import annotations

import glob
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from jointangle.errors import InputError

INFO_FILE = "INFO_UF2.TXT"
BOARD_ID = "RPI-RP2"


def mount_patterns(platform: str = sys.platform) -> tuple[str, ...]:
    """Glob patterns of the directories where removable drives are mounted: udisks under
    /media/USER and /run/media/USER, hand mounts under /media and /mnt, /Volumes on macOS,
    drive letters on Windows."""
    if platform == "darwin":
        return ("/Volumes/*",)
    if platform == "win32":
        return tuple(f"{letter}:/" for letter in "DEFGHIJKLMNOPQRSTUVWXYZ")
    return ("/media/*/*", "/run/media/*/*", "/media/*", "/mnt/*")


def board_id(directory: Path) -> str | None:
    """The Board-ID line of `directory`'s INFO_UF2.TXT (either case of the name), or None
    when there is no such file or it cannot be read."""
    for name in (INFO_FILE, INFO_FILE.lower()):
        try:
            text = (directory / name).read_text(encoding="ascii", errors="replace")
        except OSError:
            continue
        for line in text.splitlines():
            key, _, value = line.partition(":")
            if key.strip().lower() == "board-id":
                return value.strip()
        return ""
    return None


def is_rp2_drive(directory: Path) -> bool:
    return board_id(directory) == BOARD_ID


def find_rp2_drives(patterns: Sequence[str]) -> list[Path]:
    """The RPI-RP2 drives mounted at directories matching `patterns` (globs), in pattern order,
    each once."""
    found: list[Path] = []
    for pattern in patterns:
        for hit in sorted(glob.glob(pattern)):
            path = Path(hit)
            if path.is_dir() and is_rp2_drive(path) and path.resolve() not in (
                    p.resolve() for p in found):
                found.append(path)
    return found


def choose_drive(drive: Path | None, patterns: Sequence[str]) -> Path:
    """`drive` if it is an RPI-RP2 drive, else the one drive found under `patterns`.
    InputError when there is none, or several, or `drive` is not one."""
    if drive is not None:
        if not drive.is_dir():
            raise InputError("not a directory (the mounted RPI-RP2 drive)", path=drive,
                             field="--drive")
        found_id = board_id(drive)
        if found_id != BOARD_ID:
            why = (f"no {INFO_FILE}" if found_id is None
                   else f"its {INFO_FILE} says Board-ID: {found_id or '(none)'}")
            raise InputError(f"not a Pico's BOOTSEL drive ({why}; expected Board-ID: "
                             f"{BOARD_ID})", path=drive, field="--drive")
        return drive
    drives = find_rp2_drives(patterns)
    if not drives:
        raise InputError(f"no RPI-RP2 drive found (searched {' '.join(patterns)} for an "
                         f"{INFO_FILE} with Board-ID: {BOARD_ID}): hold BOOTSEL while "
                         f"plugging the Pico in, then try again, or name the drive with --drive",
                         field="--drive")
    if len(drives) > 1:
        raise InputError(f"{len(drives)} RPI-RP2 drives found ({', '.join(map(str, drives))}): "
                         f"name one with --drive", field="--drive")
    return drives[0]


def copy_to_drive(uf2: bytes, drive: Path, name: str) -> Path:
    """Write `uf2` as `drive/name`, flushed to the device before returning (the bootrom writes
    the flash as the blocks arrive and restarts the board after the last one)."""
    target = drive / name
    with target.open("wb") as f:
        f.write(uf2)
        f.flush()
        os.fsync(f.fileno())
    return target
