"""The array matrices reproduce rigid-body kinematics exactly, for any geometry and motion."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from jointangle.errors import GeometryError
from jointangle.model import D, array_matrices, drot, rot

coord = st.floats(-0.5, 0.5, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(
    n=st.integers(2, 8),
    seed=st.integers(0, 2**32 - 1),
    w=st.floats(-20, 20),
    alpha=st.floats(-200, 200),
    aox=st.floats(-50, 50),
    aoy=st.floats(-50, 50),
)
def test_G_and_F_recover_rigid_body_motion(n: int, seed: int, w: float, alpha: float,
                                           aox: float, aoy: float) -> None:
    rng = np.random.default_rng(seed)
    r = rng.uniform(-0.5, 0.5, (n, 2))
    if np.sum((r - r.mean(0)) ** 2) < 1e-4:
        r[0] += 0.1
    joint = rng.uniform(-0.5, 0.5, 2)
    y = np.array([w * w, alpha])
    a_joint = np.array([aox, aoy])
    # eq. 1: a_i = a_O + D(r_i − r_O) y
    a = np.concatenate([a_joint + D(ri - joint) @ y for ri in r])
    m = array_matrices(r, joint)
    np.testing.assert_allclose(m.G @ a, y, rtol=1e-9, atol=1e-9 * (1 + np.abs(y).max()))
    np.testing.assert_allclose(m.F @ a, a_joint, rtol=1e-9, atol=1e-9 * (1 + np.abs(a).max()))
    # E removes the mean; F_m takes it.
    np.testing.assert_allclose(m.Fm @ (m.E @ a), 0.0, atol=1e-9 * (1 + np.abs(a).max()))


def test_coincident_sensors_are_refused() -> None:
    with pytest.raises(GeometryError, match="coincident"):
        array_matrices(np.array([[0.1, 0.0], [0.1, 0.0]]), np.zeros(2), "a")


def test_rotation_convention() -> None:
    # vᵃ = R(θ_ab) vᵇ: a vector along link b's x axis, seen from a when b is rotated by −θ.
    theta = 0.3
    vb = np.array([1.0, 0.0])
    # Link a at world angle θ_a = θ, link b at 0: vᵃ = Rot(−θ) vʷ and vʷ = vᵇ.
    expected = np.array([np.cos(theta), -np.sin(theta)])
    np.testing.assert_allclose(rot(theta) @ vb, expected)
    h = 1e-6
    np.testing.assert_allclose(drot(theta), (rot(theta + h) - rot(theta - h)) / (2 * h),
                               atol=1e-8)
