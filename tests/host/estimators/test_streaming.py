"""Streaming estimators (live, record): pushed in any chunks, the batch run's numbers."""

from __future__ import annotations

import numpy as np
import pytest

from jointangle.errors import InputError
from jointangle.estimators.base import Estimates, sensor_to_link, wrap
from jointangle.estimators.registry import get_estimator
from jointangle.estimators.streaming import (
    STREAMING,
    StreamingEstimator,
    concat_estimates,
    streaming_estimator,
)
from jointangle.rig import Rig
from jointangle.sim.scenarios import simulate


def _data(name: str, seconds: float, rate: float = 100.0,
          seeds: tuple[int, ...] = (3, 4)) -> tuple[Rig, np.ndarray]:
    sims = [simulate(name, seed=s, rate_hz=rate, seconds=seconds) for s in seeds]
    rig = sims[0].rig
    return rig, np.stack([sensor_to_link(rig, s.readings) for s in sims])


def _streamed(stream: StreamingEstimator, acc: np.ndarray, sizes: list[int]) -> Estimates:
    """Push acc in chunks of the given sizes (cycled), checking that each push hands out
    exactly the samples whose lag has passed."""
    parts, begin, given, i = [], 0, 0, 0
    T = acc.shape[1]
    while begin < T:
        end = min(begin + sizes[i % len(sizes)], T)
        i += 1
        e = stream.push(acc[:, begin:end])
        given += e.theta.shape[1]
        if end > stream.lag_samples:
            assert given == end - stream.lag_samples, (given, end)
        else:
            assert given == 0
        parts.append(e)
        begin = end
    parts.append(stream.finish())
    return concat_estimates(parts, acc.shape[0])


@pytest.mark.parametrize("name", ["array-ekf", "array-fls", "analytical", "smooth"])
def test_streaming_in_chunks_equals_the_batch_run(name: str) -> None:
    rig, acc = _data("gravity-fast-periodic", 4.0)
    whole = get_estimator(name).estimate(rig, acc)
    for sizes in ([1], [0, 7, 1, 33], [130]):
        got = _streamed(streaming_estimator(name, rig), acc, sizes)
        assert got.theta.shape == whole.theta.shape
        np.testing.assert_allclose(wrap(got.theta - whole.theta), 0.0, rtol=0, atol=1e-9)
        for a, b in ((got.omega_a, whole.omega_a), (got.omega_b, whole.omega_b),
                     (got.theta_sigma, whole.theta_sigma)):
            if b is None:
                assert a is None
            else:
                assert a is not None
                np.testing.assert_allclose(a, b, rtol=0, atol=1e-9, equal_nan=True)


def test_fls_stream_shorter_than_its_lag_is_the_batch_run() -> None:
    rig, acc = _data("paper-table2-L20", 0.05)  # 5 samples < lag + 1 = 11
    whole = get_estimator("array-fls").estimate(rig, acc)
    got = _streamed(streaming_estimator("array-fls", rig), acc, [2])
    np.testing.assert_allclose(got.theta, whole.theta, rtol=0, atol=1e-9)


def test_lags_are_the_estimators_stated_latency() -> None:
    rig, _ = _data("paper-table2-L20", 0.05, rate=500.0, seeds=(0,))
    for name in STREAMING:
        lat = get_estimator(name).latency_s(rig)
        stream = streaming_estimator(name, rig)
        assert lat is not None
        assert stream.lag_samples == round(lat * 500.0), name
    assert streaming_estimator("array-fls", rig).lag_samples == 50


@pytest.mark.parametrize("name", ["ekf", "array-rts", "incl-kf", "nope"])
def test_filters_without_a_streaming_form_are_refused_by_name(name: str) -> None:
    rig, _ = _data("paper-table2-L20", 0.05, seeds=(0,))
    with pytest.raises(InputError) as exc:
        streaming_estimator(name, rig)
    assert name in str(exc.value) and "array-fls" in str(exc.value)
