"""The rig as built, not as drawn: build errors the simulator applies and the estimators never see.

A rig file gives the nominal geometry (sensor `position`, `rotation_deg`, link `joint`): what
the drawing says. A real build is off by millimetres and fractions of a degree, and a
multiplexed loop reads its sensors one after another. These simulation-only rig fields hold
the difference (the estimators read only the nominal fields; `sim_*` fields are the
simulator's alone):

  sensor  sim_position_offset_m   true position = position + offset            (m, link frame)
          sim_rotation_offset_deg true in-plane mounting = rotation_deg + offset (°, about z)
          sim_read_skew_s         row k's sample is read at t_k + skew           (s)
          sim_clock_ppm, _phase   the part's own conversion clock (sensor_timing.part_clock)
  link    sim_joint_offset_m      true hinge O = joint + offset                   (m, link frame)

To the sensors a joint offset δ is a common shift of the link's sensors by −δ (only r_i − r_O
enters the rigid-body model a_i = a_O + D(r_i − r_O) y), and the simulator applies it so: the
mechanism (the hinge's path, the links' angles) is the scenario's, the sensors sit at
r_i + Δr_i − δ in its link frame.

Levels (`AS_BUILT_LEVELS`), every error drawn uniformly and independently per axis and per
sensor from the build seed (`build_rng`: the noise seed and a fixed stream id, so seed s of an
as-built scenario is one build, the same on every run):

  as-built        positions ±2 mm, joints ±2 mm, mountings ±0.2° (what remains after the
                  static-pose calibration, `jointangle calibrate`), read skew of the board
  as-built-uncal  the same with mountings ±1° (no static calibration)
  as-built-clocks as-built, and each part on its own conversion clock (sim_clock_ppm within
                  ±CLOCK_PPM, sim_clock_phase uniform; sensor_timing.part_clock): a read
                  returns the latest conversion, and read_delay_s says the mean, the read
                  offset less half a conversion period (`mean_conversion_age_s`)

Read skew: the AVR board reads its sensors in one I2C batch per loop, in rig order (links a
then b), at 400 kHz; measured, four ADXL345 behind a TCA9548A take 41.2 bytes a loop
(firmware/app/APP.md, `bench firmware`), 9 SCL periods a byte: 10.3 bytes = 232 µs per sensor.
Sensor k of the loop is read `k · BOARD_SKEW_PER_SENSOR_S` after the first; the first is
taken at the row's time (the latency common to all sensors is `--sensor-timing board:L`'s
business, sim/sensor_timing.py).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from jointangle.rig import LINK_NAMES, Rig, SensorConfig
from jointangle.sim.sensor_timing import odr_period_ns

BUS_HZ = 400_000.0
BUS_BYTES_PER_SENSOR = 41.2 / 4  # APP.md: 41.2 bytes a loop for four ADXL345 (select + read)
SCL_PER_BYTE = 9
BOARD_SKEW_PER_SENSOR_S = BUS_BYTES_PER_SENSOR * SCL_PER_BYTE / BUS_HZ  # 232 µs
BUILD_STREAM = 21  # second word of the build RNG's seed: independent of the noise stream


# The parts' own conversion clocks (level as-built-clocks): each part converts on its on-chip
# oscillator, phase uniform over a period, frequency off by up to this much. ADI gives no
# tolerance for the ADXL345's output data rate; ±2 % is what on-chip RC oscillators of this
# class hold. Closer clocks drift their phases apart more slowly and cost more, the age error
# then a slow bias (docs/as-built.md).
CLOCK_PPM = 20_000.0


@dataclass(frozen=True)
class BuildErrors:
    """Magnitudes of one as-built level (uniform ±bound per axis / per sensor)."""

    name: str
    position_m: float
    joint_m: float
    mounting_deg: float
    skew_per_sensor_s: float
    description: str
    clock_ppm: float | None = None  # free-running part clocks (±ppm, any phase); None: in step


AS_BUILT_LEVELS: dict[str, BuildErrors] = {
    "as-built": BuildErrors(
        "as-built", 0.002, 0.002, 0.2, BOARD_SKEW_PER_SENSOR_S,
        "positions and joints ±2 mm, mountings ±0.2° (after static calibration), "
        f"board read skew {BOARD_SKEW_PER_SENSOR_S * 1e3:.3f} ms a sensor"),
    "as-built-uncal": BuildErrors(
        "as-built-uncal", 0.002, 0.002, 1.0, BOARD_SKEW_PER_SENSOR_S,
        "positions and joints ±2 mm, mountings ±1° (no static calibration), "
        f"board read skew {BOARD_SKEW_PER_SENSOR_S * 1e3:.3f} ms a sensor"),
    "as-built-clocks": BuildErrors(
        "as-built-clocks", 0.002, 0.002, 0.2, BOARD_SKEW_PER_SENSOR_S,
        "as `as-built`, and each part converting on its own clock (any phase, "
        f"±{CLOCK_PPM:.0f} ppm): the loop reads its latest conversion", CLOCK_PPM),
}


def build_rng(seed: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), BUILD_STREAM])


def clock_rng(seed: int) -> np.random.Generator:
    """The part clocks' own stream: a level with clocks has the same geometry as without."""
    return np.random.default_rng([int(seed), BUILD_STREAM, 1])


def mean_conversion_age_s(sensor: SensorConfig, rate_hz: float) -> float:
    """How old the latest conversion is on average when the loop reads it: half the part's
    nominal conversion period (the read falls anywhere in it). The board knows the ODR it set."""
    return 0.5 * odr_period_ns(sensor.model, rate_hz) * 1e-9


def as_built_rig(rig: Rig, seed: int, level: str = "as-built") -> Rig:
    """`rig` with build errors of `level` drawn from `seed` in its sim_* fields (nominal fields
    unchanged)."""
    e = AS_BUILT_LEVELS[level]
    rng = build_rng(seed)
    clocks = clock_rng(seed)
    links = {}
    k = 0
    for ln in LINK_NAMES:
        link = rig.links[ln]
        joint = rng.uniform(-e.joint_m, e.joint_m, 2)
        sensors = []
        for s in link.sensors:
            dp = rng.uniform(-e.position_m, e.position_m, 2)
            rot = float(rng.uniform(-e.mounting_deg, e.mounting_deg))
            s = replace(s, sim_position_offset_m=(float(dp[0]), float(dp[1])),
                        sim_rotation_offset_deg=rot, sim_read_skew_s=k * e.skew_per_sensor_s,
                        read_delay_s=k * e.skew_per_sensor_s)
            if e.clock_ppm is not None:
                # The sample is the latest conversion before the read, on average half a
                # conversion period older than the read: the board's best knowledge of it.
                s = replace(s, sim_clock_ppm=float(clocks.uniform(-e.clock_ppm, e.clock_ppm)),
                            sim_clock_phase=float(clocks.uniform(0.0, 1.0)),
                            read_delay_s=s.read_delay_s - mean_conversion_age_s(
                                s, rig.sample_rate_hz))
            sensors.append(s)
            k += 1
        links[ln] = replace(link, sensors=tuple(sensors),
                            sim_joint_offset_m=(float(joint[0]), float(joint[1])))
    return replace(rig, links=links)


def true_positions(rig: Rig, link: str) -> np.ndarray:
    """Sensor positions (N, 2) as built, in the nominal joint's frame: r_i + Δr_i − δ."""
    cfg = rig.links[link]
    pos = cfg.positions()
    for i, s in enumerate(cfg.sensors):
        if s.sim_position_offset_m is not None:
            pos[i] += np.asarray(s.sim_position_offset_m)
    if cfg.sim_joint_offset_m is not None:
        pos -= np.asarray(cfg.sim_joint_offset_m)
    return pos


def has_build_errors(rig: Rig) -> bool:
    return any(rig.links[ln].sim_joint_offset_m is not None for ln in LINK_NAMES) or any(
        s.sim_position_offset_m is not None or s.sim_rotation_offset_deg is not None
        or s.sim_read_skew_s is not None or s.sim_clock_ppm is not None
        or s.sim_clock_phase is not None for _, _, s in rig.all_sensors())


def nominal_rig(rig: Rig) -> Rig:
    """`rig` with every as-built field cleared (what the drawing says)."""
    links = {ln: replace(rig.links[ln], sim_joint_offset_m=None, sensors=tuple(
        replace(s, sim_position_offset_m=None, sim_rotation_offset_deg=None,
                sim_read_skew_s=None, sim_clock_ppm=None, sim_clock_phase=None)
        for s in rig.links[ln].sensors)) for ln in LINK_NAMES}
    return replace(rig, links=links)


BUILD_SOURCES = ("positions", "mountings", "joints", "skew", "clocks")


def only_sources(rig: Rig, sources: tuple[str, ...] | list[str]) -> Rig:
    """`rig` as built with only these error sources of BUILD_SOURCES kept (the others cleared):
    one error source at a time, to see what each costs."""
    unknown = set(sources) - set(BUILD_SOURCES)
    if unknown:
        raise ValueError(f"unknown build error sources {sorted(unknown)}; known: "
                         f"{', '.join(BUILD_SOURCES)}")
    keep = set(sources)
    links = {ln: replace(
        rig.links[ln],
        sim_joint_offset_m=rig.links[ln].sim_joint_offset_m if "joints" in keep else None,
        sensors=tuple(replace(
            s, sim_position_offset_m=s.sim_position_offset_m if "positions" in keep else None,
            sim_rotation_offset_deg=s.sim_rotation_offset_deg if "mountings" in keep else None,
            sim_read_skew_s=s.sim_read_skew_s if "skew" in keep else None,
            sim_clock_ppm=s.sim_clock_ppm if "clocks" in keep else None,
            sim_clock_phase=s.sim_clock_phase if "clocks" in keep else None,
            read_delay_s=_known_delay(s, rig.sample_rate_hz, keep))
            for s in rig.links[ln].sensors)) for ln in LINK_NAMES}
    return replace(rig, links=links)


def _known_delay(s: SensorConfig, rate_hz: float, keep: set[str]) -> float:
    """The read_delay_s a board knows for s when only the sources in keep are built in: the
    read skew (skew) less the mean conversion age (clocks)."""
    clocked = s.sim_clock_ppm is not None or s.sim_clock_phase is not None
    age = mean_conversion_age_s(s, rate_hz) if clocked else 0.0
    skew = s.read_delay_s + age  # the read offset alone
    return (skew if "skew" in keep else 0.0) - (age if "clocks" in keep else 0.0)


def split_variant(name: str) -> tuple[str, str | None]:
    """'gravity-ramp-as-built' -> ('gravity-ramp', 'as-built'); a plain name -> (name, None)."""
    for level in sorted(AS_BUILT_LEVELS, key=len, reverse=True):
        if name.endswith("-" + level):
            return name[: -len(level) - 1], level
    return name, None
