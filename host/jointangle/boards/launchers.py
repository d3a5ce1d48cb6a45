"""The virtual boards behind `sim://NAME` (docs/design.md §4): the table `SIM_LAUNCHERS`
(python-can's table of backends, not string-prefix guessing) of `native`, the firmware
application compiled for x86, `avr`, the real AVR image in simavr, and `pico`, the RP2040 image
in the rp2040js emulator under Node.js. A launcher writes the rig
and the motion the board plays (`prepare_motion`, from the motion simulator `jointangle.sim`)
into a fresh work folder and starts the board (`process.start_process_board`).

Importing this module has no side effects and it keeps no module state.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from types import MappingProxyType

from jointangle.boards.options import DEFAULT_BAUD, PORT_FIELD, LaunchOptions, board_args
from jointangle.boards.process import (
    OWNER_FILE,
    BoardLauncher,
    RunningBoard,
    remove_orphaned_workdirs,
    start_process_board,
)
from jointangle.built import (
    PICO_BOARD_LIB,
    PICO_BOOTROM,
    PICO_IMAGE,
    REPO_ROOT,
    how_to_get,
    locate_built,
)
from jointangle.errors import InputError
from jointangle.io.csv_formats import AccelData, Truth, read_accel_csv, write_accel_csv
from jointangle.io.rig_file import write_rig
from jointangle.model import read_checked_rig
from jointangle.sim.scenarios import get_scenario, simulate

DEFAULT_FACTORY_RATE_HZ = 500  # a launcher that names none (app::kFactoryRateHz)


def prepare_motion(options: LaunchOptions, workdir: Path) -> tuple[Path, Path, str]:
    """Write the rig file and the accelerations CSV a virtual board plays (docs/design.md §4):
    the scenario's motion at the board's rate, on `options.rig_path` or the scenario's rig.
    With `options.motion_path` the given CSV and rig are used as they are (nothing generated)."""
    # The rig is checked as `--rig` is (its geometry too: coincident sensors...) before the board
    # starts, and a given motion against it (columns, numbers) as `estimate` checks its input.
    if options.motion_path is not None:
        if options.rig_path is None:
            raise InputError("a motion CSV needs the rig it was made for", field="rig")
        text, checked = read_checked_rig(options.rig_path)
        if not options.motion_path.is_file():
            raise InputError("motion CSV not found", path=options.motion_path)
        read_accel_csv(options.motion_path, checked)
        return options.rig_path, options.motion_path, text
    rate = float(options.rate_hz or DEFAULT_FACTORY_RATE_HZ)
    rig = (read_checked_rig(options.rig_path)[1].with_sample_rate(rate)
           if options.rig_path is not None else get_scenario(options.scenario).rig(rate))
    sim = simulate(options.scenario, seed=options.seed, rate_hz=rate, seconds=options.seconds,
                   rig=rig)
    rig_path, motion = workdir / "rig.toml", workdir / "motion.csv"
    write_rig(sim.rig, rig_path)
    write_accel_csv(motion, sim.rig, AccelData(t=sim.t, readings=sim.readings,
                                               truth=Truth(sim.theta, sim.omega_a,
                                                           sim.omega_b)))
    return rig_path, motion, rig_path.read_text(encoding="utf-8")


def _start_virtual_board(binary: Path | Sequence[str], options: LaunchOptions, prefix: str,
                         trailing: Sequence[str] = (), baud: bool = True) -> RunningBoard:
    """Every virtual board: the rig and motion in a fresh work directory (removed if writing
    them fails), then `binary --rig R --motion M --baud B <board_args> <extra_args> <trailing>`
    (without --baud when `baud` is false: the image's own rate). `binary` may be a command
    (interpreter and script)."""
    remove_orphaned_workdirs(Path(tempfile.gettempdir()), prefix)
    workdir = Path(tempfile.mkdtemp(prefix=prefix))
    try:
        (workdir / OWNER_FILE).write_text(f"{os.getpid()}\n", encoding="ascii")
        rig_path, motion, rig_text = prepare_motion(options, workdir)
    except BaseException:
        shutil.rmtree(workdir, ignore_errors=True)
        raise
    command = [str(binary)] if isinstance(binary, Path) else list(binary)
    argv = [*command, "--rig", str(rig_path), "--motion", str(motion),
            *(["--baud", str(options.baud)] if baud else []), *board_args(options),
            *options.extra_args, *trailing]
    return start_process_board(argv, options, rig_text, workdir)


def _locate_board_part(url: str, root: Path, what: str, pattern: str, target: str, env: str,
                       build: bool) -> Path:
    """A compiled part a virtual board needs (`locate_built`); missing: one line naming the
    board, the part, its CMake target and how to get it."""
    def missing(detail: str) -> InputError:
        return InputError(f"{url} needs {what}, CMake target `{target}`, which is not built"
                          f"{detail}: {how_to_get(target, env, root)}, or name a port with "
                          "--port", field=PORT_FIELD)

    return locate_built(pattern, env=env, target=target, build=build, root=root, missing=missing)


def _with_clock_stretch(options: LaunchOptions) -> LaunchOptions:
    """`options` with its clock stretching as the emulating boards' --clock-stretch ADDR=US."""
    stretch = [a for addr, us in options.clock_stretch
               for a in ("--clock-stretch", f"{addr:#x}={us}")]
    return replace(options, extra_args=(*options.extra_args, *stretch))


@dataclass(frozen=True)
class NativeBoardLauncher:
    """`sim://native`: the firmware application compiled for x86, serving a pty.

    The board is the CMake target `target`; its binary is found through $JOINTANGLE_NATIVE_BOARD
    or under build/*/firmware/ (built first when a configured build tree exists). It is started
    as

        ja_native_board --rig RIG.toml --motion DATA.csv --baud B [--fast] [extra args]

    with the rig and the motion written by `prepare_motion` plus `board_args` (fast clock,
    motion loop, EEPROM file, faults, cable pull: firmware/platform/posix/README.md), and must
    follow `start_process_board`'s contract (print `PTY <path>`, serve the protocol, exit on
    SIGTERM).
    """

    name: str = "native"
    description: str = "the firmware application compiled for x86 on a pseudo-terminal"
    factory_rate_hz: int = 500  # app::kFactoryRateHz
    target: str = "ja_native_board"
    env: str = "JOINTANGLE_NATIVE_BOARD"
    root: Path = REPO_ROOT

    def _missing(self, detail: str = "") -> InputError:
        return InputError(
            f"sim://native needs the native virtual board, CMake target `{self.target}`, "
            f"which is not built{detail}: {how_to_get(self.target, self.env, self.root)}, or "
            "name a port with --port", field=PORT_FIELD)

    def find_binary(self, build: bool = False) -> Path:
        return locate_built(f"firmware/**/{self.target}", env=self.env, target=self.target,
                            missing=self._missing, build=build, root=self.root,
                            executable=True)

    def start(self, options: LaunchOptions) -> RunningBoard:
        if options.elf_path is not None or options.clock_stretch:
            raise InputError("elf= and stretch= are the AVR board's: they need sim://avr, not "
                             "sim://native", field=PORT_FIELD)
        options = replace(options, rate_hz=options.rate_hz or self.factory_rate_hz)
        return _start_virtual_board(self.find_binary(build=options.build), options,
                                    "jointangle-native-")


@dataclass(frozen=True)
class AvrBoardLauncher:
    """`sim://avr`: the real AVR image run cycle-exactly in simavr (issue 6), its TWI bridged to
    the virtual devices and its USART0 to a pty (firmware/sim/avr_board/README.md).

    Two CMake artefacts: the board, target `ja_avr_board` (build/*/firmware/sim/), and the
    image `jointangle_mega2560.elf`, target `avr_images` (build/*/avr/); found through
    $JOINTANGLE_AVR_BOARD and $JOINTANGLE_AVR_IMAGE or under build/ (build/native first), built
    first when build/native is configured. Started as

        ja_avr_board --rig RIG.toml --motion DATA.csv --baud B [board_args] [extra] IMAGE.elf

    (the native board's options; --fast runs ahead only while the image streams). With
    `elf_path` (sim://avr?elf=IMAGE.elf) it runs that image instead, as `--elf IMAGE.elf`, with
    a fresh EEPROM erased and the UART at the image's own rate unless a baud was given.
    """

    name: str = "avr"
    description: str = "the AVR firmware image in simavr, UART bridged to a pty"
    factory_rate_hz: int = 250  # the Mega's (firmware/platform/avr/board/board.cpp)
    target: str = "ja_avr_board"
    env: str = "JOINTANGLE_AVR_BOARD"
    image: str = "jointangle_mega2560.elf"
    image_target: str = "avr_images"
    image_env: str = "JOINTANGLE_AVR_IMAGE"
    root: Path = REPO_ROOT

    def _locate(self, what: str, pattern: str, target: str, env: str, build: bool) -> Path:
        return _locate_board_part("sim://avr", self.root, what, pattern, target, env, build)

    def find_binary(self, build: bool = False) -> Path:
        return self._locate("the AVR virtual board", f"firmware/sim/{self.target}", self.target,
                            self.env, build)

    def find_image(self, build: bool = False) -> Path:
        return self._locate(f"the AVR image {self.image}", f"avr/{self.image}",
                            self.image_target, self.image_env, build)

    def start(self, options: LaunchOptions) -> RunningBoard:
        binary = self.find_binary(build=options.build)
        options = replace(options, rate_hz=options.rate_hz or self.factory_rate_hz)
        options = _with_clock_stretch(options)
        if options.elf_path is not None:
            if not options.elf_path.is_file():
                raise InputError("the AVR image (elf=) is not a file", path=options.elf_path)
            return _start_virtual_board(binary, options, "jointangle-avr-",
                                        ("--elf", str(options.elf_path)),
                                        baud=options.baud != DEFAULT_BAUD)
        image = self.find_image(build=options.build)
        return _start_virtual_board(binary, options, "jointangle-avr-", (str(image),))


@dataclass(frozen=True)
class PicoBoardLauncher:
    """`sim://pico`: the RP2040 image run in the rp2040js emulator under Node.js, its I2C0 on the
    virtual devices and its UART0 on a pty (firmware/sim/pico_board/README.md).

    The harness is `firmware/sim/pico_board/pico_board.mjs` (npm packages installed beside it
    by scripts/setup.sh); it needs `node`, the image `jointangle_pico.elf` (CMake target
    `pico_images`, build/*/pico/), the bootrom `pico_bootrom.bin` (target `ja_pico_bootrom`) and
    `libja_sim_board.so` (target `ja_sim_board`), each found through its environment variable or
    under build/ and built first when build/native is configured. Started as

        node pico_board.mjs --rig RIG.toml --motion DATA.csv [--baud B] [board_args] [extra]
             --bootrom ROM --board-lib LIB IMAGE.elf

    (--baud only when one other than the host's default was asked for: the line then runs at
    the image's own rate).
    """

    name: str = "pico"
    description: str = "the RP2040 image in the rp2040js emulator, UART0 bridged to a pty"
    factory_rate_hz: int = 800  # the Pico's (firmware/platform/pico/board/board.cpp)
    harness: Path = REPO_ROOT / "firmware" / "sim" / "pico_board" / "pico_board.mjs"
    root: Path = REPO_ROOT

    def _locate(self, what: str, pattern: str, target: str, env: str, build: bool) -> Path:
        return _locate_board_part("sim://pico", self.root, what, pattern, target, env, build)

    def command(self) -> list[str]:
        """`node <harness>`; an InputError in one line when Node.js or the harness's npm packages
        are missing."""
        node = shutil.which("node")
        if node is None:
            raise InputError("sim://pico needs Node.js (>= 18), which is not installed: "
                             "`bash scripts/setup.sh` installs it", field=PORT_FIELD)
        if not (self.harness.parent / "node_modules" / "rp2040js").is_dir():
            raise InputError(f"sim://pico needs the npm packages of {self.harness.parent}, which "
                             "are not installed: `bash scripts/setup.sh` installs them",
                             field=PORT_FIELD)
        return [node, str(self.harness)]

    def start(self, options: LaunchOptions) -> RunningBoard:
        if options.elf_path is not None:
            raise InputError("elf= is the AVR board's: it needs sim://avr, not sim://pico",
                             field=PORT_FIELD)
        command = self.command()
        lib, bootrom, image = (
            self._locate(f"{part.what} {part.filename}", part.pattern, part.target, part.env,
                         options.build)
            for part in (PICO_BOARD_LIB, PICO_BOOTROM, PICO_IMAGE))
        options = replace(options, rate_hz=options.rate_hz or self.factory_rate_hz)
        options = _with_clock_stretch(options)
        # The line at the image's own rate (1 Mbaud) unless a baud was named: the host's
        # default is the Mega's 500 kbaud, too slow for the Pico's stream.
        return _start_virtual_board(command, options, "jointangle-pico-",
                                    ("--bootrom", str(bootrom), "--board-lib", str(lib),
                                     str(image)), baud=options.baud != DEFAULT_BAUD)


SIM_LAUNCHERS: Mapping[str, BoardLauncher] = MappingProxyType({
    "native": NativeBoardLauncher(),
    "avr": AvrBoardLauncher(),
    "pico": PicoBoardLauncher(),
})
