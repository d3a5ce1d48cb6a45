"""`jointangle bench parity`: the firmware's fixed-point core against `mirror` (docs/design.md §5).

Both run open-loop on identical inputs — every scenario's link-frame readings quantised to the
firmware's Q15.16 accelerometer format — from their own initial state; `mirror` never reads the
core's output. Per scenario over all seeds: max |Δθ| and max |Δω| from t = 2 s on, the worst
seed's RMS Δθ from 2 s on, and max |Δθ| before 2 s (start-up, same branch).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from jointangle.bench.accuracy import DEFAULT_SEEDS, simulate_seeds
from jointangle.estimators.base import sensor_to_link, wrap
from jointangle.estimators.mirror import (
    MirrorSettings,
    _geometry,
    output_theta,
    quantise_inputs,
    quantise_raw,
    replay_core,
    run_mirror,
    sensors_per_link,
    slot_readings,
)
from jointangle.rig import Rig
from jointangle.sim.scenarios import scenario_names, simulate

PARITY_FROM_S = 2.0
# docs/design.md §5 targets.
MAX_DTHETA_DEG = 0.05
RMS_DTHETA_DEG = 0.01
MAX_DOMEGA_DPS = 0.5
STARTUP_MAX_DTHETA_DEG = 1.0


@dataclass(frozen=True)
class ParityScores:
    """Firmware core vs mirror on one scenario (all seeds)."""

    max_abs_dtheta_deg: float
    rms_dtheta_deg: float  # worst seed
    max_abs_domega_dps: float
    startup_max_abs_dtheta_deg: float
    saturations: int  # worst seed
    skipped_updates: int  # worst seed, firmware

    def within_targets(self) -> bool:
        return (self.max_abs_dtheta_deg <= MAX_DTHETA_DEG
                and self.rms_dtheta_deg <= RMS_DTHETA_DEG
                and self.max_abs_domega_dps <= MAX_DOMEGA_DPS
                and self.startup_max_abs_dtheta_deg <= STARTUP_MAX_DTHETA_DEG)


def parity(rig: Rig, acc: np.ndarray, t: np.ndarray) -> ParityScores:
    """Core vs mirror on link-frame readings acc (S, T, M) sampled at t (T,)."""
    cfg = MirrorSettings.from_rig(rig)
    xs, _ = run_mirror(cfg, quantise_inputs(acc))
    core = replay_core(rig, acc)
    dth = np.degrees(np.abs(wrap(core.theta - output_theta(cfg, xs))))
    dw = np.degrees(np.maximum(np.abs(core.omega_a - xs[..., 0]),
                               np.abs(core.omega_b - xs[..., 1])))
    late = t >= PARITY_FROM_S
    early = ~late
    return ParityScores(
        max_abs_dtheta_deg=float(dth[:, late].max()) if late.any() else 0.0,
        rms_dtheta_deg=float(np.sqrt(np.mean(dth[:, late] ** 2, axis=1)).max())
        if late.any() else 0.0,
        max_abs_domega_dps=float(dw[:, late].max()) if late.any() else 0.0,
        startup_max_abs_dtheta_deg=float(dth[:, early].max()) if early.any() else 0.0,
        saturations=int(core.saturations.max()),
        skipped_updates=int(core.skipped.max()))


SENSORS_PER_LINK_CHOICES = (2, 3, 4)  # what the firmware's filter takes


def array_of(rig: Rig, n: int) -> Rig:
    """`rig` with n sensors per link, spread evenly from each link's first sensor to its last
    (the same span, so the same array extent), each on its own multiplexer channel/address
    pair. n = the rig's own count returns it unchanged."""
    links = {}
    for li, (name, link) in enumerate(sorted(rig.links.items())):
        if len(link.sensors) == n:
            links[name] = link
            continue
        first, last = link.sensors[0], link.sensors[-1]
        p0, p1 = np.asarray(first.position, float), np.asarray(last.position, float)
        sensors = []
        for j in range(n):
            pos = p0 + (p1 - p0) * (j / (n - 1))
            base = first if j < n / 2 else last
            sensors.append(replace(base, position=(float(pos[0]), float(pos[1])),
                                   mux_channel=(2 * li + j // 2) % 8,
                                   address=0x53 if j % 2 == 0 else 0x1D))
        links[name] = replace(link, sensors=tuple(sensors))
    return replace(rig, links=links)


def scenario_parity(scenario: str, n_seeds: int = DEFAULT_SEEDS,
                    sensors_per_link: int | None = None) -> ParityScores:
    """Parity on one scenario; with sensors_per_link, on its rig re-built with that many
    sensors per link (`array_of`)."""
    if sensors_per_link is None:
        sims, acc = simulate_seeds(scenario, range(n_seeds))
        return parity(sims[0].rig, acc, sims[0].t)

    rig = array_of(simulate(scenario, seed=0, seconds=0.01).rig, sensors_per_link)
    sims = [simulate(scenario, seed=k, rig=rig) for k in range(n_seeds)]
    acc = np.stack([sensor_to_link(rig, s.readings) for s in sims])
    return parity(rig, acc, sims[0].t)


def run_parity(scenarios: Sequence[str] | None = None, n_seeds: int = DEFAULT_SEEDS,
               sensors_per_link: int | None = None) -> dict[str, Any]:
    """The JSON document of docs/design.md §4 (`parity`), plus the targets and counters."""
    doc: dict[str, Any] = {
        "seeds": n_seeds, "from_s": PARITY_FROM_S, "sensors_per_link": sensors_per_link or 2,
        "targets": {"max_abs_dtheta_deg": MAX_DTHETA_DEG, "rms_dtheta_deg": RMS_DTHETA_DEG,
                    "max_abs_domega_dps": MAX_DOMEGA_DPS,
                    "startup_max_abs_dtheta_deg": STARTUP_MAX_DTHETA_DEG},
        "scenarios": []}
    for sc in scenarios or scenario_names():
        p = scenario_parity(sc, n_seeds, sensors_per_link)
        doc["scenarios"].append({
            "name": sc,
            "max_abs_dtheta_deg": round(p.max_abs_dtheta_deg, 6),
            "rms_dtheta_deg": round(p.rms_dtheta_deg, 6),
            "max_abs_domega_dps": round(p.max_abs_domega_dps, 6),
            "startup_max_abs_dtheta_deg": round(p.startup_max_abs_dtheta_deg, 6),
            "saturations": p.saturations,
            "skipped_updates": p.skipped_updates,
            "within_targets": p.within_targets()})
    return doc


# Off-axis sensor offsets (m) and x/y noise-density factors of `general_rig`, and the read
# delay between consecutive sensors (the AVR board's skew, docs/as-built.md).
GENERAL_OFFSETS_M = (0.012, -0.007)
GENERAL_DENSITY_XY = (1.15, 0.9)
GENERAL_READ_SKEW_S = 0.232e-3


def general_rig(rig: Rig) -> Rig:
    """`rig` with every sensor moved off its link's axis, unequal x/y noise and read one after
    another: G, F, M_b01, c_b1 and R₃₄ have no zero entries and the readings are turned back to
    the row's time, so the filter takes none of its shortcuts (FILTER.md: the cycle budget must
    hold for any configured geometry and board)."""
    links = {}
    k = 0
    for name, link in rig.links.items():
        sensors = []
        for i, s in enumerate(link.sensors):
            dx, dy, dz = s.density_ug
            sensors.append(replace(
                s, position=(s.position[0], s.position[1] + GENERAL_OFFSETS_M[i % 2]),
                noise_density_ug=(dx * GENERAL_DENSITY_XY[0], dy * GENERAL_DENSITY_XY[1], dz),
                read_delay_s=k * GENERAL_READ_SKEW_S))
            k += 1
        links[name] = replace(link, sensors=tuple(sensors))
    return replace(rig, links=links)


def write_core_input(path: str, scenarios: Sequence[str] | None = None, seed: int = 0,
                     seconds: float | None = None, general_geometry: bool = False,
                     more_sensors: Sequence[str] = ()) -> int:
    """Write scenario runs in the binary input format of firmware/platform/avr/bench/
    bench_filter.cpp (the AVR cycle bench and its x86 twin): little-endian uint32 n_runs, then
    per run uint32 n_steps, float32 dt, float32 geometry (2 × GEOMETRY_PER_LINK: the sensors in
    use and MAX_SENSORS_PER_LINK slots per link), int32 Q15.16 readings (n × 4 slots × 2 links
    × 2, unused slots 0). With general_geometry, every scenario runs a second time on
    `general_rig` of its rig. The scenarios named in more_sensors run again with 3 and 4
    sensors per link (`array_of`, general geometry). Returns the total number of steps."""
    names = list(scenarios or scenario_names())
    runs: list[tuple[Rig, np.ndarray]] = []
    for name in names:
        sims, acc = simulate_seeds(name, [seed])
        runs.append((sims[0].rig, acc[0]))
    if general_geometry:
        for name in names:
            rig = general_rig(runs[names.index(name)][0])
            sim = simulate(name, seed=seed, rate_hz=rig.sample_rate_hz, rig=rig)
            runs.append((rig, sensor_to_link(rig, sim.readings)))
    for name in more_sensors:
        for n in (3, 4):
            rig = general_rig(array_of(simulate(name, seed=seed, seconds=0.01).rig, n))
            sim = simulate(name, seed=seed, rate_hz=rig.sample_rate_hz, rig=rig)
            runs.append((rig, sensor_to_link(rig, sim.readings)))
    chunks = [np.array([len(runs)], dtype="<u4").tobytes()]
    total = 0
    for rig, acc_run in runs:
        raw = slot_readings(quantise_raw(acc_run), sensors_per_link(rig))
        if seconds is not None:
            raw = raw[: round(seconds / rig.dt)]
        chunks += [np.array([raw.shape[0]], dtype="<u4").tobytes(),
                   np.array([rig.dt], dtype="<f4").tobytes(),
                   _geometry(rig).astype("<f4").tobytes(),
                   np.ascontiguousarray(raw, dtype="<i4").tobytes()]
        total += raw.shape[0]
    with open(path, "wb") as f:
        f.write(b"".join(chunks))
    return total
