"""Estimators that need more than link-frame accelerations (the neighbouring methods).

The `Estimator` protocol (base.py) takes link-frame x, y readings only. A method that also needs
gyro rates (the inclination Kalman filter of the two-accelerometer-plus-gyro paper) declares
`requires = ("gyro",)` and implements `estimate_with_gyro(rig, acc, gyro)`; its plain `estimate`
refuses with a clear message. `run_estimator` is what callers use: it passes the gyro when the
estimator wants it and the data have it, and otherwise says exactly what is missing.

A method that only works with gravity in the plane of motion (the inclination filter reads
each link's tilt from gravity) also declares "gravity_in_plane"; `check_domain` refuses data
recorded with gravity out of the plane (a horizontal mechanism, a vertical hinge), which the
rig file does not say but the sensors' z axes show (`check_inputs`, which commands call before
running; benchmarks that score such a method where it does not apply do not).

gyro: (S, T, n_sensors, 3) rad/s in each sensor's frame, NaN for sensors without a gyro (the
shape `AccelData.gyro` has, with a leading batch axis).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from jointangle.errors import InputError
from jointangle.estimators.base import Estimates, Estimator, calibrated
from jointangle.rig import Rig
from jointangle.sensors import STANDARD_GRAVITY

# Refuse a "gravity_in_plane" method when gravity is more than this far out of the plane of
# motion: less than half of g is left in the plane (the hinge axis within 30° of vertical).
MAX_GRAVITY_OUT_OF_PLANE_DEG = 60.0


@runtime_checkable
class GyroEstimator(Protocol):
    name: str
    description: str
    requires: tuple[str, ...]

    def latency_s(self, rig: Rig) -> float | None: ...

    def estimate(self, rig: Rig, acc: np.ndarray) -> Estimates: ...

    def estimate_with_gyro(self, rig: Rig, acc: np.ndarray, gyro: np.ndarray) -> Estimates: ...


def requires_gyro(est: object) -> bool:
    return "gyro" in getattr(est, "requires", ())


def link_gyro_rate(rig: Rig, gyro: np.ndarray, link: str) -> np.ndarray:
    """z rate (S, T) of one link: the mean over that link's sensors that have a gyro.

    The mounting rotation is about z, so every gyro on a link reads the link's ω on its z axis.
    Raises InputError when the link has no gyro column.
    """
    idx = [k for k, (ln, _, _) in enumerate(rig.all_sensors()) if ln == link]
    z = gyro[..., idx, 2]
    have = np.isfinite(z).all(axis=-2)  # (S, n_link) a sensor's column present throughout
    if not have.any(axis=-1).all():
        raise InputError(f"link {link} has no gyro: this method needs one gyro per link "
                         "(a BNO055 on each link, CSV columns like "
                         f"{link}.0.gx,{link}.0.gy,{link}.0.gz)", field="gyro")
    w = np.where(have[..., None, :], np.nan_to_num(z), 0.0)
    return w.sum(-1) / have.sum(-1)[..., None]


def gravity_out_of_plane_deg(rig: Rig, readings: np.ndarray) -> float:
    """How far gravity lies out of the plane of motion, in degrees (0: the hinge axis is
    horizontal, 90: vertical), from raw sensor readings (T, n_sensors, 3) m/s².

    Motion in the plane accelerates nothing along the hinge axis, which is every sensor's z
    (the mounting rotation is about z), so a calibrated z axis reads only gravity's
    out-of-plane part: the median of |a_z| over time and sensors is g·sin(angle).
    """
    z = [calibrated(s, readings[..., k, :])[..., 2]
         for k, (_, _, s) in enumerate(rig.all_sensors())]
    ratio = float(np.median(np.abs(np.stack(z)))) / STANDARD_GRAVITY
    return float(np.degrees(np.arcsin(min(ratio, 1.0))))


def _refuse_without_gyro(est: Estimator, gyro: np.ndarray | None) -> None:
    if requires_gyro(est) and (gyro is None or not np.isfinite(gyro).any()):
        raise InputError(f"filter {est.name!r} needs gyro rates: the input has no gyro "
                         "columns (a.0.gx,a.0.gy,a.0.gz,… from a BNO055 on each link)",
                         field="--filter")


def check_inputs(est: Estimator, rig: Rig, readings: np.ndarray,
                 gyro: np.ndarray | None) -> None:
    """Refuse (InputError), before running, data a method cannot use: a gyro method without
    gyro rates, a "gravity_in_plane" method on raw readings (T, n_sensors, 3) taken with
    gravity mostly out of the plane of motion."""
    _refuse_without_gyro(est, gyro)
    if "gravity_in_plane" not in getattr(est, "requires", ()):
        return
    angle = gravity_out_of_plane_deg(rig, readings)
    if angle > MAX_GRAVITY_OUT_OF_PLANE_DEG:
        g_z = STANDARD_GRAVITY * np.sin(np.radians(angle))
        raise InputError(f"filter {est.name!r} needs gravity in the plane of motion (the hinge "
                         "axis horizontal): it reads each link's tilt from gravity, but here "
                         f"gravity is {angle:.0f}° out of the plane (the sensors' z axes, along "
                         f"the hinge, read {g_z:.2f} m/s²: a horizontal mechanism or a vertical "
                         "hinge); use an accelerometer-only filter such as array-ekf",
                         field="--filter")


def not_applicable(est: Estimator, rig: Rig, readings: np.ndarray,
                   gyro: np.ndarray | None) -> str | None:
    """Why `est` does not apply to these data — what it declares it needs (`requires`: gyro
    rates, gravity in the plane of motion) checked against the data themselves (`check_inputs`
    on raw readings (T, n_sensors, 3) and gyro (T, n_sensors, 3) or None) — or None."""
    try:
        check_inputs(est, rig, readings, gyro)
    except InputError as exc:
        return exc.reason
    return None


def run_estimator(est: Estimator, rig: Rig, acc: np.ndarray,
                  gyro: np.ndarray | None = None) -> Estimates:
    """Run any estimator on link-frame readings acc (S, T, M), passing gyro rates if it needs
    them. A gyro method without gyro data raises InputError naming what is missing."""
    if requires_gyro(est):
        _refuse_without_gyro(est, gyro)
        assert gyro is not None and isinstance(est, GyroEstimator)
        return est.estimate_with_gyro(rig, acc, gyro)
    return est.estimate(rig, acc)
