"""What geometry calibrated from motion buys: the real-time filters on held-out motions.

For each seed s (build s of the `as-built` level, sim/as_built.py): 60 s of
`gravity-free-motion-as-built` are calibrated (calibration/motion.py, mounting tolerance
0.2°); then every gravity scenario's as-built variant (the same build, other motions) is
estimated with the nominal rig and with the calibrated one, next to the ideal geometry and to
the ideal geometry read with the board's skew alone (what geometry calibration cannot remove).
Steady RMS θ (t ≥ 5 s), mean over seeds; for the calibrated rig also the RMS around the run's
mean error (the constant offset that the unidentifiable direction of each link's x axis
leaves removed); and the calibrated rig given the joint's zero by 3 s of the same build held
still and straight (`gravity-reference-pose`, calibration/reference.py). Also the lever-arm
and relative-mounting errors. `--sources` keeps only some of the build's errors (positions,
mountings, joints, skew): one at a time, what each costs.

    .venv/bin/python -m jointangle.bench.motion_calibration --seeds 20 [--sources S] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from typing import Any

import numpy as np

from jointangle.calibration.motion import MotionPrior, calibrate_motion, motion_calibrated_rig
from jointangle.calibration.reference import measure_reference, referenced_rig
from jointangle.estimators.base import sensor_to_link, wrap
from jointangle.estimators.registry import get_estimator
from jointangle.rig import LINK_NAMES, Rig
from jointangle.sim.as_built import (
    AS_BUILT_LEVELS,
    BUILD_SOURCES,
    nominal_rig,
    only_sources,
    true_positions,
)
from jointangle.sim.scenarios import Simulation, simulate

HELD_OUT = ("gravity-slow-periodic", "gravity-fast-periodic", "gravity-ramp", "gravity-impulse")
FILTERS = ("ekf", "firmware", "array-ekf")
CASES = ("ideal", "ideal+skew", "as-built nominal", "as-built calibrated",
         "calibrated, offset removed", "calibrated + reference pose")
REFERENCE_SECONDS = 3.0


def without_read_delays(rig: Rig) -> Rig:
    """`rig` as if the filters did not know when the board reads each sensor."""
    return replace(rig, links={ln: replace(rig.links[ln], sensors=tuple(
        replace(s, read_delay_s=0.0) for s in rig.links[ln].sensors)) for ln in LINK_NAMES})


def _steady(rig: Rig, sim: Simulation, name: str, read_delays: bool = True
            ) -> tuple[float, float]:
    """Steady RMS θ error and its RMS around its mean (the constant offset removed)."""
    if not read_delays:
        rig = without_read_delays(rig)
    est = get_estimator(name).estimate(rig, sensor_to_link(rig, sim.readings)[None])
    err = np.degrees(wrap(est.theta[0] - sim.theta))[sim.t >= 5.0]
    return float(np.sqrt(np.mean(err**2))), float(np.std(err))


def _skew_only(built: Rig) -> Rig:
    """The nominal geometry with the build's timing alone: its read skew and part clocks."""
    nom = nominal_rig(built)
    return replace(nom, links={ln: replace(nom.links[ln], sensors=tuple(
        replace(s, sim_read_skew_s=b.sim_read_skew_s, sim_clock_ppm=b.sim_clock_ppm,
                sim_clock_phase=b.sim_clock_phase)
        for s, b in zip(nom.links[ln].sensors, built.links[ln].sensors, strict=True)))
        for ln in LINK_NAMES})


def _built(name: str, seed: int, seconds: float | None, sources: tuple[str, ...],
           level: str = "as-built") -> Simulation:
    """Scenario `name` as built (build `seed` of `level`), with only these error sources."""
    kw: dict[str, Any] = {} if seconds is None else {"seconds": seconds}
    sim = simulate(f"{name}-{level}", seed=seed, **kw)
    if set(sources) == set(BUILD_SOURCES):
        return sim
    return simulate(name, seed=seed, rig=only_sources(sim.rig, sources), **kw)


def run(seeds: int, seconds: float = 60.0, sources: tuple[str, ...] = BUILD_SOURCES,
        filters: tuple[str, ...] = FILTERS, held_out: tuple[str, ...] = HELD_OUT,
        read_delays: bool = True, level: str = "as-built") -> dict[str, Any]:
    out: dict[str, list[float]] = {}
    lever_before, lever_after, mount_rel = [], [], []
    refused = 0
    for seed in range(seeds):
        cal = _built("gravity-free-motion", seed, seconds, sources, level)
        nominal = nominal_rig(cal.rig)
        rep = calibrate_motion(nominal, cal.t, cal.readings, MotionPrior(
            mounting_tol_deg=AS_BUILT_LEVELS[level].mounting_deg))
        if not rep.accepted:
            refused += 1
            continue
        calibrated = motion_calibrated_rig(nominal, rep)
        pose = _built("gravity-reference-pose", seed, REFERENCE_SECONDS, sources, level)
        zero = measure_reference(calibrated, pose.readings, 0.0)
        referenced = referenced_rig(calibrated, zero) if zero.accepted else calibrated
        for ln in LINK_NAMES:
            truth = true_positions(cal.rig, ln) - np.array(cal.rig.links[ln].joint)
            lever_before += list((nominal.links[ln].positions()
                                  - np.array(nominal.links[ln].joint) - truth).ravel())
            lever_after += list((calibrated.links[ln].positions()
                                 - np.array(calibrated.links[ln].joint) - truth).ravel())
            tr = [s.sim_rotation_offset_deg or 0.0 for s in cal.rig.links[ln].sensors]
            fr = [s.rotation_deg for s in calibrated.links[ln].sensors]
            mount_rel += [(f - fr[0]) - (t - tr[0]) for f, t in zip(fr[1:], tr[1:], strict=True)]
        for sc in held_out:
            built = _built(sc, seed, None, sources, level)
            ideal = simulate(sc, seed=seed)
            skew = simulate(sc, seed=seed, rig=_skew_only(built.rig))
            for f in filters:
                for case, rig, sim in (("ideal", ideal.rig, ideal),
                                       ("ideal+skew", nominal, skew),
                                       ("as-built nominal", nominal, built),
                                       ("as-built calibrated", calibrated, built),
                                       ("calibrated + reference pose", referenced, built)):
                    rms, std = _steady(rig, sim, f, read_delays)
                    out.setdefault(f"{sc}|{f}|{case}", []).append(rms)
                    if case == "as-built calibrated":
                        out.setdefault(f"{sc}|{f}|calibrated, offset removed", []).append(std)
        sys.stderr.write(f"seed {seed} done\n")
    table = {k: round(float(np.mean(v)), 4) for k, v in out.items()}
    return {
        "seeds": seeds, "calibration_seconds": seconds, "refused": refused,
        "level": level, "sources": list(sources), "read_delays": read_delays,
        "filters": list(filters), "held_out": list(held_out),
        "lever_rms_mm_before": round(float(np.sqrt(np.mean(np.square(lever_before)))) * 1e3, 3),
        "lever_rms_mm_after": round(float(np.sqrt(np.mean(np.square(lever_after)))) * 1e3, 3),
        "relative_mounting_rms_deg_after": round(float(np.sqrt(np.mean(np.square(mount_rel)))),
                                                 4),
        "steady_theta_rms_deg": table,
    }


def markdown(doc: dict[str, Any]) -> str:
    t = doc["steady_theta_rms_deg"]
    lines = ["| scenario | filter | " + " | ".join(CASES) + " |",
             "|---|---|" + "---|" * len(CASES)]
    for sc in doc["held_out"]:
        for f in doc["filters"]:
            lines.append(f"| {sc} | `{f}` | " + " | ".join(
                f"{t[f'{sc}|{f}|{c}']:.3f}" for c in CASES) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--seconds", type=float, default=60.0)
    p.add_argument("--sources", default=",".join(BUILD_SOURCES),
                   help="build errors kept, comma-separated (default all: "
                   f"{','.join(BUILD_SOURCES)}): one at a time shows what each costs")
    p.add_argument("--filters", default=",".join(FILTERS))
    p.add_argument("--scenarios", default=",".join(HELD_OUT))
    p.add_argument("--ignore-read-delays", action="store_true",
                   help="the filters are not told when the board reads each sensor (the rigs' "
                   "read_delay_s cleared): what modelling the read skew buys")
    p.add_argument("--level", choices=list(AS_BUILT_LEVELS), default="as-built",
                   help="the builds' error level (sim/as_built.py; the motion fit's mounting "
                   "tolerance is the level's)")
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    doc = run(args.seeds, args.seconds, tuple(args.sources.split(",")),
              tuple(args.filters.split(",")), tuple(args.scenarios.split(",")),
              not args.ignore_read_delays, args.level)
    if args.json:
        json.dump(doc, sys.stdout)
        sys.stdout.write("\n")
    else:
        sys.stdout.write(markdown(doc) + "\n")
        sys.stdout.write(json.dumps({k: v for k, v in doc.items()
                                     if k != "steady_theta_rms_deg"}) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
