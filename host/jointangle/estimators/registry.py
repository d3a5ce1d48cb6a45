"""The table of estimators by name (the `--filter` choices)."""

from __future__ import annotations

from collections.abc import Callable

from jointangle.errors import InputError
from jointangle.estimators.analytical import Analytical, SmoothAnalytical
from jointangle.estimators.array_kf import ArrayEKF, ArrayFLS, ArrayRTS
from jointangle.estimators.base import Estimator
from jointangle.estimators.mirror import Firmware, Mirror
from jointangle.estimators.neighbours.constrained import ArrayEKFROM
from jointangle.estimators.neighbours.inclination import InclinationKF
from jointangle.estimators.neighbours.madgwick import MadgwickArray
from jointangle.estimators.paper import PaperEKF, PaperEKFDecorrelated, PaperUKF

ESTIMATORS: dict[str, Callable[[], Estimator]] = {
    "analytical": Analytical,
    "smooth": SmoothAnalytical,
    "ekf": PaperEKF,
    "ekf-decorrelated": PaperEKFDecorrelated,
    "ukf": PaperUKF,
    "mirror": Mirror,
    "firmware": Firmware,
    "array-ekf": ArrayEKF,
    "array-fls": ArrayFLS,
    "array-rts": ArrayRTS,
    "array-ekf-rom": ArrayEKFROM,
    "madgwick-array": MadgwickArray,
    "incl-kf": InclinationKF,
}


def get_estimator(name: str) -> Estimator:
    try:
        factory = ESTIMATORS[name]
    except KeyError:
        raise InputError(f"unknown filter {name!r}; choose one of {', '.join(ESTIMATORS)}",
                         field="--filter") from None
    return factory()
