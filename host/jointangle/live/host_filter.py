"""A host estimator on the board's raw readings as they arrive (`live`, `record`).

The board streams each step's raw counts with its own θ. `HostFilter` turns the counts into the
firmware's own link-frame readings (`device_readings`) and runs a streaming estimator
(`jointangle.estimators.streaming`) on them, `batch_s` of samples at a time (each push has a
fixed cost, so one per sample would not keep up at 500 Hz). Every board estimate comes back
paired with the host's estimate of the sample `lag` samples before it (the newest one that is
final: array-fls smooths over the 100 ms after a sample), or None while there is none.

A run of samples (a *segment*) ends where the stream does not step by one sample period (frames
lost, a board that misses periods, a reconnect), where the usable sensors change (a fault), or
where the estimator loses track; the next segment starts the estimator afresh, and the old one
hands out its last samples first. At least two usable sensors per link are needed.

Keeping up: the CPU time spent in the estimator is measured (thread time) per sample, and the
backlog is how much later than when it should have (device clock) the newest sample was
processed, relative to the smallest such delay seen. When, after `WARMUP_S`, the estimator
takes more than `MAX_LOAD` of the sample period over the last `LOAD_WINDOW_S`, or the backlog
passes `MAX_BACKLOG_S` (or that much of samples wait for one run: a board faster than real
time, sim://…?fast=1), it is switched off (and says why): the board's stream and a recording
must never suffer for it.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from jointangle.device.calibration_map import DeviceMaps, device_readings
from jointangle.device.rig import FAULT_BITS
from jointangle.device.rig import sub_rig as rig_of_sensors
from jointangle.device.verify import STEADY_AFTER_S
from jointangle.errors import InputError
from jointangle.estimators.base import Estimates
from jointangle.estimators.registry import ESTIMATORS
from jointangle.estimators.streaming import STREAMING, StreamingEstimator, streaming_estimator
from jointangle.live.session import Estimate
from jointangle.rig import Rig

DEFAULT_HOST_FILTER = "array-fls"
HOST_BATCH_S = 0.05  # samples pushed at a time (device time): 25 at 500 Hz
MAX_LOAD = 0.7  # of the sample period, over LOAD_WINDOW_S: the rest for decoding and display
# Estimates this late are of no use live. (A loaded 2-core machine delayed them by up to 0.9 s
# for a moment, and they caught up: the limit leaves room for that.)
MAX_BACKLOG_S = 5.0
LOAD_WINDOW_S = 5.0
WARMUP_S = 2.0  # the first pushes pay for imports and caches


@dataclass(frozen=True)
class HostEstimate:
    device_t: float  # s, the board clock of the sample it estimates
    theta_deg: float
    omega_a_dps: float  # NaN where the estimator has no ω (analytical)
    omega_b_dps: float
    segment_s: float  # s since its segment started (start-up vs steady)


def _num(v: float) -> float | None:
    return None if not math.isfinite(v) else round(v, 6)


class HostFilter:
    """Runs `name` (a streaming estimator) on the board's readings; see the module docstring.

    `rig` is the rig as the board sees it (`device_rig`: its rate, datasheet noise)."""

    def __init__(self, name: str, rig: Rig, batch_s: float = HOST_BATCH_S,
                 cpu_clock: Callable[[], float] = time.thread_time) -> None:
        self.name = name
        self.cpu_clock = cpu_clock  # the estimator's CPU time: this thread's
        self.rig = rig
        self.maps = DeviceMaps.from_rig(rig)
        self.period_s = 1.0 / rig.sample_rate_hz
        self.batch_s = batch_s
        # refuses, now, a filter without a streaming form
        self.lag_samples = streaming_estimator(name, rig).lag_samples
        self._stream: StreamingEstimator | None = None
        self._chosen: tuple[int, ...] | None = None  # the current segment's sensors
        self._seg_t: list[float] = []  # device times of the current segment's samples
        self._seg_first = 0  # the sample number (of the session) the segment starts at
        self._seg_done = 0  # of its samples, how many have an estimate (or never will)
        self._out: dict[int, HostEstimate | None] = {}  # estimates by sample number
        self._pending: list[Estimate] = []
        self._paired = 0  # board estimates handed back
        self._recent: deque[Estimate] = deque(maxlen=self.lag_samples + 1)
        self.latest: HostEstimate | None = None
        self.off: str | None = None  # why it was switched off
        self.note: str | None = None  # why there is no estimate right now
        self.samples = 0
        self.processed = 0  # samples that went through the estimator
        self.estimates = 0
        self.restarts = 0
        self.lost_track = 0
        self.cpu_s = 0.0
        self.window_cpu_per_sample_s = 0.0  # over the last LOAD_WINDOW_S
        self._load: deque[tuple[float, float, int]] = deque()  # (device t, cpu s, samples)
        self._offset_min: float | None = None
        self.backlog_s = 0.0
        self.backlog_max_s = 0.0
        self._t_first: float | None = None
        self._d_sq = 0.0
        self._d_max = 0.0
        self._d_n = 0

    @property
    def lag_ms(self) -> float:
        return self.lag_samples * self.period_s * 1000.0

    # -----------------------------------------------------------------------------------------
    def add(self, estimates: list[Estimate]) -> None:
        """Queue the board's new estimates (each carries its raw counts)."""
        self._pending.extend(estimates)

    def run(self, now: float | None = None) -> list[tuple[Estimate, HostEstimate | None]]:
        """Process what is queued: each board estimate with the host's estimate of the sample
        `lag_samples` before it (None while there is none)."""
        batch, self._pending = self._pending, []
        if not batch:
            return []
        if self.off is None and len(batch) > MAX_BACKLOG_S * self.rig.sample_rate_hz:
            self._switch_off(f"{len(batch) * self.period_s:.1f} s of samples waited for it")
        if self.off is None:
            t0 = self.cpu_clock()
            self._process(batch)
            spent = self.cpu_clock() - t0
            self._account(batch, spent, time.monotonic() if now is None else now)
        else:
            self.samples += len(batch)
        out = []
        for est in batch:
            h = self._out.pop(self._paired - self.lag_samples, None)
            self._recent.append(est)  # the last lag + 1: [0] is the sample h estimates
            if h is not None:
                self._compare(self._recent[0], h)
            out.append((est, h))
            self._paired += 1
        return out

    def finish(self) -> list[tuple[Estimate, HostEstimate | None]]:
        """The end of the stream: what is queued, processed (the newest `lag_samples`
        samples' estimates come after the last board estimate: they are counted, not paired)."""
        out = self.run()
        if self.off is None:
            self._close_segment()
        return out

    # -----------------------------------------------------------------------------------------
    def _usable(self, est: Estimate) -> tuple[int, ...]:
        return tuple(i for i, s in enumerate(est.sensor_status) if not s & FAULT_BITS)

    def _process(self, batch: list[Estimate]) -> None:
        """Push the batch in runs of one segment each."""
        start = 0
        prev = self._seg_t[-1] if self._seg_t else None
        for k, est in enumerate(batch):
            chosen = self._usable(est)
            stepped = prev is None or abs(est.device_s - prev - self.period_s) \
                < 0.5 * self.period_s
            if chosen != self._chosen or not stepped:
                self._push(batch[start:k])
                self._new_segment(chosen, self.samples)
                start = k
            prev = est.device_s
        self._push(batch[start:])

    def _new_segment(self, chosen: tuple[int, ...], first: int) -> None:
        if self._chosen is not None:
            self._close_segment()
            self.restarts += 1
        self._chosen = chosen
        self._seg_t, self._seg_first, self._seg_done = [], first, 0
        self._stream = None
        sub = rig_of_sensors(self.rig, chosen)
        if min(sub.sensor_count("a"), sub.sensor_count("b")) < 2:
            self.note = "fewer than two usable sensors on a link"
            return
        try:
            self._stream = streaming_estimator(self.name, sub)
            self.note = None
        except InputError as exc:
            self.note = exc.reason

    def _close_segment(self) -> None:
        """Hand out the segment's last estimates; its samples without one get None."""
        if self._stream is not None:
            with contextlib.suppress(InputError):  # lost track in its last samples
                self._emit(self._stream.finish())
        self._stream = None
        for i in range(self._seg_done, len(self._seg_t)):
            self._out[self._seg_first + i] = None
        self._seg_done = len(self._seg_t)

    def _push(self, run: list[Estimate]) -> None:
        if not run:
            return
        self._seg_t.extend(e.device_s for e in run)
        self.samples += len(run)
        if self._stream is None:
            self._close_segment()  # none of these get an estimate
            return
        self.processed += len(run)
        counts = np.stack([e.counts for e in run if e.counts is not None])
        readings = device_readings(self.maps, counts)
        cols = [c for i in self._chosen or () for c in (2 * i, 2 * i + 1)]
        try:
            self._emit(self._stream.push(readings[:, cols][None]))
        except InputError as exc:  # it lost track: start afresh from the next sample
            self.lost_track += 1
            self._stream = None
            self._new_segment(self._chosen or (), self.samples)
            self.note = f"lost track and restarted ({exc.reason.split(' (')[0]})"

    def _emit(self, e: Estimates) -> None:
        th, wa, wb = (np.degrees(a[0]) for a in (e.theta, e.omega_a, e.omega_b))
        t0 = self._seg_t[0] if self._seg_t else 0.0
        for i in range(th.shape[0]):
            t = self._seg_t[self._seg_done]
            h = HostEstimate(t, float(th[i]), float(wa[i]), float(wb[i]), t - t0)
            self._out[self._seg_first + self._seg_done] = h
            self._seg_done += 1
            self.latest = h
            self.estimates += 1

    def _account(self, batch: list[Estimate], spent: float, now: float) -> None:
        self.cpu_s += spent
        t_dev = batch[-1].device_s
        self._load.append((t_dev, spent, len(batch)))
        while self._load and self._load[0][0] < t_dev - LOAD_WINDOW_S:
            self._load.popleft()
        offset = now - t_dev
        if self._offset_min is None or offset < self._offset_min:
            self._offset_min = offset
        self.backlog_s = offset - self._offset_min
        self.backlog_max_s = max(self.backlog_max_s, self.backlog_s)
        n = sum(k for _, _, k in self._load)
        self.window_cpu_per_sample_s = sum(c for _, c, _ in self._load) / n if n else 0.0
        if self._t_first is None:
            self._t_first = t_dev
        if t_dev - self._t_first < WARMUP_S:
            return
        load = self.window_load
        if load > MAX_LOAD:
            self._switch_off(f"it needs {load:.0%} of the sample period "
                             f"({1e3 * self.window_cpu_per_sample_s:.2f} ms of CPU a sample at "
                             f"{self.rig.sample_rate_hz:g} Hz)")
        elif self.backlog_s > MAX_BACKLOG_S:
            self._switch_off(f"the stream fell {self.backlog_s:.1f} s behind")

    def _switch_off(self, why: str) -> None:
        self.off = (f"host filter {self.name} switched off: {why}; choose a lighter one "
                    "(--host-filter array-ekf), a lower rate, or --host-filter none")
        self._stream = None
        self._close_segment()

    # -----------------------------------------------------------------------------------------
    @property
    def window_load(self) -> float:
        return self.window_cpu_per_sample_s / self.period_s

    @property
    def cpu_per_sample_s(self) -> float:
        """CPU time per sample that went through the estimator."""
        return self.cpu_s / self.processed if self.processed else 0.0

    def _compare(self, board: Estimate, host: HostEstimate) -> None:
        """Count host − board θ on the same sample, from STEADY_AFTER_S into a segment."""
        if not board.running or host.segment_s < STEADY_AFTER_S:
            return
        d = (host.theta_deg - board.theta_deg + 180.0) % 360.0 - 180.0
        self._d_sq += d * d
        self._d_max = max(self._d_max, abs(d))
        self._d_n += 1

    def fields(self, host: HostEstimate | None) -> dict[str, Any]:
        """The host_* keys of a --json-lines object."""
        return {"host_filter": self.name, "host_lag_ms": round(self.lag_ms, 3),
                "host_device_t": None if host is None else round(host.device_t, 6),
                "host_theta_deg": None if host is None else _num(host.theta_deg),
                "host_omega_a_dps": None if host is None else _num(host.omega_a_dps),
                "host_omega_b_dps": None if host is None else _num(host.omega_b_dps)}

    def summary(self) -> dict[str, Any]:
        last = self.latest
        return {
            "name": self.name, "lag_ms": round(self.lag_ms, 3),
            "samples": self.samples, "estimates": self.estimates,
            "segments_restarted": self.restarts, "lost_track": self.lost_track,
            "cpu_per_sample_ms": round(1e3 * self.cpu_per_sample_s, 4),
            "cpu_load": round(self.cpu_per_sample_s / self.period_s, 4),
            "backlog_s": round(self.backlog_s, 3), "backlog_max_s": round(self.backlog_max_s, 3),
            "switched_off": self.off, "note": self.note,
            "theta_deg": None if last is None else _num(last.theta_deg),
            "host_minus_board_rms_deg": (round(math.sqrt(self._d_sq / self._d_n), 6)
                                         if self._d_n else None),
            "host_minus_board_max_abs_deg": round(self._d_max, 6) if self._d_n else None,
            "compared_samples": self._d_n,
        }


# ---------------------------------------------------------------------------------------------
# The --host-filter option of live and record

HOST_FILTER_HELP = (
    "run this host estimator on the board's raw readings as they arrive and {what}: "
    "{names}, or none. Default: {default} (lag 100 ms: each estimate uses the "
    "100 ms after its sample; array-ekf: causal, no lag), switched off with a warning if it "
    "cannot keep up (over {load:.0%} of the sample period in CPU, or the stream {backlog:g} s "
    "behind). Needs the rig (--rig, or a virtual board's own)")


def host_filter_help(what: str = "show it beside the board's θ") -> str:
    text = HOST_FILTER_HELP.format(what=what, names=", ".join(STREAMING),
                                   default=DEFAULT_HOST_FILTER,
                                   load=MAX_LOAD, backlog=MAX_BACKLOG_S)
    return text.replace("%", "%%")  # argparse formats help with %


def host_filter_name(text: str) -> str:
    """argparse type of --host-filter: a streamable estimator or none."""
    if text == "none" or text in STREAMING:
        return text
    why = ("needs the whole run or gyro rates, it cannot run as the samples arrive"
           if text in ESTIMATORS else "is not a filter")
    raise argparse.ArgumentTypeError(f"{text!r} {why}; choose one of {', '.join(STREAMING)} "
                                     "or none")


def choose_host_filter(name: str | None, rig: Rig | None) -> tuple[HostFilter | None, str]:
    """The host filter for --host-filter `name` (None: the default) on the board's `rig`
    (`device_rig`; None when there is none or it does not match the board), or None, and a
    word on it for the view. Asked for by name without a rig: InputError."""
    if name == "none":
        return None, "host filter off (--host-filter none)"
    if rig is None:
        if name is not None:
            raise InputError(f"{name} needs the rig of this build, matching the board (--rig; a "
                             "virtual board has its own)", field="--host-filter")
        return None, "host filter off: needs the rig (--rig)"
    host = HostFilter(DEFAULT_HOST_FILTER if name is None else name, rig)
    return host, f"host {host.name}, {host.lag_ms:g} ms behind"


def json_fields(host: HostFilter | None, est: HostEstimate | None) -> dict[str, Any]:
    """The host_* keys of a --json-lines object (all null without a host filter)."""
    if host is None:
        return {"host_filter": None, "host_lag_ms": None, "host_device_t": None,
                "host_theta_deg": None, "host_omega_a_dps": None, "host_omega_b_dps": None}
    return host.fields(est)
