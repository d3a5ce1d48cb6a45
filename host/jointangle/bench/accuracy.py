"""`jointangle bench accuracy`: every estimator on every scenario, scored as docs/design.md §5 says.

For each noise seed: RMS θ error over t ≥ 5 s (steady) and over t < 5 s (start-up). A scenario's
figure is the mean over seeds, with the worst seed reported; ratios to `ekf` are taken per seed
and then averaged. ω errors are RMS over the steady window.

With `as_built` (levels of sim/as_built.py, docs/as-built.md) every scenario is also run as
built: seed s simulates build s of that level, the estimators read the nominal rig as always.
Each scenario entry then gets an "as_built" object: per level its description and the same
per-filter figures plus `theta_ratio_to_ideal` / `startup_ratio_to_ideal` (as built over the
ideal geometry, per seed, then averaged) — the real-world cost of the build as a number.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np

from jointangle.estimators.base import Estimates, sensor_to_link, wrap
from jointangle.estimators.inputs import requires_gyro
from jointangle.estimators.registry import ESTIMATORS, get_estimator
from jointangle.sim.as_built import AS_BUILT_LEVELS
from jointangle.sim.scenarios import Simulation, scenario_names, simulate

STARTUP_S = 5.0
DEFAULT_SEEDS = 20
BASELINE = "ekf"

# The paper's published RMS errors: Table II (simulation) and Table III (ADXL345 bench).
PAPER_FIGURES: dict[str, dict[str, dict[str, float]]] = {
    "paper-table2-L30": {
        "theta_rms_deg": {"analytical": 9.04, "smooth": 1.74, "ukf": 1.21, "ekf": 0.71},
        "omega_a_rms_dps": {"ukf": 3.96, "ekf": 0.69},
        "omega_b_rms_dps": {"ukf": 2.07, "ekf": 0.97},
    },
    "paper-table2-L20": {
        "theta_rms_deg": {"analytical": 13.69, "smooth": 2.77, "ukf": 1.41, "ekf": 1.79},
        "omega_a_rms_dps": {"ukf": 4.10, "ekf": 1.10},
        "omega_b_rms_dps": {"ukf": 2.40, "ekf": 1.55},
    },
    "paper-table2-L10": {
        "theta_rms_deg": {"analytical": 41.42, "smooth": 10.32, "ukf": 3.35, "ekf": 3.12},
        "omega_a_rms_dps": {"ukf": 4.49, "ekf": 2.21},
        "omega_b_rms_dps": {"ukf": 3.49, "ekf": 3.11},
    },
    "gravity-slow-periodic": {"theta_rms_deg": {"analytical": 3.61, "ekf": 3.09, "ukf": 3.03}},
    "gravity-fast-periodic": {"theta_rms_deg": {"analytical": 6.41, "ekf": 5.50, "ukf": 5.51}},
    "gravity-ramp": {"theta_rms_deg": {"analytical": 4.45, "ekf": 4.21, "ukf": 4.18}},
    "gravity-impulse": {"theta_rms_deg": {"analytical": 11.67, "ekf": 7.95, "ukf": 7.92}},
}


@dataclass(frozen=True)
class SeedScores:
    """Per-seed figures of one estimator on one scenario, each (n_seeds,)."""

    steady_deg: np.ndarray
    startup_deg: np.ndarray
    omega_a_dps: np.ndarray
    omega_b_dps: np.ndarray


def score(est: Estimates, sims: Sequence[Simulation], startup_s: float = STARTUP_S
          ) -> SeedScores:
    t = sims[0].t
    steady = t >= startup_s
    start = ~steady
    theta = np.stack([s.theta for s in sims])
    err = np.degrees(wrap(est.theta - theta))

    def rms(x: np.ndarray, mask: np.ndarray) -> np.ndarray:
        return np.sqrt(np.mean(x[:, mask] ** 2, axis=1)) if mask.any() else np.full(
            x.shape[0], np.nan)

    wa = np.degrees(est.omega_a - np.stack([s.omega_a for s in sims]))
    wb = np.degrees(est.omega_b - np.stack([s.omega_b for s in sims]))
    return SeedScores(rms(err, steady), rms(err, start), rms(wa, steady), rms(wb, steady))


def simulate_seeds(scenario: str, seeds: Sequence[int]) -> tuple[list[Simulation], np.ndarray]:
    sims = [simulate(scenario, seed=s) for s in seeds]
    rig = sims[0].rig
    acc = np.stack([sensor_to_link(rig, s.readings) for s in sims])
    return sims, acc


def _task(scenario: str, filter_name: str, seeds: tuple[int, ...]
          ) -> tuple[str, str, SeedScores, float | None]:
    sims, acc = simulate_seeds(scenario, seeds)
    est = get_estimator(filter_name)
    return scenario, filter_name, score(est.estimate(sims[0].rig, acc), sims), est.latency_s(
        sims[0].rig)


def _mean(x: np.ndarray) -> float | None:
    v = float(np.mean(x))
    return None if not np.isfinite(v) else round(v, 4)


def _max(x: np.ndarray) -> float | None:
    v = float(np.max(x))
    return None if not np.isfinite(v) else round(v, 4)


def default_filters() -> list[str]:
    """Every estimator that runs on accelerations alone (methods that need gyro columns are
    compared in `bench compare`, on data that has them)."""
    return [n for n, f in ESTIMATORS.items() if not requires_gyro(f())]


def _figures(s: SeedScores, base: SeedScores, lat: float | None) -> dict[str, Any]:
    return {
        "theta_rms_deg": _mean(s.steady_deg),
        "theta_rms_startup_deg": _mean(s.startup_deg),
        "theta_worst_seed_deg": _max(s.steady_deg),
        "theta_startup_worst_seed_deg": _max(s.startup_deg),
        "omega_a_rms_dps": _mean(s.omega_a_dps),
        "omega_b_rms_dps": _mean(s.omega_b_dps),
        "latency_ms": None if lat is None else round(lat * 1000.0, 3),
        "theta_ratio_to_ekf": _mean(s.steady_deg / base.steady_deg),
        "startup_ratio_to_ekf": _mean(s.startup_deg / base.startup_deg),
    }


def count_tasks(scenarios: Sequence[str] | None, filters: Sequence[str] | None,
                as_built: Sequence[str] = ()) -> int:
    fs = list(filters or default_filters())
    n_f = len(fs) + (BASELINE not in fs)
    return len(scenarios or scenario_names()) * n_f * (1 + len(as_built))


def run_accuracy(scenarios: Sequence[str] | None = None, filters: Sequence[str] | None = None,
                 n_seeds: int = DEFAULT_SEEDS, jobs: int = 1,
                 progress: Callable[[str, str], None] | None = None,
                 as_built: Sequence[str] = ()) -> dict[str, Any]:
    """Run the benchmark and return the JSON document of docs/design.md §4 (`as_built`: also run
    these levels of sim/as_built.py and add them to each scenario, module doc)."""
    scenarios = list(scenarios or scenario_names())
    filters = list(filters or default_filters())
    for level in as_built:
        if level not in AS_BUILT_LEVELS:
            raise ValueError(f"unknown as-built level {level!r}")
    run_filters = filters if BASELINE in filters else [*filters, BASELINE]
    seeds = tuple(range(n_seeds))
    variants = [sc if lv is None else f"{sc}-{lv}" for sc in scenarios
                for lv in (None, *as_built)]
    tasks = [(sc, f, seeds) for sc in variants for f in run_filters]
    results: dict[tuple[str, str], tuple[SeedScores, float | None]] = {}
    if jobs > 1:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = [pool.submit(_task, *t) for t in tasks]
            for fut in futures:
                sc, f, s, lat = fut.result()
                results[(sc, f)] = (s, lat)
                if progress:
                    progress(sc, f)
    else:
        for t in tasks:
            sc, f, s, lat = _task(*t)
            results[(sc, f)] = (s, lat)
            if progress:
                progress(sc, f)
    doc: dict[str, Any] = {"seeds": n_seeds, "startup_s": STARTUP_S, "baseline": BASELINE,
                           "scenarios": []}
    if as_built:
        doc["as_built_levels"] = {lv: AS_BUILT_LEVELS[lv].description for lv in as_built}
    for sc in scenarios:
        base = results[(sc, BASELINE)][0]
        entry: dict[str, Any] = {"name": sc, "filters": {}, "paper": PAPER_FIGURES.get(sc, {})}
        for f in filters:
            s, lat = results[(sc, f)]
            entry["filters"][f] = _figures(s, base, lat)
        if as_built:
            entry["as_built"] = {}
        for lv in as_built:
            name = f"{sc}-{lv}"
            vbase = results[(name, BASELINE)][0]
            built: dict[str, Any] = {"name": name, "description": AS_BUILT_LEVELS[lv].description,
                                     "filters": {}}
            for f in filters:
                s, lat = results[(name, f)]
                ideal = results[(sc, f)][0]
                built["filters"][f] = {
                    **_figures(s, vbase, lat),
                    "theta_ratio_to_ideal": _mean(s.steady_deg / ideal.steady_deg),
                    "startup_ratio_to_ideal": _mean(s.startup_deg / ideal.startup_deg),
                }
            entry["as_built"][lv] = built
        doc["scenarios"].append(entry)
    return doc
