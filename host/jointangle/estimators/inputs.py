"""Estimators that need more than link-frame accelerations (the neighbouring methods).

The `Estimator` protocol (base.py) takes link-frame x, y readings only. A method that also needs
gyro rates (the inclination Kalman filter of the two-accelerometer-plus-gyro paper) declares
`requires = ("gyro",)` and implements `estimate_with_gyro(rig, acc, gyro)`; its plain `estimate`
refuses with a clear message. `run_estimator` is what callers use: it passes the gyro when the
estimator wants it and the data have it, and otherwise says exactly what is missing.

gyro: (S, T, n_sensors, 3) rad/s in each sensor's frame, NaN for sensors without a gyro (the
shape `AccelData.gyro` has, with a leading batch axis).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable

import numpy as np

from jointangle.errors import InputError
from jointangle.estimators.base import Estimates, Estimator
from jointangle.rig import Rig


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


def run_estimator(est: Estimator, rig: Rig, acc: np.ndarray,
                  gyro: np.ndarray | None = None) -> Estimates:
    """Run any estimator on link-frame readings acc (S, T, M), passing gyro rates if it needs
    them. A gyro method without gyro data raises InputError naming what is missing."""
    if requires_gyro(est):
        if gyro is None or not np.isfinite(gyro).any():
            raise InputError(f"filter {est.name!r} needs gyro rates: the input has no gyro "
                             "columns (a.0.gx,a.0.gy,a.0.gz,… from a BNO055 on each link)",
                             field="--filter")
        assert isinstance(est, GyroEstimator)
        return est.estimate_with_gyro(rig, acc, gyro)
    return est.estimate(rig, acc)
