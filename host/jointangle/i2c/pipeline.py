"""The whole pipeline on the host: read every sensor over I2C, calibrate, run the float EKF.

Per step (`I2cPipeline.step`), each stage timed separately (`StageTimes`):
1. bus — one combined transaction per sensor (plus a verified mux select when the channel
   changes): `devices.Sensor.read`. A NACK or a mux read-back mismatch sets that sensor's
   status bit (protocol SensorStatus: nack / wrong_id), keeps the error message, and the step
   goes on with the others; a faulted sensor is re-probed (configured again) every
   `probe_interval_s`, one at a time, as the firmware does.
2. conversion and calibration — counts × the firmware's m/s² per count, then per sensor
   â = S v + o and the mounting rotation (estimators.base.sensor_to_link), folded into one
   2×3 map and offset per sensor: a_link = R₂(rot)·S·v + R₂(rot)·o.
3. filter — one step of the paper's EKF (`ekf`, estimators/paper.py) on the float inputs,
   over the first two to four usable sensors of each link (device.rig.filter_choice, as the
   firmware); a change of that choice restarts the filter (x₀ = 0, P₀ = I).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from jointangle.device.calibration_map import mps2_per_count
from jointangle.device.rig import FAULT_BITS, filter_choice, filter_runs, sub_rig
from jointangle.estimators.base import mT, wrap
from jointangle.estimators.paper import PaperModel
from jointangle.i2c.devices import I2cDeviceError, Part, Sensor, SMBusLike, Tca9548a
from jointangle.protocol import messages as msgs
from jointangle.rig import Rig


class StreamingEKF:
    """The `ekf` of estimators/paper.py one sample at a time (same equations, same order)."""

    def __init__(self, rig: Rig) -> None:
        self.pm = PaperModel.from_rig(rig)
        self.Phi = self.pm.Phi
        self.Q = self.pm.Q()
        self.x = np.zeros((1, 3))
        self.P = np.eye(3)[None].copy()

    def step(self, acc: np.ndarray) -> np.ndarray:
        """acc (M,) link-frame readings → x = [ω_a, ω_b, θ_ab]."""
        pm, a = self.pm, acc[None]
        z = pm.measurement(a)
        x_pred = pm.predict(self.x, a)
        P_pred = self.Phi @ self.P @ self.Phi.T + self.Q
        H = pm.H(x_pred, a)
        Sk = H @ P_pred @ mT(H) + pm.R(x_pred)
        K = mT(np.linalg.solve(Sk, mT(P_pred @ mT(H))))
        self.x = x_pred + np.einsum("sij,sj->si", K, z - pm.h(x_pred, a))
        self.P = (np.eye(3) - K @ H) @ P_pred
        return np.asarray(self.x[0])


def calibration_maps(rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """Per sensor (rig order) the 2×3 map R₂(rot)·S·scale from counts and the offset R₂(rot)·o:
    link-frame x, y = M counts + b (sensor_to_link with the counts' scale folded in)."""
    ms, bs = [], []
    for _, _, s in rig.all_sensors():
        c, si = math.cos(math.radians(s.rotation_deg)), math.sin(math.radians(s.rotation_deg))
        r2 = np.array([[c, -si, 0.0], [si, c, 0.0]])
        S = np.eye(3) if s.S is None else np.asarray(s.S, dtype=float)
        o = np.zeros(3) if s.offset is None else np.asarray(s.offset, dtype=float)
        ms.append(r2 @ S * float(mps2_per_count(s.model, s.range_g)))
        bs.append(r2 @ o)
    return np.asarray(ms), np.asarray(bs)


@dataclass
class StageTimes:
    """Wall time spent per stage, summed over `steps` steps (seconds)."""

    bus: float = 0.0
    convert: float = 0.0
    filter: float = 0.0
    steps: int = 0

    def per_step_us(self) -> dict[str, float]:
        n = max(self.steps, 1)
        return {"bus": self.bus / n * 1e6, "convert": self.convert / n * 1e6,
                "filter": self.filter / n * 1e6}


@dataclass(frozen=True)
class Step:
    t_s: float
    theta_deg: float | None  # None: no filter running (too few usable sensors)
    omega_a_dps: float | None
    omega_b_dps: float | None
    status: tuple[int, ...]
    fresh: tuple[bool, ...]

    def as_dict(self) -> dict[str, object]:
        return {"t": self.t_s, "theta_deg": self.theta_deg, "omega_a_dps": self.omega_a_dps,
                "omega_b_dps": self.omega_b_dps, "status": list(self.status),
                "fresh": list(self.fresh)}


@dataclass
class I2cPipeline:
    bus: SMBusLike
    rig: Rig
    probe_interval_s: float = 0.25
    times: StageTimes = field(default_factory=StageTimes)
    errors: list[str] = field(default_factory=list)  # every fault, as it happened (bounded)

    def __post_init__(self) -> None:
        sensors = self.rig.all_sensors()
        parts = [Part(s.model, s.address, s.mux_channel, s.range_g, f"{ln}.{i}")
                 for ln, i, s in sensors]
        self.mux = (Tca9548a(self.bus) if any(p.mux_channel != 255 for p in parts) else None)
        self.sensors = [Sensor(self.bus, self.mux, p) for p in parts]
        n = len(parts)
        self.status = [0] * n
        self.nacks = [0] * n
        self.counts = np.zeros((n, 3))
        self.maps, self.offsets = calibration_maps(self.rig)
        self._chosen: tuple[int, ...] | None = None
        self._ekf: StreamingEKF | None = None
        self._last_probe = 0.0
        self._probe_cursor = 0
        self._t0 = time.perf_counter()
        self.filter_resets = 0

    def _fault(self, k: int, exc: I2cDeviceError) -> None:
        if exc.status & msgs.SensorStatus.NACK:
            self.nacks[k] += 1
        if not self.status[k] & exc.status:
            self.errors.append(str(exc))
            del self.errors[:-50]
        self.status[k] |= exc.status

    def configure(self) -> None:
        """Configure every sensor (at the rig's rate); failures only set status bits."""
        for k, s in enumerate(self.sensors):
            self._probe(k, s)

    def _probe(self, k: int, s: Sensor) -> None:
        try:
            s.configure(self.rig.sample_rate_hz)
        except I2cDeviceError as exc:
            self._fault(k, exc)
            return
        self.status[k] &= ~int(FAULT_BITS)

    def _probe_due(self, now: float) -> None:
        if now - self._last_probe < self.probe_interval_s:
            return
        self._last_probe = now
        n = len(self.sensors)
        for j in range(n):
            k = (self._probe_cursor + j) % n
            if self.status[k] & FAULT_BITS:
                self._probe(k, self.sensors[k])
                self._probe_cursor = (k + 1) % n
                return

    def step(self) -> Step:
        t0 = time.perf_counter()
        self._probe_due(t0)
        fresh = []
        for k, s in enumerate(self.sensors):
            if self.status[k] & FAULT_BITS:
                fresh.append(False)
                continue
            try:
                c, f = s.read()
            except I2cDeviceError as exc:
                self._fault(k, exc)
                fresh.append(False)
                continue
            self.counts[k] = c
            fresh.append(f)
        t1 = time.perf_counter()
        # Calibration: link-frame (x, y) = M_k counts_k + b_k per sensor, links a then b.
        acc_all = (np.einsum("nij,nj->ni", self.maps, self.counts) + self.offsets)
        chosen = filter_choice(self.rig, self.status)
        t2 = time.perf_counter()
        if chosen != self._chosen:
            self._chosen = chosen
            sub = sub_rig(self.rig, chosen) if filter_runs(self.rig, chosen) else None
            self._ekf = StreamingEKF(sub) if sub is not None else None
            self.filter_resets += 1
        theta = wa = wb = None
        if self._ekf is not None:
            x = self._ekf.step(acc_all[list(chosen)].reshape(-1))
            theta = float(np.degrees(wrap(x[2])))
            wa, wb = float(np.degrees(x[0])), float(np.degrees(x[1]))
        t3 = time.perf_counter()
        tm = self.times
        tm.bus += t1 - t0
        tm.convert += t2 - t1
        tm.filter += t3 - t2
        tm.steps += 1
        return Step(t0 - self._t0, theta, wa, wb, tuple(self.status), tuple(fresh))
