"""The guided flow's side of a board: raw readings from its stream, and writing a calibration
to it with proof that it arrived.

Readings: every `sample_estimate` frame carries each sensor's raw counts; v = counts · the
firmware's own float32 m/s² per count (`device.calibration_map.mps2_per_count`), which is the v
the firmware multiplies S with — so S fitted on these v means the same thing on the board.

Writing (`write_calibration`): stop the stream (save_eeprom is refused while streaming), one
`set_calibration` per slot in rig order (S in Q24, offset in µm/s², rounded), `save_eeprom`,
then `get_calibration(slot, source=eeprom)` for every slot: the board reads its EEPROM image
back (CRC checked) and the values must equal what was sent, integer for integer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from jointangle.calibration.pipeline import CalibrationReport
from jointangle.device.calibration_map import mps2_per_count
from jointangle.device.configure import (
    CALIBRATION_FIELDS,
    SAVE_CONFIRM,
    SAVE_TIMEOUT_S,
    calibration_message,
)
from jointangle.device.rig import FAULT_BITS
from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import decode_message
from jointangle.protocol.framing import Frame
from jointangle.protocol.link import Link
from jointangle.rig import Rig


class ReadbackError(RuntimeError):
    """The board's stored calibration is not what was written."""


class StreamReadings:
    """Turns a board's frames into (t, readings, faulty sensors) for `PoseCollector.feed`."""

    def __init__(self, rig: Rig) -> None:
        sensors = rig.all_sensors()
        self.labels = [f"{ln}.{i}" for ln, i, _ in sensors]
        self.scale = np.array([float(mps2_per_count(s.model, s.range_g))
                               for _, _, s in sensors])
        self._last_us: int | None = None
        self._t_us = 0

    def convert(self, frames: list[Frame]) -> tuple[np.ndarray, np.ndarray, list[str]]:
        ts: list[float] = []
        rows: list[list[tuple[int, int, int]]] = []
        faulty: set[str] = set()
        for fr in frames:
            if fr.msg_id != msgs.SampleEstimate.MSG_ID:
                continue
            m = decode_message(fr)
            assert isinstance(m, msgs.SampleEstimate)
            if len(m.sensors) != len(self.labels):
                continue
            # Device clock in µs, unwrapped at 2³².
            if self._last_us is not None:
                self._t_us += (fr.t_us - self._last_us) % (1 << 32)
            self._last_us = fr.t_us
            ts.append(self._t_us * 1e-6)
            rows.append([(s.x, s.y, s.z) for s in m.sensors])
            for lb, s in zip(self.labels, m.sensors, strict=True):
                if s.status & FAULT_BITS:
                    faulty.add(lb)
        r = np.asarray(rows, dtype=float).reshape(len(rows), len(self.labels), 3)
        return np.asarray(ts), r * self.scale[None, :, None], sorted(faulty)


@dataclass(frozen=True)
class SlotWrite:
    """One slot: what was sent and what the EEPROM gave back (raw protocol integers)."""

    slot: int
    label: str
    sent: tuple[int, ...]  # s00..s22 (Q24), ox, oy, oz (µm/s²)
    stored: tuple[int, ...]

    @property
    def confirmed(self) -> bool:
        return self.sent == self.stored


def _fields(m: msgs.SetCalibration | msgs.Calibration) -> tuple[int, ...]:
    return tuple(int(getattr(m, f)) for f in CALIBRATION_FIELDS)


def read_calibration(link: Link, slot: int,
                     source: msgs.CalibrationSource = msgs.CalibrationSource.EEPROM
                     ) -> msgs.Calibration:
    """get_calibration -> the calibration frame (sent before the ack, kept by the Link)."""
    link.command(msgs.GetCalibration(slot=slot, source=int(source)))
    for fr in link.poll():
        if fr.msg_id == msgs.Calibration.MSG_ID:
            m = decode_message(fr)
            assert isinstance(m, msgs.Calibration)
            if m.slot == slot and m.source == int(source):
                return m
    raise ReadbackError(f"the board acknowledged get_calibration for slot {slot} but sent no "
                        "calibration frame")


def write_calibration(link: Link, rig: Rig, report: CalibrationReport) -> list[SlotWrite]:
    """Write every sensor's S and offset, save to EEPROM, read each slot back from EEPROM.
    The stream must be stopped. Raises ReadbackError when a stored value differs."""
    if not report.accepted:
        raise ValueError("calibration rejected: nothing is written")
    by_label = {s.label: s for s in report.sensors}
    sent = []
    for slot, (ln, i, _) in enumerate(rig.all_sensors()):
        r = by_label[f"{ln}.{i}"]
        assert r.S is not None and r.offset is not None
        msg = calibration_message(slot, r.S, r.offset)
        link.command(msg)
        sent.append((slot, r.label, _fields(msg)))
    link.command(msgs.SaveEeprom(confirm=SAVE_CONFIRM), timeout_s=SAVE_TIMEOUT_S)
    out = []
    for slot, label, values in sent:
        stored = _fields(read_calibration(link, slot))
        out.append(SlotWrite(slot, label, values, stored))
    bad = [w for w in out if not w.confirmed]
    if bad:
        raise ReadbackError("EEPROM read-back differs for " + ", ".join(
            f"slot {w.slot} ({w.label}): sent {w.sent}, stored {w.stored}" for w in bad))
    return out
