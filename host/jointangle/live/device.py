"""What the device holds, seen from the host: its hello, its calibrated readings, its filter.

`replay --verify` and `live` compare every firmware estimate with the host's float `mirror` of
the firmware filter (docs/design.md §3, §5). For that comparison to mean anything, `mirror` must see
the *same quantised inputs* the firmware filtered, and start where the firmware's filter started:

- Inputs. The firmware turns raw counts into link-frame Q15.16 readings with a per-sensor map
  computed in float32 at configuration (firmware/app/APP.md, "Calibration in fixed point"):
  M = R(rot)[x, y rows]·S·scale rounded to Q30, b = R(rot)[x, y rows]·o rounded to Q16, then per
  sample a = round_half_up((b·2¹⁴ + Σ M·counts) / 2¹⁴). `device_readings` does exactly that, so
  mirror's own Q15.16 rounding (`quantise_inputs`) is the identity on them. Scaling counts by the
  LSB in float64 and rounding once (what `sensor_to_link` + mirror do on their own) differs from
  this by one LSB whenever the float32 coefficient or the single rounding lands elsewhere.
- Noise model and rate. With `set_filter.accel_sigma` = 0 (the default) the firmware's Q̂ is
  the datasheet density on x/y at its own rate plus LSB²/12, whatever the rig file says for the
  simulator: `device_rig` builds that rig (rate from hello, datasheet noise, positions in µm).
- Start. The firmware's filter runs from boot; a stream shows its (re)starts as health `reset`.
  `mirror` is run per *segment*: from a `reset` frame, as long as the filter is `running`, no
  frame is missing (a sequence gap means steps the host never saw) and the sensor choice stays.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from jointangle.errors import InputError
from jointangle.estimators.mirror import MAX_SENSORS_PER_LINK, MIN_SENSORS_PER_LINK
from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import text_of
from jointangle.recording.firmware_verify import DeviceMaps, mps2_per_count
from jointangle.rig import LinkConfig, Rig, SensorConfig

if TYPE_CHECKING:
    from jointangle.estimators.mirror import MirrorState

THETA_LSB = 2.0**-24  # rad (sample_estimate.theta, Q24)
OMEGA_LSB = 2.0**-16  # rad/s (Q16)
FAULT_BITS = (msgs.SensorStatus.NACK | msgs.SensorStatus.WRONG_ID | msgs.SensorStatus.SATURATED
              | msgs.SensorStatus.FROZEN | msgs.SensorStatus.BAD_CALIBRATION)
# The names of FAULT_BITS (flag_names), as the live view and line show them.
FAULT_NAMES = ("nack", "wrong_id", "saturated", "frozen", "bad_calibration")
STEADY_AFTER_S = 2.0  # docs/design.md §5: the tight parity bounds hold from 2 s after a start


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
        } for s in hello.sensors],
    }


# ---------------------------------------------------------------------------------------------
# The firmware's rig and readings


def _check_inventory(rig: Rig, hello: msgs.Hello) -> None:
    sensors = rig.all_sensors()
    if len(sensors) != len(hello.sensors):
        raise InputError(f"the rig has {len(sensors)} sensors, the device reports "
                         f"{len(hello.sensors)}", field="rig")
    for (link, i, s), h in zip(sensors, hello.sensors, strict=True):
        where = f"links.{link}.sensors[{i}]"
        dev_link = "a" if h.link == 0 else "b"
        dev_model = enum_name(msgs.SensorModel, h.model)
        if dev_link != link or dev_model != s.model or h.range_g != s.range_g:
            raise InputError(f"rig says {s.model} ±{s.range_g} g on link {link}, the device "
                             f"has {dev_model} ±{h.range_g} g on link {dev_link}", field=where)


def _um(v: float) -> float:
    return round(v * 1e6) / 1e6


def device_rig(rig: Rig, hello: msgs.Hello) -> Rig:
    """The rig as the firmware's filter sees it: its rate, positions in µm, datasheet noise on
    x/y with quantisation (what `set_filter.accel_sigma = 0` means)."""
    _check_inventory(rig, hello)

    def sensor(s: SensorConfig) -> SensorConfig:
        return dataclasses.replace(s, position=(_um(s.position[0]), _um(s.position[1])),
                                   noise_density_ug=None, quantize=True)

    links = {name: LinkConfig(joint=(_um(lc.joint[0]), _um(lc.joint[1])),
                              sensors=tuple(sensor(s) for s in lc.sensors))
             for name, lc in rig.links.items()}
    rate = float(hello.sample_rate_hz) if hello.sample_rate_hz else rig.sample_rate_hz
    return dataclasses.replace(rig, links=links, sample_rate_hz=rate)


# The firmware's calibration map and float32 m/s² per count (firmware/app/sensor.cpp), one
# implementation shared with `replay --verify-firmware`.
CalibrationMaps = DeviceMaps
firmware_mps2_per_count = mps2_per_count


def device_readings(maps: CalibrationMaps, counts: np.ndarray) -> np.ndarray:
    """Link-frame x, y readings (T, 2n) in m/s² from raw counts (T, n, 3), bit-exact with the
    firmware's Q15.16 (round half up, saturated to int32)."""
    raw = maps.readings_q16(counts)
    return (raw.reshape(raw.shape[0], -1) / 65536.0).astype(float)


def counts_from_readings(rig: Rig, readings: np.ndarray) -> np.ndarray:
    """Sensor-frame m/s² (T, n, 3) as integer counts (simulators and fakes)."""
    lsb = np.array([float(firmware_mps2_per_count(s.model, s.range_g))
                    for _, _, s in rig.all_sensors()])
    return np.round(np.asarray(readings) / lsb[None, :, None]).astype(np.int64)




def filter_choice(rig: Rig, status: Iterable[int]) -> tuple[int, ...]:
    """Sensor indices (rig order) the firmware filters: the first four usable per link."""
    st = list(status)
    chosen: list[int] = []
    k = 0
    for name in ("a", "b"):
        n = rig.sensor_count(name)
        usable = [k + i for i in range(n) if not st[k + i] & FAULT_BITS][:MAX_SENSORS_PER_LINK]
        chosen += usable
        k += n
    return tuple(chosen)


def filter_runs(rig: Rig, chosen: tuple[int, ...]) -> bool:
    """Whether the firmware's filter runs on this choice: at least two usable sensors per link."""
    na = rig.sensor_count("a")
    in_a = sum(1 for i in chosen if i < na)
    return min(in_a, len(chosen) - in_a) >= MIN_SENSORS_PER_LINK


def sub_rig(rig: Rig, chosen: tuple[int, ...]) -> Rig:
    links: dict[str, LinkConfig] = {}
    k = 0
    for name in ("a", "b"):
        lc = rig.links[name]
        keep = tuple(s for i, s in enumerate(lc.sensors) if k + i in chosen)
        links[name] = LinkConfig(joint=lc.joint, sensors=keep)
        k += len(lc.sensors)
    return dataclasses.replace(rig, links=links)


def mirror_theta(rig: Rig, maps: CalibrationMaps, counts: np.ndarray,
                 chosen: tuple[int, ...], state: MirrorState | None = None,
                 periods: np.ndarray | None = None) -> np.ndarray:
    """`mirror`'s θ (rad) for one segment of counts (T, n, 3) on the chosen sensors; with
    `state` (MirrorState.fresh(1) at the segment's start) the segment goes on from where the
    last call with that state stopped. periods (T,): each step's sample periods
    (`mirror.step_periods` of the frames' t_us); None = 1 each."""
    from jointangle.estimators.base import wrap
    from jointangle.estimators.mirror import MirrorSettings, quantise_inputs, run_mirror

    readings = device_readings(maps, counts)
    cols = [c for i in chosen for c in (2 * i, 2 * i + 1)]
    xs, _ = run_mirror(MirrorSettings.from_rig(sub_rig(rig, chosen)),
                       quantise_inputs(readings[:, cols][None]), state=state, periods=periods)
    return np.asarray(wrap(xs[..., 2])).reshape(-1)


@dataclass(frozen=True)
class Segment:
    start: int  # index into the sample_estimate columns
    stop: int
    chosen: tuple[int, ...]


def segments(health: np.ndarray, status: np.ndarray, lost_before: np.ndarray,
             rig: Rig) -> list[Segment]:
    """Runs of sample_estimate frames one `mirror` run can follow (see the module docstring).

    health (T,), status (T, n) per frame; lost_before (T,) = frames missing just before each
    one. A segment starts at a frame with health `reset` and `running`.
    """
    out: list[Segment] = []
    start: int | None = None
    chosen: tuple[int, ...] = ()
    T = int(health.shape[0])
    for k in range(T):
        h = int(health[k])
        running = bool(h & msgs.FilterHealth.RUNNING)
        if start is not None:
            now = filter_choice(rig, status[k])
            if (not running or h & msgs.FilterHealth.RESET or lost_before[k] or now != chosen):
                out.append(Segment(start, k, chosen))
                start = None
        if start is None and running and h & msgs.FilterHealth.RESET:
            start, chosen = k, filter_choice(rig, status[k])
    if start is not None:
        out.append(Segment(start, T, chosen))
    return out


@dataclass
class VerifyResult:
    dtheta_deg: np.ndarray  # firmware − mirror, over every verified frame
    steady_dtheta_deg: np.ndarray  # the part from STEADY_AFTER_S after each start
    verified_frames: int
    unverified_frames: int
    segments: int

    def as_dict(self) -> dict[str, Any]:
        d, s = self.dtheta_deg, self.steady_dtheta_deg
        return {
            "max_abs_dtheta_deg": float(np.max(np.abs(d))) if d.size else None,
            "rms_dtheta_deg": float(np.sqrt(np.mean(d**2))) if d.size else None,
            "steady_max_abs_dtheta_deg": float(np.max(np.abs(s))) if s.size else None,
            "steady_rms_dtheta_deg": float(np.sqrt(np.mean(s**2))) if s.size else None,
            "verified_frames": self.verified_frames,
            "unverified_frames": self.unverified_frames,
            "segments": self.segments,
        }


def verify_columns(rig: Rig, hello: msgs.Hello, cols: dict[str, np.ndarray],
                   lost_before: np.ndarray) -> VerifyResult:
    """Firmware θ against `mirror` on sample_estimate columns (bulk decoder layout)."""
    from jointangle.estimators.base import wrap
    from jointangle.estimators.mirror import step_periods

    drig = device_rig(rig, hello)
    maps = CalibrationMaps.from_rig(drig)
    counts = np.stack([cols["sensors.x"], cols["sensors.y"], cols["sensors.z"]], axis=2)
    if counts.shape[1] != len(hello.sensors):
        raise InputError(f"frames carry {counts.shape[1]} sensors, the hello lists "
                         f"{len(hello.sensors)}", field="sample_estimate")
    segs = segments(cols["health"], cols["sensors.status"], lost_before, drig)
    steady_k = round(STEADY_AFTER_S * drig.sample_rate_hz)
    ds, steady = [], []
    verified = 0
    for seg in segs:
        if not filter_runs(drig, seg.chosen):
            continue
        periods = step_periods(cols["t_us"][seg.start:seg.stop], drig.sample_rate_hz)
        host = mirror_theta(drig, maps, counts[seg.start:seg.stop], seg.chosen, periods=periods)
        fw = cols["theta"][seg.start:seg.stop].astype(float) * THETA_LSB
        d = np.degrees(wrap(fw - host))
        ds.append(d)
        # Steady from STEADY_AFTER_S of the run's time: periods, not frames (an overrunning
        # board steps over several periods a frame).
        steady.append(d[np.cumsum(periods) - 1 >= steady_k])
        verified += d.size
    cat = np.concatenate(ds) if ds else np.zeros(0)
    st = np.concatenate(steady) if steady else np.zeros(0)
    return VerifyResult(cat, st, verified, int(counts.shape[0]) - verified, len(ds))
