"""`replay --verify` in one pass with bounded memory (issue 16 item 6).

`device.verify.verify_columns` needs every sample_estimate frame of a recording in memory at
once (189 MB for 5 minutes at 500 Hz; over 2 GB for an hour). `StreamVerifier` takes the frames as
the streaming decoder delivers them, keeps at most CHUNK_FRAMES sample frames, and follows each
filter run across chunks with `MirrorState`: the same segments, the same losses before each
frame and the same differences as verify_columns over the whole recording (tested equal), at
O(CHUNK_FRAMES) memory. The differences themselves are kept (8 bytes a frame: 14 MB an hour).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from jointangle.device.calibration_map import DeviceMaps
from jointangle.device.rig import device_rig, filter_choice, filter_runs
from jointangle.device.verify import (
    STEADY_AFTER_S,
    THETA_LSB,
    VerifyResult,
    mirror_theta,
    starts_stream,
)
from jointangle.errors import InputError
from jointangle.estimators.base import wrap
from jointangle.estimators.mirror import MirrorState, step_periods
from jointangle.protocol import messages as msgs
from jointangle.protocol.bulk import bulk_decode, unpack_payloads
from jointangle.protocol.codec import SPECS_BY_NAME, decode_message
from jointangle.protocol.framing import Frame
from jointangle.recording.export import find_hello
from jointangle.rig import Rig

CHUNK_FRAMES = 32_768  # sample frames decoded and verified at a time (~2.3 MB of payloads)


@dataclass
class _Run:
    """The filter run (segment) still open at the end of the last chunk."""

    chosen: tuple[int, ...]
    state: MirrorState
    periods_done: int  # sample periods since the run's start (for the steady part)
    follow: bool  # filter_runs: whether the firmware filters on this choice


@dataclass
class StreamVerifier:
    """Feed every delivered frame in order (`frame`), then `result()`.

    `hello` is the sensor inventory: the first hello frame of the recording, else the one in
    its metadata (as `recording.export.find_hello` picks it)."""

    rig: Rig
    metadata: dict[str, Any]
    hello: msgs.Hello | None = None
    samples: int = 0  # sample_estimate frames of the hello's length
    _payloads: list[bytes] = field(default_factory=list)
    _t_us: list[int] = field(default_factory=list)
    _lost: list[int] = field(default_factory=list)  # unseen_before of each
    _prev_seq: int | None = None
    _lost_total: int = 0
    _lost_at_sample: int | None = None
    _setup: Any = None  # (device rig, maps, payload length) once the hello is known
    _run: _Run | None = None
    _last_choice: int = -1  # choice id of the last sample frame
    _choices: dict[tuple[int, ...], int] = field(default_factory=dict)
    _prev_t: int = 0
    _d: list[np.ndarray] = field(default_factory=list)
    _steady: list[np.ndarray] = field(default_factory=list)
    _segments: int = 0

    def frame(self, fr: Frame) -> None:
        if self._prev_seq is not None:  # losses as verify counts them: plain sequence gaps
            self._lost_total += (fr.seq - self._prev_seq - 1) & 0xFFFF
        self._prev_seq = fr.seq
        if fr.msg_id == msgs.Ack.MSG_ID:
            try:
                ack = decode_message(fr)
            except ValueError:
                return
            if isinstance(ack, msgs.Ack) and starts_stream(ack.command_id, ack.error):
                # Steps unseen without a gap (device.verify: unseen_before): counted as one.
                self._lost_total += 1
            return
        if fr.msg_id == msgs.SampleEstimate.MSG_ID:
            if self._ensure_setup() and len(fr.payload) != self._setup[2]:
                return  # another sensor count: left out as columns() leaves it out
            lost = 0 if self._lost_at_sample is None else self._lost_total - self._lost_at_sample
            self._lost_at_sample = self._lost_total
            self._payloads.append(fr.payload)
            self._t_us.append(fr.t_us)
            self._lost.append(lost)
            if len(self._payloads) >= CHUNK_FRAMES:
                self._flush()
        elif fr.msg_id == msgs.Hello.MSG_ID and self.hello is None:
            try:
                msg = decode_message(fr)
            except ValueError:
                return
            if isinstance(msg, msgs.Hello):
                self.hello = msg

    def result(self) -> dict[str, Any]:
        """verify_columns' figures (VerifyResult.as_dict) over everything fed."""
        self._flush(final=True)
        if self._setup is None:
            raise InputError("--verify needs sample_estimate frames (firmware estimates with "
                             "the samples they came from)", field="--verify")
        d = np.concatenate(self._d) if self._d else np.zeros(0)
        steady = np.concatenate(self._steady) if self._steady else np.zeros(0)
        return VerifyResult(d, steady, int(d.size), self.samples - int(d.size),
                            self._segments).as_dict()

    # ------------------------------------------------------------------------------------
    def _ensure_setup(self) -> bool:
        if self._setup is not None:
            return True

        # The metadata's hello, read as find_hello reads it (no frames to look in here).
        hello = self.hello or find_hello(bulk_decode(b""), self.metadata)
        if hello is None:
            return False
        drig = device_rig(self.rig, hello)
        length = SPECS_BY_NAME["sample_estimate"].payload_size(len(hello.sensors))
        self._setup = (drig, DeviceMaps.from_rig(drig), length)
        return True

    def _flush(self, final: bool = False) -> None:
        if not self._payloads:
            return
        if not self._ensure_setup():
            if final:
                raise InputError("--verify needs the sensor inventory (hello)", field="--verify")
            return  # (keep them until a hello turns up)
        _, _, length = self._setup
        # (Frames held before the inventory was known and of another length are left out.)
        keep = [i for i, p in enumerate(self._payloads) if len(p) == length]
        payloads = np.frombuffer(b"".join(self._payloads[i] for i in keep),
                                 dtype=np.uint8).reshape(len(keep), length)
        t_us = np.asarray([self._t_us[i] for i in keep], dtype=np.int64)
        lost = np.asarray([self._lost[i] for i in keep], dtype=np.int64)
        self._payloads.clear()
        self._t_us.clear()
        self._lost.clear()
        if payloads.shape[0]:
            self._verify_chunk(payloads, t_us, lost)

    def _verify_chunk(self, payloads: np.ndarray, t_us: np.ndarray, lost: np.ndarray) -> None:
        drig, maps, _ = self._setup
        cols = unpack_payloads("sample_estimate", payloads)
        n = payloads.shape[0]
        self.samples += n
        health = cols["health"].astype(np.int64)
        running = (health & msgs.FilterHealth.RUNNING) != 0
        reset = (health & msgs.FilterHealth.RESET) != 0
        # The firmware's sensor choice per frame, as an id (filter_choice per distinct status).
        status = np.asarray(cols["sensors.status"]).reshape(n, -1)
        uniq, inverse = np.unique(status, axis=0, return_inverse=True)
        ids = np.asarray([self._choice_id(filter_choice(drig, row)) for row in uniq])
        cid = ids[np.asarray(inverse).reshape(-1)]
        prev_cid = np.concatenate([[self._last_choice], cid[:-1]])
        # A run goes on through a frame that is running, not a reset, has nothing lost before it
        # nor a stream start (unseen_before) and the same choice (device.verify.segments, frame
        # by frame); a reset starts one.
        goes_on = running & ~reset & (lost == 0) & (cid == prev_cid)
        starts = running & reset
        idx = np.arange(n)
        last_stop = np.maximum.accumulate(np.where(goes_on, -1, idx))
        active = np.where(last_stop >= 0, starts[np.maximum(last_stop, 0)], self._run is not None)
        counts = np.stack([cols["sensors.x"], cols["sensors.y"], cols["sensors.z"]], axis=2)
        theta = cols["theta"].astype(float) * THETA_LSB
        steady_k = round(STEADY_AFTER_S * drig.sample_rate_hz)
        rate = drig.sample_rate_hz
        # Pieces: runs of active frames with one start (-1: the run open before this chunk).
        prev_active = np.concatenate([[False], active[:-1]])
        prev_stop = np.concatenate([[-2], last_stop[:-1]])
        begins = np.flatnonzero(active & (~prev_active | (last_stop != prev_stop)))
        ends = np.flatnonzero(~active | (last_stop != prev_stop))  # where a piece cannot go on
        run = self._run
        if not active[0]:
            run = None  # the open run ended at the first frame
        for a in begins.tolist():
            after = ends[np.searchsorted(ends, a, side="right"):]
            b = int(after[0]) if after.size else n
            if last_stop[a] >= 0:  # a new run starts at a
                chosen = filter_choice(drig, status[a])
                run = _Run(chosen, MirrorState.fresh(1), 0, filter_runs(drig, chosen))
                if run.follow:
                    self._segments += 1
                periods = step_periods(t_us[a:b], rate)
            else:
                assert run is not None
                periods = step_periods(np.concatenate([[self._prev_t], t_us[a:b]]), rate)[1:]
            if run.follow:
                host = mirror_theta(drig, maps, counts[a:b], run.chosen, state=run.state,
                                    periods=periods)
                d = np.degrees(wrap(theta[a:b] - host))
                self._d.append(d)
                done = run.periods_done + np.cumsum(periods)
                self._steady.append(d[done - 1 >= steady_k])
            run.periods_done += int(np.sum(periods))
            if b < n:
                run = None
        self._run = run if active[-1] else None
        self._last_choice = int(cid[-1])
        self._prev_t = int(t_us[-1])

    def _choice_id(self, chosen: tuple[int, ...]) -> int:
        return self._choices.setdefault(chosen, len(self._choices))
