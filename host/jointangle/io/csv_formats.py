"""The accelerations CSV and the estimates CSV (docs/design.md §4).

Accelerations: `t,a.0.x,a.0.y,a.0.z,a.1.x,…,b.0.x,…` in m/s² in each sensor's own frame, links a
then b in rig order; optional gyro columns `a.0.gx,…` (rad/s) and optional truth columns
`theta,omega_a,omega_b` (rad, rad/s). Estimators never read the truth columns.

Estimates: `t,theta_deg,omega_a_dps,omega_b_dps` plus optional uncertainty columns.
"""

from __future__ import annotations

import io
import math
import re
from collections.abc import Collection, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NoReturn

import numpy as np

from jointangle.errors import InputError
from jointangle.io.atomic import atomic_path
from jointangle.io.input_files import CSV_MAX_BYTES, read_input_text
from jointangle.rig import Rig, sensor_labels
from jointangle.sensors import SENSOR_MODELS, STANDARD_GRAVITY

TRUTH_COLUMNS = ("theta", "omega_a", "omega_b")
ESTIMATE_COLUMNS = ("t", "theta_deg", "omega_a_dps", "omega_b_dps")
# Plausible readings: an accelerometer saturates at its range (range_g · g); anything beyond
# twice that cannot come from the part (a unit mix-up, a corrupted cell) and would wreck the
# filters (a 1e6 cell: "not positive definite"; 1e300: NaN estimates).
PLAUSIBLE_FULL_SCALES = 2.0
MAX_GYRO_RAD_S = 70.0  # twice the BNO055's ±2000 °/s


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
    write_table(path, header, table)


def write_table(path: str | Path, header: Sequence[str], table: np.ndarray) -> None:
    """A CSV of `header` and the float rows of `table`, written whole or not at all (a write
    error is an InputError naming `path`; the file there before is kept)."""
    with atomic_path(path) as tmp:
        np.savetxt(tmp, table, delimiter=",", header=",".join(header), comments="", fmt="%.9g")


@dataclass(frozen=True)
class _Table:
    header: list[str]
    values: np.ndarray  # (rows, columns)
    lines: np.ndarray  # (rows,) the file's line number of each row (blank lines are skipped)

    def column(self, name: str) -> np.ndarray:
        return self.values[:, self.header.index(name)]


def _read_header(path: Path) -> tuple[list[str], list[str]]:
    """The header's column names and the file's lines; errors name the line and the column."""
    # A regular file under the size cap, or refused before reading (a FIFO blocked forever).
    text = read_input_text(path, "CSV", CSV_MAX_BYTES, "expected a CSV")
    lines = text.removeprefix("\ufeff").splitlines()  # a BOM (spreadsheet exports) is no text
    if not lines or not lines[0].strip():
        raise InputError("empty file: expected a header line", path=path, line=1)
    header = [h.strip() for h in lines[0].split(",")]
    if len(set(header)) != len(header):
        dup = next(h for h in header if header.count(h) > 1)
        raise InputError("duplicate column", path=path, line=1, field=dup)
    return header, lines


# A cell is a number as np.loadtxt (the fast path) reads one: no '#' comment, no quotes (csv
# would unquote them), no digit separators or non-ASCII digits (float() takes both). The precise
# check below must refuse exactly what the fast path refuses.
_NUMBER = re.compile(r"\s*[+-]?(?:(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
                     r"|inf(?:inity)?|nan)\s*", re.IGNORECASE)


def _cell_value(cell: str) -> float | None:
    """The number a cell holds, None if it is not one."""
    return float(cell) if _NUMBER.fullmatch(cell) else None


def _read_table(path: Path, header: list[str], lines: list[str],
                nan_ok: Collection[str] = ()) -> _Table:
    """The float table under the header. Every cell must be a finite number, except that the
    columns in `nan_ok` may hold NaN; '#' starts no comment. Errors name the line and the
    column."""
    numbered = [(n, ln) for n, ln in enumerate(lines[1:], start=2) if ln.strip()]
    if not numbered:
        raise InputError("no data rows after the header", path=path, line=2)
    row_lines = np.array([n for n, _ in numbered])
    nan_cols = np.array([c in nan_ok for c in header])
    try:
        table = np.loadtxt(io.StringIO("\n".join(ln for _, ln in numbered)), delimiter=",",
                           comments=None, ndmin=2, dtype=float)
        if table.shape[1] == len(header) and (np.isfinite(table)
                                              | (np.isnan(table) & nan_cols)).all():
            return _Table(header, table, row_lines)
    except ValueError:
        pass
    _raise_first_bad_cell(path, header, numbered, nan_ok)


def _raise_first_bad_cell(path: Path, header: list[str], numbered: list[tuple[int, str]],
                          nan_ok: Collection[str]) -> NoReturn:
    """Slow path of `_read_table`: the same rows split the same way, cell by cell, to say
    exactly where the first bad cell is."""
    for lineno, line in numbered:
        row = line.split(",")
        if len(row) != len(header):
            raise InputError(f"expected {len(header)} cells, found {len(row)}", path=path,
                             line=lineno)
        for col, cell in zip(header, row, strict=True):
            v = _cell_value(cell)
            if v is None:
                raise InputError(f"not a number: {cell.strip()!r}", path=path, line=lineno,
                                 field=col)
            if not math.isfinite(v) and not (math.isnan(v) and col in nan_ok):
                raise InputError(f"value is {cell.strip()} (must be finite)", path=path,
                                 line=lineno, field=col)
    raise InputError("could not parse the table", path=path)  # pragma: no cover


_SENSOR_COLUMN = re.compile(r"([ab])\.(\d+)\.(x|y|z|gx|gy|gz)")


def _check_columns(p: Path, header: list[str], rig: Rig) -> None:
    """Every column the rig needs is there, and no sensor column names a sensor it lacks."""
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
    for col in header:
        m = _SENSOR_COLUMN.fullmatch(col)
        if m is not None and f"{m[1]}.{m[2]}" not in labels:
            n = rig.sensor_count(m[1])
            raise InputError(
                f"a column of sensor {m[1]}.{m[2]}, which the rig does not have (link {m[1]} "
                f"has {n} sensors: {', '.join(f'{m[1]}.{i}' for i in range(n))}); remove it or "
                "describe that sensor in the rig file", path=p, line=1, field=col)
    models = {f"{ln}.{i}": s.model for ln, i, s in rig.all_sensors()}
    for lab in labels:
        present = [f"{lab}.{ax}" in header for ax in ("gx", "gy", "gz")]
        if any(present) and not SENSOR_MODELS[models[lab]].has_gyro:
            col = next(f"{lab}.{ax}" for ax, ok in zip(("gx", "gy", "gz"), present,
                                                       strict=True) if ok)
            raise InputError(f"sensor {lab} is an {models[lab]} in the rig, which has no gyro: "
                             "remove its gyro columns or give the rig its real model", path=p,
                             line=1, field=col)
        if any(present) and not all(present):
            gone = next(f"{lab}.{ax}" for ax, ok in zip(("gx", "gy", "gz"), present,
                                                        strict=True) if not ok)
            raise InputError(f"missing column {gone} (a gyro has all three axes)", path=p,
                             line=1, field=gone)


def _check_plausible(p: Path, tab: _Table, rig: Rig) -> None:
    """Readings no sensor of the rig can give are refused, naming the first such cell: an
    accelerometer's beyond PLAUSIBLE_FULL_SCALES × its range (the part saturates at 1 ×), a
    gyro's beyond MAX_GYRO_RAD_S."""
    limits: dict[str, float] = {}
    for lab, (_, _, s) in zip(sensor_labels(rig), rig.all_sensors(), strict=True):
        for ax in ("x", "y", "z"):
            limits[f"{lab}.{ax}"] = PLAUSIBLE_FULL_SCALES * s.range_g * STANDARD_GRAVITY
            limits[f"{lab}.g{ax}"] = MAX_GYRO_RAD_S
    cols = [k for k, c in enumerate(tab.header) if c in limits]
    bound = np.array([limits[tab.header[k]] for k in cols])
    over = np.abs(tab.values[:, cols]) > bound
    if not over.any():
        return
    row, j = np.argwhere(over)[0]
    col = tab.header[cols[j]]
    value = float(tab.values[row, cols[j]])
    if col.rsplit(".", 1)[1].startswith("g"):
        why = (f"{value:.6g} rad/s is not a gyro reading (a BNO055 reads at most ±2000 °/s = "
               f"34.9 rad/s; refused above {MAX_GYRO_RAD_S:g} rad/s)")
    else:
        lab = col.rsplit(".", 1)[0]
        _, _, s = rig.all_sensors()[sensor_labels(rig).index(lab)]
        why = (f"{value:.6g} m/s² is beyond what sensor {lab} ({s.model}, range_g = "
               f"{s.range_g}) can read: it saturates at {s.range_g * STANDARD_GRAVITY:.4g} m/s² "
               f"(refused above {PLAUSIBLE_FULL_SCALES:g}× that)")
    raise InputError(why, path=p, line=int(tab.lines[row]), field=col)


def read_accel_csv(path: str | Path, rig: Rig) -> AccelData:
    """Read an accelerations CSV, checking its columns and readings against the rig.

    Only the columns estimators read (t, accelerations, gyro rates) must be finite; truth
    columns may hold NaN where the truth is unknown (those samples are not scored).
    """
    p = Path(path)
    header, lines = _read_header(p)
    _check_columns(p, header, rig)
    labels = sensor_labels(rig)
    # NaN is refused only where an estimator would read it: t and the sensor columns.
    tab = _read_table(p, header, lines, nan_ok=[c for c in header if c != "t"
                                                 and _SENSOR_COLUMN.fullmatch(c) is None])
    t = tab.column("t")
    if len(t) > 1 and not np.all(np.diff(t) > 0):
        bad = int(np.argmax(np.diff(t) <= 0)) + 1
        raise InputError("time must increase from row to row", path=p,
                         line=int(tab.lines[bad]), field="t")
    _check_plausible(p, tab, rig)
    readings = np.stack([tab.values[:, [header.index(f"{lab}.{ax}") for ax in ("x", "y", "z")]]
                         for lab in labels], 1)
    gyro = None
    if any(f"{lab}.gx" in header for lab in labels):
        gyro = np.full_like(readings, np.nan)
        for k, lab in enumerate(labels):
            if f"{lab}.gx" in header:
                gyro[:, k, :] = tab.values[:, [header.index(f"{lab}.g{ax}")
                                               for ax in ("x", "y", "z")]]
    truth = None
    if all(c in header for c in TRUTH_COLUMNS):
        truth = Truth(*(tab.column(c) for c in TRUTH_COLUMNS))
    return AccelData(t=t, readings=readings, gyro=gyro, truth=truth)


def write_estimates_csv(path: str | Path, t: np.ndarray, theta_rad: np.ndarray,
                        omega_a: np.ndarray, omega_b: np.ndarray,
                        extra: dict[str, np.ndarray] | None = None) -> None:
    cols = [t, np.degrees(theta_rad), np.degrees(omega_a), np.degrees(omega_b)]
    header = list(ESTIMATE_COLUMNS)
    for name, values in (extra or {}).items():
        header.append(name)
        cols.append(values)
    write_table(path, header, np.stack(cols, 1))


@dataclass(frozen=True)
class EstimateTable:
    t: np.ndarray
    theta_deg: np.ndarray
    omega_a_dps: np.ndarray
    omega_b_dps: np.ndarray


def read_estimates_csv(path: str | Path) -> EstimateTable:
    p = Path(path)
    header, lines = _read_header(p)
    for c in ESTIMATE_COLUMNS:
        if c not in header:
            raise InputError("missing column", path=p, line=1, field=c)
    # analytical and smooth have no rates where they cannot difference θ: NaN there is theirs.
    tab = _read_table(p, header, lines, nan_ok=[c for c in header if c not in ("t", "theta_deg")])
    return EstimateTable(*(tab.column(c) for c in ESTIMATE_COLUMNS))
