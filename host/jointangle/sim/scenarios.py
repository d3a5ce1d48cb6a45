"""Named simulation scenarios (docs/design.md §5) and the simulator that runs them.

paper-table2-L{30,20,10}: the paper's slider-crank (Appendix III), L_a = L, L_b = 2L, two
sensors per link at 0 and L/2 from the joint, crank θ_a = 45° sin(2π·0.2 Hz·t), 30 s at 100 Hz,
400 µg/√Hz white noise, no quantisation, horizontal mechanism (gravity out of the plane).

gravity-*: the paper's bench (§V): two 30 cm links on a horizontal hinge, link a clamped
level to the bench, sensors 4.75 cm and 27.5 cm from the joint on each link, ADXL345 ±2 g
with its datasheet noise (290/290/430 µg/√Hz) and 3.9 mg quantisation. Link b's world angle:
  slow-periodic  −45° + 35° sin(2π·0.25 Hz·t)
  fast-periodic  −45° + 30° sin(2π·1.0 Hz·t)
  ramp           minimum-jerk moves of 60° lasting 2 s, 2 s pauses between them
  impulse        minimum-jerk moves of 30° lasting 0.35 s, 2.5 s pauses between them

gravity-free-motion (a calibration motion, not one of the benchmark's scenarios): the same
bench with link a's far end on a pivot, both links swinging freely through sums of sines
  link a   0° + 30° sin(2π·0.31 Hz·t) + 15° sin(2π·0.97 Hz·t + 1)
  link b −45° + 35° sin(2π·0.23 Hz·t) + 20° sin(2π·0.71 Hz·t + 2) + 8° sin(2π·1.9 Hz·t + 0.5)
for `jointangle calibrate --method motion` (calibration/motion.py), and gravity-reference-pose:
the same rig held still and straight (θ = 0, both links level), the joint's zero that motion
cannot see (calibration/reference.py, `--reference`).

Every scenario NAME also has the variants NAME-as-built and NAME-as-built-uncal: the same
nominal rig (what the estimators read) with build errors drawn from the seed in its sim_*
fields, which the simulator uses (sim/as_built.py: positions, joints, mountings, read skew).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from jointangle.errors import InputError
from jointangle.rig import LinkConfig, Rig, SensorConfig
from jointangle.sensors import STANDARD_GRAVITY
from jointangle.sim.as_built import AS_BUILT_LEVELS, as_built_rig, split_variant, true_positions
from jointangle.sim.mechanism import MechanismState, slider_crank, specific_force_link, two_link
from jointangle.sim.motion import Constant, MinimumJerkMoves, Motion, Sine, SineSum
from jointangle.sim.sensor_model import sensor_reading
from jointangle.sim.sensor_timing import conversion_instants, odr_period_ns, part_clock

DEFAULT_RATE_HZ = 100.0
DEFAULT_SECONDS = 30.0


@dataclass(frozen=True)
class Simulation:
    """A simulated run: the rig, sample times, readings (T, n_sensors, 3) and truth."""

    rig: Rig
    t: np.ndarray
    readings: np.ndarray  # m/s², sensor frames, sensors in rig order (links a then b)
    theta: np.ndarray  # θ_ab, rad
    omega_a: np.ndarray  # rad/s
    omega_b: np.ndarray  # rad/s
    mechanism: MechanismState


@dataclass(frozen=True)
class Scenario:
    name: str
    description: str
    rig: Callable[[float], Rig]
    mechanism: Callable[[np.ndarray], MechanismState]
    gravity_world: tuple[float, float, float]


def _sensor(x: float, channel: int, **kw: object) -> SensorConfig:
    return SensorConfig(model="adxl345", position=(x, 0.0), mux_channel=channel, address=0x53,
                        range_g=2, **kw)  # type: ignore[arg-type]


def paper_rig(L: float, rate_hz: float) -> Rig:
    """Slider-crank rig of Table II: sensors at 0 and L/2 from the joint on both links."""
    noise = {"noise_density_ug": (400.0, 400.0, 400.0), "quantize": False}
    link_a = LinkConfig(joint=(L, 0.0), sensors=(_sensor(L, 0, **noise),
                                                  _sensor(L / 2, 1, **noise)))
    link_b = LinkConfig(joint=(0.0, 0.0), sensors=(_sensor(0.0, 2, **noise),
                                                    _sensor(L / 2, 3, **noise)))
    return Rig(name=f"paper-table2-L{round(L * 100)}", sample_rate_hz=rate_hz,
               links={"a": link_a, "b": link_b})


GRAVITY_LINK_M = 0.30
GRAVITY_SENSOR_DISTANCES_M = (0.0475, 0.275)


def gravity_rig(rate_hz: float, name: str = "gravity-bench") -> Rig:
    """The paper's 30 cm bench with sensors at 4.75 and 27.5 cm from the joint on each link."""
    L = GRAVITY_LINK_M
    d1, d2 = GRAVITY_SENSOR_DISTANCES_M
    link_a = LinkConfig(joint=(L, 0.0), sensors=(_sensor(L - d1, 0), _sensor(L - d2, 1)))
    link_b = LinkConfig(joint=(0.0, 0.0), sensors=(_sensor(d1, 2), _sensor(d2, 3)))
    return Rig(name=name, sample_rate_hz=rate_hz, links={"a": link_a, "b": link_b})


def _paper(L: float) -> Scenario:
    crank = Sine(amplitude_rad=np.radians(45.0), freq_hz=0.2)
    return Scenario(
        name=f"paper-table2-L{round(L * 100)}",
        description=f"slider-crank L_a={L * 100:g} cm, L_b={2 * L * 100:g} cm, 45° at 0.2 Hz",
        rig=lambda rate: paper_rig(L, rate),
        mechanism=lambda t: slider_crank(t, crank, L, 2 * L),
        gravity_world=(0.0, 0.0, -STANDARD_GRAVITY),
    )


def _moves(start_deg: float, delta_deg: float, dur: float, pause: float,
           seconds: float = 120.0, first: float = 1.0) -> MinimumJerkMoves:
    """Alternate between start and start+delta, pausing between moves."""
    moves = []
    t0 = first
    target = start_deg
    while t0 < seconds:
        target = start_deg + delta_deg if target == start_deg else start_deg
        moves.append((t0, dur, float(np.radians(target))))
        t0 += dur + pause
    return MinimumJerkMoves(start_rad=float(np.radians(start_deg)), moves=tuple(moves))


def _gravity(name: str, motion_b: Motion, description: str) -> Scenario:
    return Scenario(
        name=name,
        description=description,
        rig=lambda rate: gravity_rig(rate, name),
        mechanism=lambda t: two_link(t, Constant(0.0), motion_b, (GRAVITY_LINK_M, 0.0)),
        gravity_world=(0.0, -STANDARD_GRAVITY, 0.0),
    )


def _build() -> dict[str, Scenario]:
    out = [
        _paper(0.30),
        _paper(0.20),
        _paper(0.10),
        _gravity("gravity-slow-periodic",
                 Sine(np.radians(35.0), 0.25, offset_rad=np.radians(-45.0)),
                 "link b swings −45° ± 35° at 0.25 Hz, link a clamped level"),
        _gravity("gravity-fast-periodic",
                 Sine(np.radians(30.0), 1.0, offset_rad=np.radians(-45.0)),
                 "link b swings −45° ± 30° at 1 Hz, link a clamped level"),
        _gravity("gravity-ramp", _moves(-15.0, -60.0, 2.0, 2.0),
                 "60° minimum-jerk ramps over 2 s with 2 s pauses"),
        _gravity("gravity-impulse", _moves(-30.0, -30.0, 0.35, 2.5),
                 "30° minimum-jerk jerks in 0.35 s with 2.5 s pauses"),
    ]
    return {s.name: s for s in out}


def _calibration_motions() -> dict[str, Scenario]:
    d = np.radians
    free = Scenario(
        name="gravity-free-motion",
        description="both links swinging freely (sums of sines): a motion to calibrate from",
        rig=lambda rate: gravity_rig(rate, "gravity-free-motion"),
        mechanism=lambda t: two_link(
            t, SineSum(0.0, ((d(30.0), 0.31, 0.0), (d(15.0), 0.97, 1.0))),
            SineSum(d(-45.0), ((d(35.0), 0.23, 0.0), (d(20.0), 0.71, 2.0), (d(8.0), 1.9, 0.5))),
            (GRAVITY_LINK_M, 0.0)),
        gravity_world=(0.0, -STANDARD_GRAVITY, 0.0),
    )
    still = Scenario(
        name="gravity-reference-pose",
        description="the rig held still and straight (θ = 0), links level: the joint's zero",
        rig=lambda rate: gravity_rig(rate, "gravity-reference-pose"),
        mechanism=lambda t: two_link(t, Constant(0.0), Constant(0.0), (GRAVITY_LINK_M, 0.0)),
        gravity_world=(0.0, -STANDARD_GRAVITY, 0.0),
    )
    return {free.name: free, still.name: still}


def scenario_names() -> list[str]:
    """The base scenarios (docs/design.md §5); `as_built_names` lists their as-built variants."""
    return list(_build())


def as_built_names() -> list[str]:
    bases = [*_build(), *_calibration_motions()]
    return [f"{n}-{level}" for level in AS_BUILT_LEVELS for n in bases]


def all_scenario_names() -> list[str]:
    """Every name `simulate` takes: the benchmark's scenarios, the calibration motions and
    the as-built variants of both."""
    return scenario_names() + list(_calibration_motions()) + as_built_names()


def get_scenario(name: str) -> Scenario:
    """A base scenario; an as-built variant's name gives its base scenario (`simulate` adds the
    build errors)."""
    table = {**_build(), **_calibration_motions()}
    base, _ = split_variant(name)
    if base not in table:
        raise InputError(f"unknown scenario {name!r}; known: {', '.join(table)} (each also "
                         f"as NAME-{' and NAME-'.join(AS_BUILT_LEVELS)})",
                         field="--scenario")
    return table[base]


def simulate_rig(rig: Rig, mech: MechanismState, gravity_world: np.ndarray,
                 seed: int, mechanism_at: Callable[[np.ndarray], MechanismState] | None = None
                 ) -> np.ndarray:
    """Readings (T, n_sensors, 3) of every sensor of `rig` moving with `mech`.

    The sensors sit where the rig is built (sim/as_built.py `true_positions`); a sensor with a
    read skew is read at t + skew, and one with its own conversion clock (`sim_clock_*`)
    gives the latest conversion before its read (sensor_timing.py `part_clock`); both need
    `mechanism_at` (the mechanism at any times; without it they are refused).
    """
    rng = np.random.default_rng(seed)
    cols = []
    for link in ("a", "b"):
        cfg = rig.links[link]
        pos = true_positions(rig, link)
        f = specific_force_link(mech, link, pos, gravity_world)
        for i, sensor in enumerate(cfg.sensors):
            fi = f[:, i, :]
            t_sample = sample_instants(sensor, mech.t, rig.sample_rate_hz)
            if t_sample is not None:
                if mechanism_at is None:
                    raise InputError("a read skew or a part's own clock is simulated only for "
                                     "the named scenarios (`simulate --scenario`), whose motion "
                                     "is known at any time",
                                     field=f"links.{link}.sensors[{i}]." + (
                                         "sim_read_skew_s" if sensor.sim_read_skew_s
                                         else "sim_clock_ppm"))
                m_skew = mechanism_at(t_sample)
                fi = specific_force_link(m_skew, link, pos[i:i + 1], gravity_world)[:, 0, :]
            cols.append(sensor_reading(sensor, fi, rig.sample_rate_hz, rng))
    return np.stack(cols, axis=1)


def sample_instants(sensor: SensorConfig, t: np.ndarray, rate_hz: float) -> np.ndarray | None:
    """When the sample of each row t is taken, or None for at t itself: read at t + skew, and,
    for a part on its own clock, the latest conversion at or before that read."""
    skew = sensor.sim_read_skew_s or 0.0
    if sensor.sim_clock_ppm is None and sensor.sim_clock_phase is None:
        return t + skew if skew else None
    period, offset = part_clock(sensor, odr_period_ns(sensor.model, rate_hz))
    return conversion_instants(t, period, -skew, offset)


def simulate(name: str, seed: int = 0, rate_hz: float = DEFAULT_RATE_HZ,
             seconds: float = DEFAULT_SECONDS, rig: Rig | None = None) -> Simulation:
    """Run a named scenario. `rig` overrides the scenario's own rig (same mechanism). An
    as-built variant (NAME-as-built, NAME-as-built-uncal) gives the rig the build errors of
    seed `seed` (sim/as_built.py)."""
    sc = get_scenario(name)
    if rig is None:
        rig = sc.rig(rate_hz)
    _, level = split_variant(name)
    if level is not None:
        rig = as_built_rig(rig, seed, level)
    n = round(seconds * rate_hz)
    t = np.arange(n) / rate_hz
    mech = sc.mechanism(t)
    readings = simulate_rig(rig, mech, np.asarray(sc.gravity_world), seed, sc.mechanism)
    return Simulation(rig=rig, t=t, readings=readings, theta=mech.theta_ab,
                      omega_a=mech.a.omega, omega_b=mech.b.omega, mechanism=mech)
