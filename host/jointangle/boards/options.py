"""What a virtual board is started with (`LaunchOptions`), how a `sim://NAME?KEY=VALUE&...`
URL's query sets it (`SIM_QUERY`), and the command-line options every virtual board takes for it
(`board_args`: the native board's, firmware/platform/posix/README.md). The launchers themselves
are in `launchers.py`.
"""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any
from urllib.parse import parse_qsl

from jointangle.errors import InputError

DEFAULT_BAUD = 500_000  # the firmware's UART rate (protocol/README.md: 500 frames/s fit)
SIM_PREFIX = "sim://"
PORT_FIELD = "--port"
MIN_SIM_BAUD = 300  # the virtual boards' UART model
MAX_MOTION_SECONDS = 3600.0  # a generated motion longer than an hour is a typo (500 Hz: 1.8 M rows)


@dataclass(frozen=True)
class LaunchOptions:
    """What a virtual board is started with."""

    scenario: str = "gravity-slow-periodic"
    rig_path: Path | None = None  # a rig file; None: the scenario's own rig
    seed: int = 0
    # The rig's (and so the board's) rate; None: the board's factory rate (its launcher's
    # factory_rate_hz: one the board holds with its factory sensors at >= 20 % asleep).
    rate_hz: int | None = None
    # Length of the generated motion; the board plays it in a loop (`loop`). 60 s is a whole
    # number of periods of the periodic scenarios (0.2, 0.25, 1 Hz), so their loop is seamless,
    # and it is quick to generate and load (600 s took ~2.5 s + ~4 s to start).
    seconds: float = 60.0
    loop: bool = True  # False: hold the last sample at the end
    realtime: bool = True  # simulated clock in real time (people) or as fast as possible
    baud: int = DEFAULT_BAUD
    motion_path: Path | None = None  # an accelerations CSV to play instead (needs rig_path)
    eeprom_path: Path | None = None  # the board's EEPROM image (kept); None: a fresh one
    # sim://avr only: run this Mega image (a user's sketch) instead of the project's firmware
    elf_path: Path | None = None
    cold_start: bool = False  # the parts power up with the board (a BNO055 boots 650 ms)
    # sim://avr only: clock stretching, (7-bit address, microseconds) before each read's answer
    clock_stretch: tuple[tuple[int, int], ...] = ()
    faults: tuple[str, ...] = ()  # sensor faults, SENSOR:KIND[=PARAM]@START[-END]
    disconnect_after_s: float | None = None  # pull the cable after this much simulated time
    reconnect_after_s: float | None = None  # and plug it back in this many seconds later
    extra_args: tuple[str, ...] = ()
    start_timeout_s: float = 60.0  # first build included
    build: bool = True  # build the board's CMake target if a configured build tree exists


FAULT_SPEC_RE = re.compile(r"^([ab]\.\d+|mux):(nack|wrong_id|saturate|frozen)(=\d+)?@"
                           r"(\d+(?:\.\d*)?)(?:-(\d+(?:\.\d*)?))?$")

# The query keys of a sim:// URL: (what it sets, help). `jointangle live --help` lists them.
SIM_QUERY: Mapping[str, str] = MappingProxyType({
    "fast": "1: simulated time as fast as the host reads while streaming (default 0: real time)",
    "fault": "SENSOR:KIND[=PARAM]@START[-END] a sensor fault in simulated seconds, repeatable; "
             "SENSOR a.0, a.1, b.0, ... or mux, KIND nack, wrong_id, saturate or frozen "
             "(e.g. fault=a.0:nack@2-4)",
    "scenario": "the motion to play (as --scenario)",
    "seed": "noise seed (as --seed)",
    "seconds": "seconds of motion to generate (as --sim-seconds)",
    "loop": "1 (default): play the motion in a loop; 0: hold its last sample",
    "rate": "the rig's sample rate for the generated motion, Hz (default: the board's factory "
            "rate, native 500, avr 250, pico 800)",
    "rig": "RIG.toml: the board's rig (as --rig)",
    "motion": "DATA.csv: play this accelerations CSV (with rig=) instead of a scenario",
    "eeprom": "FILE: the board's EEPROM image, kept across runs (default: a fresh one)",
    "elf": "IMAGE.elf: sim://avr runs this ATmega2560 image (your own Arduino sketch) on the "
           "same rig, motion, faults and pty instead of the project's firmware; its UART runs at "
           "the rate the sketch sets unless baud= names one (firmware/sim/avr_board/README.md)",
    "baud": "the board's UART rate (as --baud)",
    "cold": "1: the parts power up with the board, a BNO055 answering after its 650 ms boot "
            "(default 0: booted; 1 with elf=)",
    "stretch": "ADDR=US: sim://avr, the slave at ADDR holds SCL US microseconds before it "
               "answers a read (clock stretching, as a BNO055 does; e.g. stretch=0x28=400), "
               "repeatable",
    "disconnect": "S: pull the cable after S simulated seconds",
    "reconnect": "S: with disconnect, plug it back in S seconds later",
})


def sim_query_help() -> str:
    return "; ".join(f"{k}: {v}" for k, v in SIM_QUERY.items())


def split_sim_url(url: str) -> tuple[str, list[tuple[str, str]]]:
    """`sim://NAME?k=v&...` -> (NAME, [(k, v), ...]) in order; unknown keys are refused."""

    rest = url[len(SIM_PREFIX):]
    name, _, query = rest.partition("?")
    try:
        pairs = parse_qsl(query, keep_blank_values=True, strict_parsing=bool(query))
    except ValueError:
        raise InputError(f"{url}: cannot read the query {query!r} (KEY=VALUE&...)",
                         field=PORT_FIELD) from None
    for k, _ in pairs:
        if k not in SIM_QUERY:
            raise InputError(f"{url}: unknown option {k!r}; sim:// options: "
                             + ", ".join(SIM_QUERY), field=PORT_FIELD)
    return name, pairs


def apply_sim_query(options: LaunchOptions, pairs: Sequence[tuple[str, str]],
                    url: str = "") -> LaunchOptions:
    """The launch options with a sim:// URL's query applied (see SIM_QUERY)."""
    def bad(key: str, value: str, what: str) -> InputError:
        return InputError(f"{url}: {key}={value!r}: {what}", field=PORT_FIELD)

    def number(key: str, value: str, lo: float, integer: bool = False,
               hi: float = float("inf")) -> float:
        try:
            v = float(int(value)) if integer else float(value)
        except ValueError:
            raise bad(key, value, "not a number") from None
        if not v >= lo or v != v or v in (float("inf"), float("-inf")):
            raise bad(key, value, f"must be at least {lo:g}")
        if v > hi:
            raise bad(key, value, f"must be at most {hi:g}")
        return v

    def flag(key: str, value: str) -> bool:
        if value not in ("0", "1", "true", "false", "yes", "no", ""):
            raise bad(key, value, "expected 1 or 0")
        return value in ("1", "true", "yes", "")

    changes: dict[str, Any] = {}
    faults = list(options.faults)
    stretch = list(options.clock_stretch)
    for key, value in pairs:
        if key == "fast":
            changes["realtime"] = not flag(key, value)
        elif key == "loop":
            changes["loop"] = flag(key, value)
        elif key == "cold":
            changes["cold_start"] = flag(key, value)
        elif key == "stretch":
            addr, _, us = value.partition("=")
            try:
                pair = (int(addr, 0), int(us))
            except ValueError:
                raise bad(key, value, "expected ADDR=US (e.g. 0x28=400)") from None
            if not (0 <= pair[0] <= 0x7F and 0 <= pair[1] <= 100_000):
                raise bad(key, value, "ADDR 0..0x7f, US 0..100000")
            stretch.append(pair)
        elif key == "fault":
            m = FAULT_SPEC_RE.match(value)
            if m is None or (m.group(5) is not None and
                             not float(m.group(5)) > float(m.group(4))):
                raise bad(key, value, "expected SENSOR:KIND[=PARAM]@START[-END] with END > "
                          "START, SENSOR a.N, b.N or mux, KIND nack, wrong_id, saturate or "
                          "frozen (e.g. a.0:nack@2-4)")
            faults.append(value)
        elif key == "scenario":
            changes["scenario"] = value
        elif key == "seed":
            changes["seed"] = int(number(key, value, 0, integer=True))
        elif key == "seconds":
            changes["seconds"] = number(key, value, 0.01, hi=MAX_MOTION_SECONDS)
        elif key == "rate":
            # The firmware's set_rate range (APP.md): refused here, before a motion is made.
            changes["rate_hz"] = int(number(key, value, 10, integer=True, hi=1000))
        elif key == "baud":
            changes["baud"] = int(number(key, value, MIN_SIM_BAUD, integer=True))
        elif key in ("rig", "motion", "eeprom", "elf"):
            if not value:
                raise bad(key, value, "needs a file name")
            changes[{"rig": "rig_path", "motion": "motion_path", "eeprom": "eeprom_path",
                     "elf": "elf_path"}[key]] = Path(value).expanduser()
        elif key == "disconnect":
            changes["disconnect_after_s"] = number(key, value, 0)
        elif key == "reconnect":
            changes["reconnect_after_s"] = number(key, value, 0)
    changes["faults"] = tuple(faults)
    changes["clock_stretch"] = tuple(stretch)
    out = dataclasses.replace(options, **changes)
    if out.motion_path is not None and out.rig_path is None:
        raise InputError(f"{url}: motion= needs the rig it was made for (rig= or --rig)",
                         field=PORT_FIELD)
    if out.reconnect_after_s is not None and out.disconnect_after_s is None:
        raise InputError(f"{url}: reconnect= needs disconnect=", field=PORT_FIELD)
    return out


def board_args(options: LaunchOptions) -> list[str]:
    """The board options every virtual board takes (the native board's command line: fast
    clock, motion loop, EEPROM file, sensor faults, cable pull)."""
    out: list[str] = []
    if not options.realtime:
        out.append("--fast")
    if options.loop:  # a given motion too, as `loop`'s help says (it used to play once)
        out.append("--loop-motion")
    if options.cold_start:
        out.append("--cold-start")
    if options.eeprom_path is not None:
        out += ["--eeprom", str(options.eeprom_path)]
    for f in options.faults:
        out += ["--fault", f]
    if options.disconnect_after_s is not None:
        out += ["--disconnect-after", f"{options.disconnect_after_s:g}"]
    if options.reconnect_after_s is not None:
        out += ["--reconnect-after", f"{options.reconnect_after_s:g}"]
    return out
