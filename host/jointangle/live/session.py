"""The numbers behind the live readout, computed from the frames as they arrive.

`LiveState.feed(frames)` keeps: the latest estimate (θ, ω_a, ω_b, health), a moving trace of θ,
the sample rate (device clock, last second), per-sensor health from sample and status frames,
the firmware-vs-`mirror` divergence of the current filter run and an observability flag
(docs/design.md §6: with gravity out of the plane and too little motion, the angle is a guess).

The divergence runs `mirror` over the current filter run (from its `reset` frame) on the
firmware's own readings (`jointangle.device`), going on from where the last refresh stopped
(`MirrorState`: each refresh costs the frames that arrived since, not the whole run):
`DivergenceWorker` does it on a thread, at most `duty` of the time, and the view says how old
the figure is.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from jointangle.device.calibration_map import DeviceMaps, device_readings
from jointangle.device.describe import flag_names, sustainable_rate_hz
from jointangle.device.rig import FAULT_BITS, filter_choice, filter_runs, sub_rig
from jointangle.device.verify import OMEGA_LSB, THETA_LSB, mirror_theta, starts_stream
from jointangle.estimators.base import wrap
from jointangle.estimators.mirror import MirrorState, step_periods
from jointangle.observability import observable
from jointangle.protocol import messages as msgs
from jointangle.protocol.codec import decode_message
from jointangle.protocol.framing import COUNT_KEYS, Frame
from jointangle.rig import Rig

if TYPE_CHECKING:
    from jointangle.estimators.mirror import MirrorState

TRACE_S = 10.0  # seconds of θ kept for the moving trace
MAX_RUN_S = 600.0  # divergence is tracked over at most this much of a filter run


@dataclass
class Estimate:
    t_s: float  # device clock, seconds since the first frame of the session
    seq: int
    theta_deg: float
    omega_a_dps: float
    omega_b_dps: float
    health: int
    sensor_status: tuple[int, ...]
    device_s: float = 0.0  # the device's own clock (t_us unwrapped), seconds
    # the raw counts (n, 3) the step read, for a host filter (`live.host_filter`)
    counts: np.ndarray | None = field(default=None, repr=False, compare=False)

    @property
    def running(self) -> bool:
        """The board's filter ran this step; else θ and ω in the frame mean nothing."""
        return bool(self.health & msgs.FilterHealth.RUNNING)

    def as_dict(self) -> dict[str, Any]:
        run = self.running  # null, not a 0 that reads as an angle, while the filter is stopped
        return {"t": round(self.t_s, 6), "device_t": round(self.device_s, 6), "seq": self.seq,
                "theta_deg": self.theta_deg if run else None,
                "omega_a_dps": self.omega_a_dps if run else None,
                "omega_b_dps": self.omega_b_dps if run else None,
                "health": flag_names(msgs.FilterHealth, self.health),
                "sensors": [flag_names(msgs.SensorStatus, s) for s in self.sensor_status]}


@dataclass
class Divergence:
    max_abs_deg: float
    rms_deg: float
    frames: int  # of the run, compared
    run: int  # which filter run (1 = first seen)
    at: float  # time.monotonic() when computed


@dataclass
class FilterRun:
    """Counts and firmware θ of the current filter run, for `mirror`."""

    number: int
    chosen: tuple[int, ...]
    counts: list[np.ndarray] = field(default_factory=list)
    theta_q24: list[int] = field(default_factory=list)
    t_us: list[int] = field(default_factory=list)  # frame times: the steps' periods
    broken: str | None = None  # why mirror can no longer follow (frames lost, ...)


class DivergenceWorker:
    """Computes the divergence of a filter run on a thread, throttled to `duty`."""

    def __init__(self, rig: Rig, duty: float = 0.25) -> None:
        self.rig = rig
        self.maps = DeviceMaps.from_rig(rig)
        self.duty = duty
        self.result: Divergence | None = None
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._next_at = 0.0
        # Where the last compute left the run: its number, the mirror's state, frames done, and
        # max |Δθ| and Σ Δθ² over them.
        self._run_number = -1
        self._state: MirrorState | None = None
        self._done = 0
        self._max_abs = 0.0
        self._sum_sq = 0.0

    def compute(self, run: FilterRun, n: int) -> Divergence:
        """The divergence over frames 0..n-1 of `run`: the frames not seen by the last call on
        this run, from the mirror state it left (the same figures as one pass over all n)."""
        if run.number != self._run_number or self._state is None or n < self._done:
            self._run_number, self._state = run.number, MirrorState.fresh(1)
            self._done, self._max_abs, self._sum_sq = 0, 0.0, 0.0
        if n > self._done:
            counts = np.stack(run.counts[self._done:n])
            # The steps' periods from the frame times, the chunk's first from the frame before.
            first = max(self._done - 1, 0)
            periods = step_periods(np.asarray(run.t_us[first:n]), self.rig.sample_rate_hz)
            host = mirror_theta(self.rig, self.maps, counts, run.chosen, self._state,
                                periods[self._done - first:])
            fw = np.asarray(run.theta_q24[self._done:n], dtype=float) * THETA_LSB
            d = np.degrees(wrap(fw - host))
            self._max_abs = max(self._max_abs, float(np.max(np.abs(d))))
            self._sum_sq += float(np.sum(d**2))
            self._done = n
        return Divergence(self._max_abs, float(np.sqrt(self._sum_sq / n)), n, run.number,
                          time.monotonic())

    def maybe_start(self, run: FilterRun) -> None:
        if self._thread is not None and self._thread.is_alive():
            return
        if (time.monotonic() < self._next_at or not filter_runs(self.rig, run.chosen)
                or not run.counts):
            return
        n = len(run.counts)

        def work() -> None:
            t0 = time.monotonic()
            res = self.compute(run, n)
            with self._lock:
                self.result = res
            spent = time.monotonic() - t0
            self._next_at = time.monotonic() + spent * (1.0 - self.duty) / self.duty

        self._thread = threading.Thread(target=work, name="mirror-divergence", daemon=True)
        self._thread.start()

    def wait(self, timeout: float = 30.0) -> None:
        if self._thread is not None:
            self._thread.join(timeout)


@dataclass
class SensorHealth:
    status: int = 0
    nacks: int = 0
    id_errors: int = 0
    saturations: int = 0
    freezes: int = 0


class LiveState:
    def __init__(self, hello: msgs.Hello, rig: Rig | None = None, *,
                 divergence: bool = True) -> None:
        self.hello = hello
        self.rig = rig
        n = len(hello.sensors)
        self.rate_hz = float(hello.sample_rate_hz or 100)
        self.latest: Estimate | None = None
        self.trace: deque[tuple[float, float]] = deque(maxlen=int(TRACE_S * self.rate_hz) + 1)
        self.sensors = [SensorHealth() for _ in range(n)]
        self.status: msgs.Status | None = None
        self.status_device_s: float | None = None  # device time of the last status frame
        self.last_log: str | None = None
        self.samples = 0
        self.frames = 0
        self._t0_us: int | None = None
        self._t_prev: int | None = None
        self._t_wraps = 0
        self._last_seq: int | None = None
        self._lost_since_sample = 0
        self._arrivals: deque[float] = deque()
        self.run: FilterRun | None = None
        self.runs = 0
        self.worker = DivergenceWorker(rig) if rig is not None and divergence else None
        self._window: deque[np.ndarray] = deque(
            maxlen=max(1, round(0.25 * self.rate_hz)))  # counts for observability
        self.observable: bool | None = None

    # ---------------------------------------------------------------------------------
    def _t_s(self, t_us: int) -> tuple[float, float]:
        """(seconds since the session's first frame, the device clock unwrapped)."""
        if self._t_prev is not None and t_us < self._t_prev - (1 << 31):
            self._t_wraps += 1
        self._t_prev = t_us
        t = t_us + (self._t_wraps << 32)
        if self._t0_us is None:
            self._t0_us = t
        return (t - self._t0_us) / 1e6, t / 1e6

    def feed(self, frames: list[Frame]) -> list[Estimate]:
        """Take new frames; returns the estimates among them."""
        out: list[Estimate] = []
        for fr in frames:
            self.frames += 1
            gap = 0 if self._last_seq is None else (fr.seq - self._last_seq - 1) & 0xFFFF
            self._last_seq = fr.seq
            # The frames lost since the last sample frame, also those before a status or a log
            # frame: the filter run stepped unseen (the link keeps the acks of its own commands,
            # which leaves gaps too).
            self._lost_since_sample += gap
            try:
                msg = decode_message(fr)
            except ValueError:
                continue
            if isinstance(msg, msgs.SampleEstimate):
                out.append(self._estimate(fr, msg, self._lost_since_sample))
                self._lost_since_sample = 0
            elif isinstance(msg, msgs.Ack) and starts_stream(msg.command_id, msg.error):
                # Unseen steps without a gap (device.verify: unseen_before).
                self._break("the stream started again")
            elif isinstance(msg, msgs.LeanEstimate):
                out.append(self._lean_estimate(fr, msg))
            elif isinstance(msg, msgs.Status):
                self.status = msg
                self.status_device_s = self._t_s(fr.t_us)[1]
                for h, s in zip(self.sensors, msg.sensors, strict=False):
                    h.status, h.nacks, h.id_errors = s.status, s.nacks, s.id_errors
                    h.saturations, h.freezes = s.saturations, s.freezes
            elif isinstance(msg, msgs.Log):
                self.last_log = f"{flag_or_level(msg.level)}: {msg.text}"
            elif isinstance(msg, msgs.Hello) and gap:
                self._break("the device restarted")
        return out

    def _estimate(self, fr: Frame, msg: msgs.SampleEstimate, gap: int) -> Estimate:
        t, device_s = self._t_s(fr.t_us)
        status = tuple(s.status for s in msg.sensors)
        est = Estimate(t, fr.seq, float(np.degrees(msg.theta * THETA_LSB)),
                       float(np.degrees(msg.omega_a * OMEGA_LSB)),
                       float(np.degrees(msg.omega_b * OMEGA_LSB)), msg.health, status, device_s)
        self.latest = est
        self.samples += 1
        if est.running:  # a stopped filter's zeros would flatten the trace's scale
            self.trace.append((t, est.theta_deg))
        self._arrivals.append(t)
        while self._arrivals and self._arrivals[0] < t - 1.0:
            self._arrivals.popleft()
        for h, s in zip(self.sensors, status, strict=False):
            h.status = (h.status & ~0x3F) | s  # sample frames carry the current bits
        counts = np.array([[s.x, s.y, s.z] for s in msg.sensors], dtype=np.int64)
        est.counts = counts
        self._window.append(counts)
        self._track_run(msg, counts, gap, fr.t_us)
        return est

    def _lean_estimate(self, fr: Frame, msg: msgs.LeanEstimate) -> Estimate:
        """A lean_estimate frame (--stream estimates): the estimate and which sensors are at
        fault (their bits come with the status frames, sent on every change); no readings, so
        nothing for the mirror or a host filter."""
        t, device_s = self._t_s(fr.t_us)
        for i, h in enumerate(self.sensors):
            if not (msg.faulty >> i) & 1:
                h.status &= ~FAULT_BITS  # cleared since the last status frame
        status = tuple(h.status for h in self.sensors)
        est = Estimate(t, fr.seq, float(np.degrees(msg.theta * THETA_LSB)),
                       float(np.degrees(msg.omega_a * OMEGA_LSB)),
                       float(np.degrees(msg.omega_b * OMEGA_LSB)), msg.health, status, device_s)
        self.latest = est
        self.samples += 1
        if est.running:
            self.trace.append((t, est.theta_deg))
        self._arrivals.append(t)
        while self._arrivals and self._arrivals[0] < t - 1.0:
            self._arrivals.popleft()
        return est

    def _break(self, why: str) -> None:
        if self.run is not None and self.run.broken is None:
            self.run.broken = why

    def _track_run(self, msg: msgs.SampleEstimate, counts: np.ndarray, gap: int,
                   t_us: int) -> None:
        if self.rig is None or len(msg.sensors) != len(self.hello.sensors):
            return
        running = msg.health & msgs.FilterHealth.RUNNING
        if running and msg.health & msgs.FilterHealth.RESET:
            self.runs += 1
            self.run = FilterRun(self.runs, filter_choice(self.rig, [s.status for s in
                                                                     msg.sensors]))
        elif self.run is None or self.run.broken is not None:
            return
        elif gap:
            self._break(f"{gap} frames lost")
            return
        elif not running:
            self._break("the filter stopped")
            return
        elif filter_choice(self.rig, [s.status for s in msg.sensors]) != self.run.chosen:
            self._break("sensor choice changed")
            return
        if len(self.run.counts) >= MAX_RUN_S * self.rate_hz:
            self._break(f"run longer than {MAX_RUN_S:.0f} s")
            return
        self.run.counts.append(counts)
        self.run.theta_q24.append(msg.theta)
        self.run.t_us.append(t_us)

    # ---------------------------------------------------------------------------------
    @property
    def status_age_s(self) -> float | None:
        """Device seconds since the last status frame (None before one or before estimates).
        On a saturated link the board's status frames can be dropped like any other frame,
        so its counters (uart_drops, ...) may be old: the view says so."""
        if self.status_device_s is None or self.latest is None:
            return None
        return max(0.0, self.latest.device_s - self.status_device_s)

    @property
    def sample_rate(self) -> float:
        a = self._arrivals
        if len(a) < 2 or a[-1] <= a[0]:
            return 0.0
        return (len(a) - 1) / (a[-1] - a[0])

    def refresh(self) -> None:
        """Slow work, once per screen refresh: divergence thread, observability."""
        if self.worker is not None and self.run is not None and self.run.broken is None:
            self.worker.maybe_start(self.run)
        self.observable = self._observable()
        if self.latest is not None and self.latest.health & msgs.FilterHealth.UNOBSERVABLE:
            self.observable = False  # the device says so itself

    def _observable(self) -> bool | None:
        if self.rig is None or not self._window or self.run is None:
            return None

        chosen = self.run.chosen
        if not filter_runs(self.rig, chosen):
            return None
        worker_maps = self.worker.maps if self.worker else DeviceMaps.from_rig(self.rig)
        acc = device_readings(worker_maps, np.stack(list(self._window)))
        cols = [c for i in chosen for c in (2 * i, 2 * i + 1)]
        W = len(self._window)
        ok = observable(sub_rig(self.rig, chosen), acc[:, cols][None],
                        window_s=W / self.rate_hz)
        return bool(ok[0, -1])

    @property
    def divergence(self) -> Divergence | None:
        return None if self.worker is None else self.worker.result

    def summary(self, link_stats: dict[str, int]) -> dict[str, Any]:
        d = self.divergence
        st = self.status
        lost = link_stats.get("frames_lost", 0)
        frames = link_stats.get("frames", self.frames)
        return {
            "samples": self.samples, "frames": frames, "frames_lost": lost,
            "frame_loss": lost / (frames + lost) if frames + lost else 0.0,
            "crc_errors": link_stats.get("crc_errors", 0),
            **{k: link_stats.get(k, 0) for k in COUNT_KEYS if k not in ("frames", "frames_lost")},
            "sample_rate_hz": round(self.sample_rate, 2),
            "theta_deg": (None if self.latest is None or not self.latest.running
                          else self.latest.theta_deg),
            "max_abs_dtheta_deg": None if d is None else d.max_abs_deg,
            "rms_dtheta_deg": None if d is None else d.rms_deg,
            "dtheta_frames": 0 if d is None else d.frames,
            "filter_runs": self.runs,
            "observable": self.observable,
            "uart_drops": None if st is None else st.uart_drops,
            "loop_overruns": None if st is None else st.loop_overruns,
            "board_loop_rate_hz": None if st is None else st.loop_rate_hz,
            "board_idle_fraction": None if st is None else st.idle_permille / 1000.0,
            "board_sustainable_rate_hz": None if st is None else sustainable_rate_hz(st),
            "status_age_s": None if self.status_age_s is None else round(self.status_age_s, 3),
            "sensors": [flag_names(msgs.SensorStatus, h.status) for h in self.sensors],
            "sensor_counters": [{"nacks": h.nacks, "id_errors": h.id_errors,
                                 "saturations": h.saturations, "freezes": h.freezes}
                                for h in self.sensors],
        }


def flag_or_level(level: int) -> str:
    try:
        return str(msgs.LogLevel(level).name).lower()
    except ValueError:
        return f"level {level}"
