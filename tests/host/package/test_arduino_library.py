"""The firmware as an Arduino library (issue 18 item 4, firmware/arduino/README.md): the CMake
target `arduino_library` zips library.properties, src/ and examples/JointAngle from the
firmware's own sources; Debian's arduino-builder builds the example for the Mega 2560 from the
unzipped library as the IDE does; its image is compared in size with the CMake image and streams
on sim://avr (its ELF given to the board), passing `replay --verify` and `--verify-firmware`.

About a minute and a half on two cores (the Arduino core and the library, -Os with LTO)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from jointangle import __version__
from jointangle.built import AVR_IMAGE, REPO_ROOT, find_part

pytestmark = pytest.mark.slow
TREE = REPO_ROOT / "build" / "native"
FQBN = "arduino:avr:mega:cpu=atmega2560"
ARDUINO = Path("/usr/share/arduino")  # Debian's arduino-core-avr
# The core's own language (platform.txt: gnu++11) — the library builds as shipped; only Debian's
# core 1.8 with gcc-avr 5.4 needs DECIMAL_DIG, for any sketch (firmware/arduino/README.md).
PREFS = "compiler.cpp.extra_flags=-DDECIMAL_DIG=__DECIMAL_DIG__"
FLASH_BYTES, RAM_BYTES = 253_952, 8192  # the Mega 2560's, less the bootloader (boards.txt)


def avr_size(elf: Path) -> tuple[int, int]:
    """(flash, RAM) bytes of an image: text + data, data + bss (avr-size's Berkeley format)."""
    out = subprocess.run(["avr-size", str(elf)], capture_output=True, text=True,
                         check=True).stdout.splitlines()[1].split()
    text, data, bss = (int(x) for x in out[:3])
    return text + data, data + bss


def jointangle(*argv: str) -> str:
    res = subprocess.run([sys.executable, "-m", "jointangle", *argv], capture_output=True,
                         text=True, timeout=300, check=False)
    assert res.returncode == 0, (argv, res.stdout[-2000:], res.stderr[-2000:])
    return res.stdout


def library_zip() -> Path:
    assert (TREE / "CMakeCache.txt").is_file(), f"{TREE} is not configured (scripts/test.sh)"
    res = subprocess.run(["cmake", "--build", str(TREE), "--target", "arduino_library"],
                         capture_output=True, text=True, check=False)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    return TREE / "firmware" / "arduino" / f"JointAngle-{__version__}.zip"


def check_zip(zip_path: Path) -> None:
    """The layout the IDE's "Add .ZIP Library" and arduino-cli expect, from the same sources."""
    z = zipfile.ZipFile(zip_path)
    names = set(z.namelist())
    props = dict(line.split("=", 1) for line in
                 z.read("JointAngle/library.properties").decode().splitlines() if "=" in line)
    assert props["name"] == "JointAngle" and props["version"] == __version__
    assert props["architectures"] == "avr" and props["includes"] == "JointAngle.h"
    ino = z.read("JointAngle/examples/JointAngle/JointAngle.ino").decode()
    sketch = (REPO_ROOT / "firmware/sketches/JointAngle/JointAngle.ino").read_text()
    assert ino == sketch.replace('#include "platform/avr/board/board.hpp"',
                                 "#include <JointAngle.h>")
    firmware = REPO_ROOT / "firmware"
    sources = [p for d in ("app", "drivers", "protocol", "core", "platform/avr/board")
               for p in (firmware / d).iterdir() if p.suffix in (".cpp", ".hpp")
               and p.name != "main.cpp"]
    assert len(sources) > 30
    for src in sources:  # each one byte for byte, where the firmware's includes expect it
        rel = src.relative_to(firmware).as_posix()
        assert z.read(f"JointAngle/src/{rel}") == src.read_bytes(), rel
    assert "JointAngle/src/platform/avr/board/main.cpp" not in names
    assert {"JointAngle/src/cmath", "JointAngle/src/Eigen/Core",
            "JointAngle/src/JointAngle.h"} <= names


def build_with_arduino_builder(zip_path: Path, work: Path) -> Path:
    """Unzip into a sketchbook's libraries/ and build the example as the IDE does."""
    builder = shutil.which("arduino-builder")
    assert builder, "arduino-builder is missing: scripts/setup.sh installs it"
    libraries, build, sketch = work / "libraries", work / "build", work / "JointAngle"
    for d in (libraries, build, sketch):
        d.mkdir()
    zipfile.ZipFile(zip_path).extractall(libraries)
    shutil.copy(libraries / "JointAngle/examples/JointAngle/JointAngle.ino", sketch)
    res = subprocess.run(
        [builder, "-compile", "-hardware", str(ARDUINO / "hardware"), "-tools",
         str(ARDUINO / "hardware/tools"), "-libraries", str(libraries), "-fqbn", FQBN,
         "-build-path", str(build), "-warnings", "default", f"-prefs={PREFS}",
         str(sketch / "JointAngle.ino")], capture_output=True, text=True, timeout=900,
        check=False)
    assert res.returncode == 0, res.stdout[-4000:] + res.stderr[-4000:]
    assert any((build / "libraries" / "JointAngle").rglob("board.cpp.o")), "library not built"
    return build / "JointAngle.ino.elf"


def test_the_arduino_library_builds_with_arduino_builder_and_streams_on_sim_avr(
        tmp_path: Path) -> None:
    zip_path = library_zip()
    check_zip(zip_path)
    elf = build_with_arduino_builder(zip_path, tmp_path)

    # Size beside the CMake image: the IDE builds at -Os with LTO, the CMake image at -O2.
    cmake_elf = find_part(AVR_IMAGE, build=True)
    (lib_flash, lib_ram), (cm_flash, cm_ram) = avr_size(elf), avr_size(cmake_elf)
    print(f"Arduino library image: flash {lib_flash} B, RAM {lib_ram} B; CMake image: flash "
          f"{cm_flash} B, RAM {cm_ram} B")
    assert lib_flash < FLASH_BYTES and lib_ram < RAM_BYTES - 2048  # room for the stack
    assert 0.5 * cm_flash < lib_flash <= 1.1 * cm_flash
    assert abs(lib_ram - cm_ram) <= 1024

    # The same behaviour on sim://avr: the CMake image writes the rig's EEPROM configuration,
    # the library's image boots from it, streams, and its estimates verify against `mirror`
    # and, bit for bit, against the x86 fixed-point core.
    eeprom, rec = tmp_path / "eeprom.bin", tmp_path / "library.jrec"
    jointangle("info", "--port", f"sim://avr?eeprom={eeprom}&fast=1")
    jointangle("record", "--port", f"sim://avr?elf={elf}&eeprom={eeprom}&fast=1", "--seconds",
               "3", "--out", str(rec))
    doc = json.loads(jointangle("replay", str(rec), "--verify", "--verify-firmware", "--json"))
    assert doc["frames"] > 300 and doc["frames_lost"] == 0 and doc["crc_errors"] == 0
    # docs/design.md §5's parity budget, firmware against mirror: from 2 s on (the start-up's
    # transient has its own, 1°, over the whole run)
    assert doc["steady_max_abs_dtheta_deg"] <= 0.05 and doc["steady_rms_dtheta_deg"] <= 0.01, doc
    assert doc["max_abs_dtheta_deg"] <= 1.0, doc
    assert doc["firmware_frames_compared"] > 300 and doc["firmware_mismatches"] == 0
