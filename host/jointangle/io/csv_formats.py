"""The accelerations CSV and the estimates CSV (DESIGN.md §4).

Accelerations: `t,a.0.x,a.0.y,a.0.z,a.1.x,…,b.0.x,…` in m/s² in each sensor's own frame, links a
then b in rig order; optional gyro columns `a.0.gx,…` (rad/s) and optional truth columns
`theta,omega_a,omega_b` (rad, rad/s). Estimators never read the truth columns.

Estimates: `t,theta_deg,omega_a_dps,omega_b_dps` plus optional uncertainty columns.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from jointangle.errors import InputError
from jointangle.rig import Rig, sensor_labels

TRUTH_COLUMNS = ("theta", "omega_a", "omega_b")
ESTIMATE_COLUMNS = ("t", "theta_deg", "omega_a_dps", "omega_b_dps")


@dataclass(frozen=True)
class Truth:
    theta: np.ndarray  # rad
    omega_a: np.ndarray  # rad/s
    omega_b: np.ndarray  # rad/s


@dataclass(frozen=True)
class AccelData:
    t: np.ndarray  # (T,) s
    readings: np.ndarray  # (T, n_sensors, 3) m/s², sensor frames
    gyro: np.ndarray | None = None  # (T, n_sensors, 3) rad/s where present, NaN elsewhere
    truth: Truth | None = None


def accel_header(rig: Rig, *, gyro: bool | list[int] = False, truth: bool = False) -> list[str]:
    """CSV header; `gyro` is True for gyro columns of every sensor, or the sensor indices that
    have them (a sensor without a gyro, e.g. an ADXL357 beside BNO055s, gets no gyro columns)."""
    cols = ["t"]
    labels = sensor_labels(rig)
    for lab in labels:
        cols += [f"{lab}.x", f"{lab}.y", f"{lab}.z"]
    with_gyro = list(range(len(labels))) if gyro is True else (gyro or [])
    for k in with_gyro:
        cols += [f"{labels[k]}.gx", f"{labels[k]}.gy", f"{labels[k]}.gz"]
    if truth:
        cols += list(TRUTH_COLUMNS)
    return cols


def write_accel_csv(path: str | Path, rig: Rig, data: AccelData) -> None:
    n_t = len(data.t)
    blocks = [data.t[:, None], data.readings.reshape(n_t, -1)]
    with_gyro: list[int] = []
    if data.gyro is not None:
        # Only the sensors that have a gyro (the others' columns are NaN: the reader refuses NaN).
        with_gyro = [k for k in range(data.gyro.shape[1]) if not np.isnan(data.gyro[:, k]).all()]
        blocks.append(data.gyro[:, with_gyro].reshape(n_t, -1))
    if data.truth is not None:
        blocks.append(np.stack([data.truth.theta, data.truth.omega_a, data.truth.omega_b], 1))
    table = np.hstack(blocks)
    header = accel_header(rig, gyro=with_gyro, truth=data.truth is not None)
    np.savetxt(path, table, delimiter=",", header=",".join(header), comments="", fmt="%.9g")


def _read_table(path: Path) -> tuple[list[str], np.ndarray]:
    """Header and float table of a CSV; errors name the line and the column."""
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot read CSV: {exc.strerror}", path=path) from None
    lines = text.splitlines()
    if not lines or not lines[0].strip():
        raise InputError("empty file: expected a header line", path=path, line=1)
    header = [h.strip() for h in lines[0].split(",")]
    if len(set(header)) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise InputError("duplicate column", path=path, line=1, field=dup)
    body = [ln for ln in lines[1:] if ln.strip()]
    if not body:
        raise InputError("no data rows after the header", path=path, line=2)
    try:
        table = np.loadtxt(io.StringIO("\n".join(body)), delimiter=",", ndmin=2,
                           dtype=float)
        if table.shape[1] == len(header) and np.isfinite(table).all():
            return header, table
    except ValueError:
        pass
    # Slow path: find the first bad cell and say exactly where it is.
    for lineno, row in enumerate(csv.reader(lines[1:]), start=2):
        if not row or not "".join(row).strip():
            continue
        if len(row) != len(header):
            raise InputError(f"expected {len(header)} cells, found {len(row)}", path=path,
                             line=lineno)
        for col, cell in zip(header, row, strict=True):
            try:
                v = float(cell)
            except ValueError:
                raise InputError(f"not a number: {cell.strip()!r}", path=path, line=lineno,
                                 field=col) from None
            if not math.isfinite(v):
                raise InputError(f"value is {cell.strip()} (must be finite)", path=path,
                                 line=lineno, field=col)
    raise InputError("could not parse the table", path=path)  # pragma: no cover


def read_accel_csv(path: str | Path, rig: Rig) -> AccelData:
    """Read an accelerations CSV, checking its columns against the rig."""
    p = Path(path)
    header, table = _read_table(p)
    labels = sensor_labels(rig)
    required = accel_header(rig)
    missing = [c for c in required if c not in header]
    if missing:
        extra_sensors = sorted({c.rsplit(".", 1)[0] for c in header
                                if c.count(".") == 2 and c.rsplit(".", 1)[0] not in labels})
        hint = ""
        if extra_sensors or any(c.startswith(("a.", "b.")) for c in header):
            n_csv = len({c.rsplit(".", 1)[0] for c in header if c.count(".") == 2
                         and not c.endswith((".gx", ".gy", ".gz"))})
            hint = (f" (the rig has {len(labels)} sensors: {', '.join(labels)}; the CSV has "
                    f"{n_csv})")
        raise InputError(f"missing column(s) {', '.join(missing)}{hint}", path=p, line=1,
                         field=missing[0])
    idx = {c: i for i, c in enumerate(header)}
    t = table[:, idx["t"]]
    if len(t) > 1 and not np.all(np.diff(t) > 0):
        bad = int(np.argmax(np.diff(t) <= 0)) + 3
        raise InputError("time must increase from row to row", path=p, line=bad, field="t")
    readings = np.stack(
        [table[:, [idx[f"{lab}.x"], idx[f"{lab}.y"], idx[f"{lab}.z"]]] for lab in labels], 1)
    gyro = None
    if any(f"{lab}.gx" in idx for lab in labels):
        gyro = np.full_like(readings, np.nan)
        for k, lab in enumerate(labels):
            if f"{lab}.gx" in idx:
                gyro[:, k, :] = table[:, [idx[f"{lab}.gx"], idx[f"{lab}.gy"], idx[f"{lab}.gz"]]]
    truth = None
    if all(c in idx for c in TRUTH_COLUMNS):
        truth = Truth(*(table[:, idx[c]] for c in TRUTH_COLUMNS))
    return AccelData(t=t, readings=readings, gyro=gyro, truth=truth)


def write_estimates_csv(path: str | Path, t: np.ndarray, theta_rad: np.ndarray,
                        omega_a: np.ndarray, omega_b: np.ndarray,
                        extra: dict[str, np.ndarray] | None = None) -> None:
    cols = [t, np.degrees(theta_rad), np.degrees(omega_a), np.degrees(omega_b)]
    header = list(ESTIMATE_COLUMNS)
    for name, values in (extra or {}).items():
        header.append(name)
        cols.append(values)
    np.savetxt(path, np.stack(cols, 1), delimiter=",", header=",".join(header), comments="",
               fmt="%.9g")


@dataclass(frozen=True)
class EstimateTable:
    t: np.ndarray
    theta_deg: np.ndarray
    omega_a_dps: np.ndarray
    omega_b_dps: np.ndarray


def read_estimates_csv(path: str | Path) -> EstimateTable:
    p = Path(path)
    header, table = _read_table(p)
    for c in ESTIMATE_COLUMNS:
        if c not in header:
            raise InputError("missing column", path=p, line=1, field=c)
    idx = {c: i for i, c in enumerate(header)}
    return EstimateTable(*(table[:, idx[c]] for c in ESTIMATE_COLUMNS))
