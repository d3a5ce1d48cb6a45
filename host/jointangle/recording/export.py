"""Decode a recording and export it to the accelerations and estimates CSVs (docs/design.md §4).

Counts become m/s² with each sensor's model and range from the firmware's `hello` (in the
recording, else in the metadata under "hello"); θ and ω come from `estimate` or `sample_estimate`
frames (fixed point as defined in protocol/messages.toml). Time is the device clock (t_us,
unwrapped across its 32-bit wrap) in seconds from the first exported frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from jointangle.errors import InputError
from jointangle.io.csv_formats import write_table
from jointangle.protocol import messages as msgs
from jointangle.protocol.bulk import BulkResult, bulk_decode
from jointangle.protocol.codec import SPECS_BY_NAME, decode_message
from jointangle.protocol.framing import Frame
from jointangle.recording.jrec import JrecReader
from jointangle.sensors import SENSOR_MODELS

_THETA_Q = 2.0**-24  # rad per LSB (estimate.theta, sample_estimate.theta)
_OMEGA_Q = 2.0**-16  # rad/s per LSB


def unwrap_us(t_us: npt.NDArray[Any]) -> npt.NDArray[np.int64]:
    """Unwrap a 32-bit microsecond clock (monotonic input assumed, wraps every ~71.6 min)."""
    t = t_us.astype(np.int64)
    if t.size < 2:
        return t
    steps = np.diff(t)
    wraps = np.concatenate([[0], np.cumsum(steps < -(1 << 31))])
    return t + (wraps << 32)


@dataclass(frozen=True)
class Inventory:
    """Sensors in rig order: CSV labels ('a.0', ...) and the m/s² of one count."""

    labels: tuple[str, ...]
    lsb_mps2: tuple[float, ...]


def inventory_from_hello(hello: msgs.Hello) -> Inventory:
    labels: list[str] = []
    lsb: list[float] = []
    per_link = {0: 0, 1: 0}
    for s in hello.sensors:
        link = "a" if s.link == 0 else "b"
        labels.append(f"{link}.{per_link[s.link & 1]}")
        per_link[s.link & 1] += 1
        try:
            model = SENSOR_MODELS[msgs.SensorModel(s.model).name.lower()]
            lsb.append(model.lsb_mps2(s.range_g))
        except (ValueError, KeyError):
            lsb.append(math.nan)  # unknown part or range: exported as NaN, never guessed
    return Inventory(tuple(labels), tuple(lsb))


def find_hello(result: BulkResult, metadata: dict[str, Any]) -> msgs.Hello | None:
    for pos, payload in result.payloads(msgs.Hello.MSG_ID):
        for p, row in sorted(zip(pos.tolist(), payload, strict=True), key=lambda x: x[0]):
            fr = Frame(msgs.Hello.MSG_ID, int(result.seq[p]), int(result.t_us[p]), row.tobytes())
            try:
                msg = decode_message(fr)
            except ValueError:
                continue
            if isinstance(msg, msgs.Hello):
                return msg
    meta = metadata.get("hello")
    if isinstance(meta, dict):
        try:
            sensors = tuple(msgs.HelloSensor(**s) for s in meta.get("sensors", []))
            fields = {k: v for k, v in meta.items() if k != "sensors"}
            if isinstance(fields.get("build"), str):
                fields["build"] = fields["build"].encode().ljust(12, b"\x00")[:12]
            return msgs.Hello(**fields, sensors=sensors)
        except TypeError:
            return None
    return None


def _data_columns(result: BulkResult) -> tuple[str, dict[str, np.ndarray]] | None:
    """Columns of the richest data message present: sample_estimate, else samples."""
    for name in ("sample_estimate", "samples"):
        if (result.msg_id == SPECS_BY_NAME[name].msg_id).any():
            return name, result.columns(name)
    return None


@dataclass(frozen=True)
class CsvTable:
    """A CSV to write: its column names and its float rows."""

    header: tuple[str, ...]
    rows: np.ndarray  # (rows, columns)

    def write(self, out: str | Path) -> int:
        """Write it whole or not at all (`write_table`); returns the number of rows."""
        write_table(out, self.header, self.rows)
        return len(self.rows)


def accelerations_table(rec: JrecReader) -> CsvTable:
    """The accelerations CSV of a recording (m/s², sensor frames)."""
    result = bulk_decode(rec.data())
    hello = find_hello(result, rec.metadata)
    if hello is None:
        raise InputError("no sensor inventory: the recording has no hello frame and no 'hello' "
                         "in its metadata", path=rec.path)
    inv = inventory_from_hello(hello)
    found = _data_columns(result)
    if found is None:
        raise InputError("no samples or sample_estimate frames to export", path=rec.path)
    _, cols = found
    n_sensors = cols["sensors.x"].shape[1] if cols["sensors.x"].ndim == 2 else 0
    if n_sensors != len(inv.labels):
        raise InputError(f"frames carry {n_sensors} sensors but the hello lists "
                         f"{len(inv.labels)}", path=rec.path)
    t = unwrap_us(cols["t_us"])
    t_s = (t - (t[0] if t.size else 0)) / 1e6
    lsb = np.array(inv.lsb_mps2)
    header = ["t"]
    xyz = np.stack([cols["sensors.x"], cols["sensors.y"], cols["sensors.z"]], axis=2) * \
        lsb[None, :, None]
    for lab in inv.labels:
        header += [f"{lab}.x", f"{lab}.y", f"{lab}.z"]
    return CsvTable(tuple(header), np.hstack([t_s[:, None], xyz.reshape(len(t_s), -1)]))


def estimates_table(rec: JrecReader, sources: tuple[str, ...] = ("estimate", "sample_estimate")
                    ) -> CsvTable:
    """The firmware's estimates CSV of a recording (t, theta_deg, omega_a_dps, omega_b_dps,
    health), from the first message of `sources` the recording has."""
    result = bulk_decode(rec.data())
    cols: dict[str, np.ndarray] | None = None
    for name in sources:
        if (result.msg_id == SPECS_BY_NAME[name].msg_id).any():
            cols = result.columns(name)
            break
    if cols is None:
        raise InputError(f"no {' or '.join(sources)} frames to export", path=rec.path)
    t = unwrap_us(cols["t_us"])
    t_s = (t - (t[0] if t.size else 0)) / 1e6
    table = np.stack([
        t_s,
        np.degrees(cols["theta"] * _THETA_Q),
        np.degrees(cols["omega_a"] * _OMEGA_Q),
        np.degrees(cols["omega_b"] * _OMEGA_Q),
        cols["health"].astype(np.float64),
    ], axis=1)
    return CsvTable(("t", "theta_deg", "omega_a_dps", "omega_b_dps", "health"), table)


def export_accelerations(rec: JrecReader, out: str | Path) -> int:
    """Write the accelerations CSV; returns the number of rows."""
    return accelerations_table(rec).write(out)


def export_estimates(rec: JrecReader, out: str | Path) -> int:
    """Write the estimates CSV (t, theta_deg, omega_a_dps, omega_b_dps, health)."""
    return estimates_table(rec).write(out)
