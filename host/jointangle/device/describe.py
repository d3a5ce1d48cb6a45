"""What a board's hello and status say, in words: names for its codes and flags, what to tell
a user about its EEPROM, and the loop rate it can sustain."""

from __future__ import annotations

import dataclasses
from typing import Any

from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import text_of

# The names of rig.FAULT_BITS (flag_names), as the live view and line show them.
FAULT_NAMES = ("nack", "wrong_id", "saturated", "frozen", "bad_calibration")

CAPACITY_MARGIN = 0.87  # a loop's busy time varies: at 92 % of the period the Mega overran
CAPACITY_STEP_HZ = 10


def sustainable_rate_hz(status: msgs.Status) -> int | None:
    """The loop rate the board should hold, from its own status: it measured `idle_permille`
    asleep at `loop_rate_hz`, so a loop keeps it busy (1 - idle) / loop_rate seconds and it fits
    about loop_rate / (1 - idle) loops a second; CAPACITY_MARGIN of that, rounded down to
    CAPACITY_STEP_HZ. None before the board has measured (rate 0) or when it reports no busy
    time. (The Mega on sim://avr with four ADXL345 behind the multiplexer, asked for 500 Hz in
    `live`: 250 Hz at 36.1 % asleep, 2.56 ms busy a loop -> 340 Hz, which it holds at 13 %
    asleep; at 360 Hz, 92 % busy, it overran: the 0.93 used before suggested that.)"""
    if status.sustainable_rate_hz:  # the board's own figure (0.8 of its capacity: >= 20 % asleep)
        return int(status.sustainable_rate_hz)
    busy = 1.0 - status.idle_permille / 1000.0
    if status.loop_rate_hz <= 0 or busy <= 0.0:
        return None
    fits = CAPACITY_MARGIN * status.loop_rate_hz / busy
    return int(fits // CAPACITY_STEP_HZ) * CAPACITY_STEP_HZ


def flag_names(flags: type[msgs.SensorStatus] | type[msgs.FilterHealth] | type[msgs.StreamMode],
               value: int) -> list[str]:
    return [str(f.name).lower() for f in flags if f.value & value]


def enum_name(enum: Any, value: int) -> str:
    try:
        return str(enum(value).name).lower()
    except ValueError:
        return f"unknown ({value})"


def hello_record(hello: msgs.Hello) -> dict[str, Any]:
    """The hello as plain JSON with raw values (recording metadata; `find_hello` reads it back)."""
    doc = dataclasses.asdict(hello)
    doc["build"] = text_of(hello.build)
    return doc


EEPROM_WARNINGS = {
    msgs.EepromState.BAD_CHECKSUM_DEFAULTS: "the EEPROM image failed its checksum: the board "
    "runs on factory defaults (configure it again and save_eeprom)",
    msgs.EepromState.NEWER_LAYOUT_DEFAULTS: "the EEPROM holds a newer layout than this "
    "firmware reads: the board runs on factory defaults",
    msgs.EepromState.EMPTY_DEFAULTS: "the EEPROM is empty: the board runs on factory defaults",
}


def eeprom_warning(state: int) -> str | None:
    """What to tell a user about the EEPROM state in hello/status (None when it is ok)."""
    if state == msgs.EepromState.OK:
        return None
    return EEPROM_WARNINGS.get(msgs.EepromState(state)) if state in list(msgs.EepromState) \
        else f"unknown EEPROM state {state}"


def eeprom_problem(state: int) -> str | None:
    """eeprom_warning for an EEPROM that failed (bad checksum, newer layout, unknown state),
    None also for an empty one: a board never saved to (every virtual board without an
    `eeprom=` file) runs on its defaults as expected."""
    return None if state == msgs.EepromState.EMPTY_DEFAULTS else eeprom_warning(state)


def hello_doc(hello: msgs.Hello) -> dict[str, Any]:
    """The hello for people and scripts (`info --json`): names instead of codes."""
    return {
        "firmware_version": f"{hello.firmware_major}.{hello.firmware_minor}."
                            f"{hello.firmware_patch}",
        "protocol_version": hello.protocol_version,
        "schema_hash": f"0x{hello.schema_hash:08X}",
        "build": text_of(hello.build),
        "board": enum_name(msgs.Board, hello.board),
        "sample_rate_hz": hello.sample_rate_hz,
        "stream_mode": flag_names(msgs.StreamMode, hello.stream_mode),
        "eeprom": enum_name(msgs.EepromState, hello.eeprom),
        "eeprom_warning": eeprom_warning(hello.eeprom),
        "sensors": [{
            "link": "a" if s.link == 0 else "b",
            "model": enum_name(msgs.SensorModel, s.model),
            "mux_channel": None if s.mux_channel == 255 else s.mux_channel,
            "address": f"0x{s.address:02X}",
            "chip_id": f"0x{s.chip_id:02X}",
            "range_g": s.range_g,
            "status": flag_names(msgs.SensorStatus, s.status),
            "read_delay_us": s.read_delay_us,
        } for s in hello.sensors],
    }
