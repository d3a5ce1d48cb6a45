"""A host estimator's θ, ω_a, ω_b for every sample of a recording (`replay --estimates-csv
--host-filter NAME`).

The board's `sample_estimate` frames carry the raw counts each step read. They become the
firmware's own link-frame readings (`device_readings`, the rig as the board sees it), and the
estimator — any of `estimate --filter`'s that needs accelerations only; offline ones too, the
recording is whole — runs on each *segment*: a run of frames one sample period apart with no
frame lost and the same usable sensors (≥ 2 per link), as `live --host-filter` runs it. Rows of
a segment the estimator refuses, or without two usable sensors per link, are NaN.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from jointangle.device.calibration_map import DeviceMaps, device_readings, mps2_per_count
from jointangle.device.rig import FAULT_BITS, device_rig, sub_rig
from jointangle.errors import InputError
from jointangle.estimators.inputs import check_inputs, run_estimator
from jointangle.estimators.registry import get_estimator
from jointangle.protocol import messages as msgs
from jointangle.recording.export import unwrap_us
from jointangle.rig import Rig

COLUMNS = ("host_theta_deg", "host_omega_a_dps", "host_omega_b_dps")


@dataclass
class HostColumns:
    name: str
    values: np.ndarray  # (T, 3): θ (°), ω_a, ω_b (°/s); NaN where there is no estimate
    segments: int = 0
    refused: list[str] = field(default_factory=list)  # why segments have no estimate


def _segment_starts(t_us: np.ndarray, lost_before: np.ndarray, usable: np.ndarray,
                    period_us: float) -> np.ndarray:
    """Indices where a new segment starts (0 included)."""
    t = unwrap_us(t_us)
    T = t.size
    brk = np.zeros(T, dtype=bool)
    brk[0] = T > 0
    if T > 1:
        step = np.diff(t).astype(float)
        brk[1:] = (np.abs(step - period_us) >= 0.5 * period_us) | (lost_before[1:] > 0) | \
            np.any(usable[1:] != usable[:-1], axis=1)
    return np.flatnonzero(brk)


def host_columns(rig: Rig, hello: msgs.Hello, cols: dict[str, np.ndarray],
                 lost_before: np.ndarray, name: str) -> HostColumns:
    """The estimator `name` on the sample_estimate columns `cols` (bulk decoder layout)."""
    est = get_estimator(name)
    drig = device_rig(rig, hello)
    maps = DeviceMaps.from_rig(drig)
    counts = np.stack([cols["sensors.x"], cols["sensors.y"], cols["sensors.z"]], axis=2)
    usable = (cols["sensors.status"] & int(FAULT_BITS)) == 0  # (T, n)
    readings = device_readings(maps, counts)
    lsb = np.array([float(mps2_per_count(s.model, s.range_g))
                    for _, _, s in drig.all_sensors()])
    T = counts.shape[0]
    out = HostColumns(name, np.full((T, 3), np.nan))
    starts = _segment_starts(cols["t_us"], lost_before, usable, 1e6 / drig.sample_rate_hz)
    for a, b in zip(starts, [*starts[1:], T], strict=True):
        chosen = tuple(int(i) for i in np.flatnonzero(usable[a]))
        seg_rig = sub_rig(drig, chosen)
        out.segments += 1
        if min(seg_rig.sensor_count("a"), seg_rig.sensor_count("b")) < 2:
            out.refused.append(f"rows {a}-{b - 1}: fewer than two usable sensors on a link")
            continue
        cols_xy = [c for i in chosen for c in (2 * i, 2 * i + 1)]
        try:
            check_inputs(est, seg_rig, counts[a:b][:, list(chosen)] * lsb[list(chosen)][:, None],
                         None)
            e = run_estimator(est, seg_rig, readings[a:b, cols_xy][None])
        except InputError as exc:
            out.refused.append(f"rows {a}-{b - 1}: {exc.reason}")
            continue
        out.values[a:b] = np.degrees(np.stack([e.theta[0], e.omega_a[0], e.omega_b[0]], 1))
    return out
