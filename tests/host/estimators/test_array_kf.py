"""Our array filters: chunked smoothing is exact, start-up hypotheses, consistency."""

from __future__ import annotations

import numpy as np

from jointangle.bench.accuracy import simulate_seeds
from jointangle.estimators.array_kf import ArrayEKF, ArrayFLS, ArrayRTS
from jointangle.estimators.base import wrap


def test_chunked_fixed_lag_equals_one_pass() -> None:
    sims, acc = simulate_seeds("gravity-impulse", (4, 5))
    rig = sims[0].rig
    acc = acc[:, :700]
    whole = ArrayFLS(chunk=10_000).estimate(rig, acc)
    for chunk in (1, 37, 256):
        part = ArrayFLS(chunk=chunk).estimate(rig, acc)
        np.testing.assert_allclose(part.theta, whole.theta, rtol=0, atol=1e-12)
        np.testing.assert_allclose(part.omega_a, whole.omega_a, rtol=0, atol=1e-12)
        assert part.theta_sigma is not None and whole.theta_sigma is not None
        np.testing.assert_allclose(part.theta_sigma, whole.theta_sigma, rtol=0, atol=1e-12)


def test_filters_are_consistent_and_smoothers_better() -> None:
    """The filter's own σ matches its error (the model is honest about its uncertainty), and
    each smoother beats the filter it smooths."""
    sims, acc = simulate_seeds("paper-table2-L20", (0, 1, 2, 3))
    rig = sims[0].rig
    truth = np.stack([s.theta for s in sims])
    steady = sims[0].t >= 5.0
    rms = {}
    for est in (ArrayEKF(), ArrayFLS(), ArrayRTS()):
        e = est.estimate(rig, acc)
        err = wrap(e.theta - truth)[:, steady]
        rms[est.name] = float(np.sqrt(np.mean(err**2)))
        if est.name == "array-ekf":
            assert e.theta_sigma is not None
            sigma = float(np.sqrt(np.mean(e.theta_sigma[:, steady] ** 2)))
            assert 0.8 < rms[est.name] / sigma < 1.25
    assert rms["array-rts"] < rms["array-fls"] < rms["array-ekf"]
