"""`replay --accel-csv/--estimates-csv` in one pass with bounded memory (issue 16 item 6).

`recording.export` builds each CSV from the whole recording decoded at once. `StreamExport`
takes the frames as the streaming decoder delivers them and spools the integer columns it needs
to a temporary binary file per (message, payload length) -- a few tens of bytes a frame on
disk, CHUNK_FRAMES frames in memory -- then writes the CSVs from those files chunk by chunk.
It picks the same message, the same payload length, the same sensor inventory and writes the
same rows (`write_table`'s %.9g) as `accelerations_table` / `estimates_table` (tested equal).
Every check is made before anything is written; the CSVs are written whole or not at all.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, BinaryIO

import numpy as np

from jointangle.errors import InputError
from jointangle.io.atomic import atomic_path
from jointangle.protocol import messages as msgs
from jointangle.protocol.bulk import bulk_decode, unpack_payloads
from jointangle.protocol.codec import SPECS_BY_ID, SPECS_BY_NAME, decode_message
from jointangle.protocol.framing import Frame
from jointangle.recording.export import find_hello, inventory_from_hello

CHUNK_FRAMES = 32_768  # frames held in memory per message kind before they are spooled
_SPOOLED = ("samples", "sample_estimate", "estimate")
_THETA_Q = 2.0**-24  # rad per LSB (as recording.export)
_OMEGA_Q = 2.0**-16


@dataclass
class _Spool:
    """The frames of one (message, payload length): t_us and the integer fields a CSV needs,
    as int64 rows in a temporary file."""

    name: str
    length: int
    width: int = 0
    rows: int = 0
    pending: list[bytes] = field(default_factory=list)
    t_us: list[int] = field(default_factory=list)
    file: BinaryIO | None = None

    def flush(self, folder: Path, out: Path) -> None:
        """Spool the pending frames (beside `out`, the CSV named in a write error)."""
        if not self.pending:
            return
        n = len(self.pending)
        payloads = np.frombuffer(b"".join(self.pending), dtype=np.uint8).reshape(n, self.length)
        cols = unpack_payloads(self.name, payloads)
        block = [np.asarray(self.t_us, dtype=np.int64)[:, None]]
        if "sensors.x" in cols:
            xyz = np.stack([cols["sensors.x"], cols["sensors.y"], cols["sensors.z"]], axis=2)
            block.append(xyz.reshape(n, -1).astype(np.int64))
        if "theta" in cols:
            block.append(np.stack([cols["theta"], cols["omega_a"], cols["omega_b"],
                                   cols["health"]], axis=1).astype(np.int64))
        table = np.hstack(block)
        self.width = table.shape[1]
        try:
            if self.file is None:
                self.file = tempfile.TemporaryFile(  # noqa: SIM115 (closed by close())
                    dir=folder, prefix=".jointangle-export-")
            table.tofile(self.file)
        except OSError as exc:  # a full disk: the CSV cannot be written either
            raise InputError(f"cannot write: {exc.strerror or exc} (while spooling the "
                             "recording's frames beside it)", path=out) from None
        self.rows += n
        self.pending.clear()
        self.t_us.clear()

    def chunks(self) -> Iterator[np.ndarray]:
        """The spooled rows, CHUNK_FRAMES at a time."""
        if self.file is None:
            return
        self.file.flush()
        self.file.seek(0)
        while True:
            block = np.fromfile(self.file, dtype=np.int64, count=CHUNK_FRAMES * self.width)
            if not block.size:
                return
            yield block.reshape(-1, self.width)

    def close(self) -> None:
        if self.file is not None:
            self.file.close()
            self.file = None


@dataclass
class StreamExport:
    """Feed every delivered frame in order (`frame`), then `write()`."""

    path: Path  # the recording (named in errors)
    metadata: dict[str, Any]
    accel_out: Path | None
    estimates_out: Path | None
    hello: msgs.Hello | None = None
    _spools: dict[tuple[str, int], _Spool] = field(default_factory=dict)
    _folder: Path = field(default_factory=lambda: Path(tempfile.gettempdir()))
    _named: Path = Path()  # the output a spooling error names

    def __post_init__(self) -> None:
        out = self.estimates_out or self.accel_out
        if out is not None:  # spool beside an output: its file system has room for it
            self._named = Path(out)
            given = Path(out)
            special = given.exists() and not given.is_file()  # /dev/stdout, /dev/null, a FIFO
            real = Path(os.path.realpath(given))
            if not special and os.access(real.parent, os.W_OK | os.X_OK):
                self._folder = real.parent

    def frame(self, fr: Frame) -> None:
        spec = SPECS_BY_ID.get(fr.msg_id)
        if spec is None:
            return
        if spec.name in _SPOOLED and _readable(spec.name, len(fr.payload)):
            key = (spec.name, len(fr.payload))
            spool = self._spools.get(key)
            if spool is None:
                spool = self._spools[key] = _Spool(spec.name, len(fr.payload))
            spool.pending.append(fr.payload)
            spool.t_us.append(fr.t_us)
            if len(spool.pending) >= CHUNK_FRAMES:
                spool.flush(self._folder, self._named)
        elif fr.msg_id == msgs.Hello.MSG_ID and self.hello is None:
            with contextlib.suppress(ValueError):
                msg = decode_message(fr)
                if isinstance(msg, msgs.Hello):
                    self.hello = msg

    def write(self) -> dict[str, int]:
        """Check both tables, then write them (each whole or not at all); rows per CSV."""
        try:
            for spool in self._spools.values():
                spool.flush(self._folder, self._named)
            plans: list[tuple[str, Path, Any]] = []
            if self.accel_out is not None:
                plans.append(("accel_rows", self.accel_out, self._accel_plan()))
            if self.estimates_out is not None:
                plans.append(("estimate_rows", self.estimates_out, self._estimates_plan()))
            with contextlib.ExitStack() as stack:
                tmps = [stack.enter_context(atomic_path(out)) for _, out, _ in plans]
                done = {key: self._write_csv(tmp, plan) for (key, _, plan), tmp
                        in zip(plans, tmps, strict=True)}
            return done
        finally:
            for spool in self._spools.values():
                spool.close()

    # ------------------------------------------------------------------------------------
    def _pick(self, name: str) -> _Spool | None:
        """The spool `columns(name)` would read: the payload length with the most frames (the
        shortest of a tie); for a message without a group, its one valid length."""
        spec = SPECS_BY_NAME[name]
        mine = sorted((s for (n, _), s in self._spools.items() if n == name and s.rows),
                      key=lambda s: s.length)
        if spec.group is None:
            return next((s for s in mine if s.length == spec.fixed_size), None)
        g = spec.group
        best: _Spool | None = None
        for s in mine:
            m = s.length
            if (m - spec.fixed_size - 1) % g.item_size == 0 and m > spec.fixed_size and \
                    (best is None or s.rows > best.rows):
                best = s
        return best

    def _present(self, name: str) -> bool:
        return any(n == name and s.rows for (n, _), s in self._spools.items())

    def _accel_plan(self) -> tuple[str, tuple[str, ...], _Spool | None, np.ndarray]:
        hello = self.hello or find_hello(bulk_decode(b""), self.metadata)
        if hello is None:
            raise InputError("no sensor inventory: the recording has no hello frame and no "
                             "'hello' in its metadata", path=self.path)
        inv = inventory_from_hello(hello)
        name = next((n for n in ("sample_estimate", "samples") if self._present(n)), None)
        if name is None:
            raise InputError("no samples or sample_estimate frames to export", path=self.path)
        spool = self._pick(name)
        n_sensors = 0 if spool is None else (spool.width - 1 - (name != "samples") * 4) // 3
        if n_sensors != len(inv.labels):
            raise InputError(f"frames carry {n_sensors} sensors but the hello lists "
                             f"{len(inv.labels)}", path=self.path)
        header = ["t"]
        for lab in inv.labels:
            header += [f"{lab}.x", f"{lab}.y", f"{lab}.z"]
        return "accel", tuple(header), spool, np.array(inv.lsb_mps2)

    def _estimates_plan(self) -> tuple[str, tuple[str, ...], _Spool | None, np.ndarray]:
        sources = ("estimate", "sample_estimate")
        name = next((n for n in sources if self._present(n)), None)
        if name is None:
            raise InputError(f"no {' or '.join(sources)} frames to export", path=self.path)
        return ("estimates", ("t", "theta_deg", "omega_a_dps", "omega_b_dps", "health"),
                self._pick(name), np.zeros(0))

    def _write_csv(self, tmp: Path, plan: tuple[str, tuple[str, ...], _Spool | None,
                                                 np.ndarray]) -> int:
        kind, header, spool, lsb = plan
        rows = 0
        t0: int | None = None
        prev = 0
        wraps = 0
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(",".join(header) + "\n")
            for block in ([] if spool is None else spool.chunks()):
                t = block[:, 0]
                steps = np.diff(np.concatenate([[prev if t0 is not None else t[0]], t]))
                w = wraps + np.cumsum(steps < -(1 << 31))  # recording.export.unwrap_us
                wraps = int(w[-1])
                prev = int(t[-1])
                tt = t + (w << 32)
                if t0 is None:
                    t0 = int(tt[0])
                t_s = (tt - t0) / 1e6
                if kind == "accel":
                    n = lsb.size
                    xyz = block[:, 1 : 1 + 3 * n].reshape(-1, n, 3) * lsb[None, :, None]
                    table = np.hstack([t_s[:, None], xyz.reshape(len(t_s), -1)])
                else:
                    est = block[:, -4:]
                    table = np.stack([t_s, np.degrees(est[:, 0] * _THETA_Q),
                                      np.degrees(est[:, 1] * _OMEGA_Q),
                                      np.degrees(est[:, 2] * _OMEGA_Q),
                                      est[:, 3].astype(np.float64)], axis=1)
                np.savetxt(f, table, delimiter=",", fmt="%.9g")
                rows += len(table)
        return rows


def _readable(name: str, length: int) -> bool:
    """A payload length `columns(name)` can read: the fixed size, or a whole group."""
    spec = SPECS_BY_NAME[name]
    if spec.group is None:
        return length == spec.fixed_size
    return length > spec.fixed_size and \
        (length - spec.fixed_size - 1) % spec.group.item_size == 0
