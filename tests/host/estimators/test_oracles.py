"""Oracle tests: the pinned filters against filterpy, and every Jacobian against finite
differences."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter, MerweScaledSigmaPoints
from filterpy.kalman import unscented_transform as fp_unscented_transform

from jointangle.bench.accuracy import simulate_seeds
from jointangle.estimators.array_kf import N_STATE, ArrayModel
from jointangle.estimators.paper import (
    PaperEKF,
    PaperModel,
    sigma_points,
    ukf_weights,
    unscented_transform,
)


@pytest.fixture(scope="module")
def run() -> tuple[object, np.ndarray]:
    sims, acc = simulate_seeds("paper-table2-L20", (7,))
    return sims[0].rig, acc[:, :600]


def _random_spd(rng: np.random.Generator, n: int) -> np.ndarray:
    A = rng.normal(size=(n, n))
    return A @ A.T + n * np.eye(n)


def test_sigma_points_and_weights_match_filterpy() -> None:
    rng = np.random.default_rng(0)
    points = MerweScaledSigmaPoints(3, alpha=1.0, beta=2.0, kappa=0.0)
    wm, wc, lam = ukf_weights(3)
    np.testing.assert_allclose(wm, points.Wm, rtol=0, atol=1e-12)
    np.testing.assert_allclose(wc, points.Wc, rtol=0, atol=1e-12)
    for _ in range(20):
        x = rng.normal(size=3)
        P = _random_spd(rng, 3)
        ours = sigma_points(x[None], P[None], lam)[0]
        np.testing.assert_allclose(ours, points.sigma_points(x, P), rtol=0, atol=1e-12)
        noise = _random_spd(rng, 4)
        ys = rng.normal(size=(7, 4))
        m1, c1 = unscented_transform(ys[None], wm, wc, noise[None])
        m2, c2 = fp_unscented_transform(ys, points.Wm, points.Wc, noise)
        np.testing.assert_allclose(m1[0], m2, rtol=0, atol=1e-12)
        np.testing.assert_allclose(c1[0], c2, rtol=0, atol=1e-12)


def test_ekf_matches_filterpy_over_a_run(run: tuple[object, np.ndarray]) -> None:
    rig, acc = run
    pm = PaperModel.from_rig(rig)  # type: ignore[arg-type]
    ours = PaperEKF().estimate(rig, acc)  # type: ignore[arg-type]
    M = acc.shape[-1]
    f = ExtendedKalmanFilter(dim_x=3, dim_z=4, dim_u=M)
    f.x = np.zeros(3)
    f.P = np.eye(3)
    f.F = pm.Phi
    f.B = pm.dt * pm.B()  # x⁻ = Φ x + ΔT B â  (eq. 13)
    f.Q = pm.Q()
    thetas, wa, wb = [], [], []
    for k in range(acc.shape[1]):
        a = acc[0, k]
        f.predict(u=a)
        f.update(pm.measurement(a[None])[0],
                 HJacobian=lambda x, a=a: pm.H(x[None], a[None])[0],
                 Hx=lambda x, a=a: pm.h(x[None], a[None])[0],
                 R=pm.R(f.x[None])[0])
        wa.append(f.x[0])
        wb.append(f.x[1])
        thetas.append(f.x[2])
    np.testing.assert_allclose(ours.omega_a[0], wa, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.omega_b[0], wb, rtol=0, atol=1e-9)
    wrapped = np.angle(np.exp(1j * np.array(thetas)))
    np.testing.assert_allclose(ours.theta[0], wrapped, rtol=0, atol=1e-9)


def _fd_jacobian(fun, x: np.ndarray, h: float = 1e-6) -> np.ndarray:  # type: ignore[no-untyped-def]
    cols = []
    for i in range(x.shape[-1]):
        e = np.zeros_like(x)
        e[..., i] = h
        cols.append((fun(x + e) - fun(x - e)) / (2 * h))
    return np.stack(cols, -1)


def test_paper_jacobian_matches_finite_differences(run: tuple[object, np.ndarray]) -> None:
    rig, acc = run
    pm = PaperModel.from_rig(rig)  # type: ignore[arg-type]
    rng = np.random.default_rng(1)
    x = rng.normal(size=(50, 3))
    a = acc[0, rng.integers(0, acc.shape[1], 50)]
    np.testing.assert_allclose(pm.H(x, a), _fd_jacobian(lambda s: pm.h(s, a), x), atol=1e-7)


def test_array_jacobian_matches_finite_differences(run: tuple[object, np.ndarray]) -> None:
    rig, _ = run
    model = ArrayModel(rig)  # type: ignore[arg-type]
    rng = np.random.default_rng(2)
    s = rng.normal(size=(50, N_STATE))
    np.testing.assert_allclose(model.H(s), _fd_jacobian(model.h, s), atol=1e-7)


def test_noise_cross_covariance_sign(run: tuple[object, np.ndarray]) -> None:
    """w = −ΔT B ê (the process integrates the noisy â) and v = V ê share ê: check E[w vᵀ]."""
    rig, _ = run
    pm = PaperModel.from_rig(rig)  # type: ignore[arg-type]
    rng = np.random.default_rng(3)
    x = np.array([[0.4, -0.2, 0.7]])
    e = rng.normal(size=(400_000, pm.q_hat.size)) * np.sqrt(pm.q_hat)
    w = -pm.dt * e @ pm.B().T
    v = e @ pm.V(x)[0].T
    empirical = w.T @ v / len(e)
    expected = pm.cross_cov(x)[0]
    # A sign error flips every entry; sampling error is ~1 % of the largest entry.
    np.testing.assert_allclose(empirical, expected, atol=0.05 * np.abs(expected).max())
