"""The simulator satisfies the mechanisms' closed-form kinematics and the sensor models."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from jointangle.rig import SensorConfig
from jointangle.sensors import STANDARD_GRAVITY
from jointangle.sim.mechanism import (
    point_accelerations_link,
    point_positions_world,
    slider_crank,
    specific_force_link,
    two_link,
)
from jointangle.sim.motion import Constant, MinimumJerkMoves, Sine
from jointangle.sim.scenarios import scenario_names, simulate
from jointangle.sim.sensor_model import sensor_reading

FS = 2000.0


def _second_derivative(x: np.ndarray, dt: float) -> np.ndarray:
    return (x[2:] - 2 * x[1:-1] + x[:-2]) / dt**2


@pytest.mark.parametrize("L", [0.1, 0.3])
def test_slider_crank_closed_form(L: float) -> None:
    t = np.arange(0, 5, 1 / FS)
    m = slider_crank(t, Sine(np.radians(45), 0.2), L, 2 * L)
    # The slider (far end of link b) stays on the world x axis.
    slider = point_positions_world(m, "b", np.array([[2 * L, 0.0]]))[:, 0]
    np.testing.assert_allclose(slider[:, 1], 0.0, atol=1e-12)
    # Crank tip and connecting-rod start coincide (the joint).
    tip_a = point_positions_world(m, "a", np.array([[L, 0.0]]))[:, 0]
    tip_b = point_positions_world(m, "b", np.array([[0.0, 0.0]]))[:, 0]
    np.testing.assert_allclose(tip_a, tip_b, atol=1e-12)
    # ω and α are the derivatives of θ.
    np.testing.assert_allclose(np.gradient(m.b.theta, t)[5:-5], m.b.omega[5:-5], atol=1e-5)
    np.testing.assert_allclose(np.gradient(m.b.omega, t)[5:-5], m.b.alpha[5:-5], atol=1e-4)


@pytest.mark.parametrize("mech", ["slider", "two-link"])
def test_point_accelerations_match_positions(mech: str) -> None:
    t = np.arange(0, 3, 1 / FS)
    if mech == "slider":
        m = slider_crank(t, Sine(np.radians(45), 0.7), 0.2, 0.4)
    else:
        m = two_link(t, Sine(0.5, 0.9, 0.2), MinimumJerkMoves(-0.2, ((0.5, 1.0, 1.1),)),
                     (0.3, 0.0), (0.02, 0.01))
    r = np.array([[0.05, 0.01], [0.25, -0.02]])
    for link in ("a", "b"):
        pos = point_positions_world(m, link, r)
        acc_world_fd = _second_derivative(pos, 1 / FS)
        acc_link = point_accelerations_link(m, link, r)[1:-1]
        theta = (m.a.theta if link == "a" else m.b.theta)[1:-1]
        c, s = np.cos(theta)[:, None], np.sin(theta)[:, None]
        acc_world = np.stack([c * acc_link[..., 0] - s * acc_link[..., 1],
                              s * acc_link[..., 0] + c * acc_link[..., 1]], -1)
        # Minimum-jerk profiles have a jump in jerk at each move's ends, where the finite
        # difference itself is off by O(Δt · jerk jump).
        np.testing.assert_allclose(acc_world, acc_world_fd, atol=2e-4 if mech == "slider"
                                   else 3e-3)


def test_clamped_link_reads_gravity() -> None:
    t = np.arange(0, 1, 0.01)
    m = two_link(t, Constant(0.0), Sine(0.3, 1.0), (0.3, 0.0))
    f = specific_force_link(m, "a", np.array([[0.1, 0.0]]), np.array([0, -STANDARD_GRAVITY, 0]))
    np.testing.assert_allclose(f[:, 0], np.tile([0.0, STANDARD_GRAVITY, 0.0], (len(t), 1)),
                               atol=1e-12)


def _sensor(**kw: object) -> SensorConfig:
    base = SensorConfig(model="adxl345", position=(0.0, 0.0), mux_channel=0, address=0x53,
                        range_g=2)
    return replace(base, **kw)  # type: ignore[arg-type]


def test_noise_density_sets_sigma() -> None:
    s = _sensor(noise_density_ug=(400.0, 400.0, 400.0), quantize=False)
    f = np.zeros((200_000, 3))
    v = sensor_reading(s, f, 100.0, np.random.default_rng(1))
    expected = 400e-6 * STANDARD_GRAVITY * np.sqrt(50.0)
    np.testing.assert_allclose(v.std(axis=0), expected, rtol=0.01)


def test_quantisation_saturation_and_mounting() -> None:
    s = _sensor(noise_density_ug=(0.0, 0.0, 0.0), rotation_deg=90.0)
    f = np.array([[1.0, 0.0, 0.0], [0.0, 30.0, 0.0]])
    v = sensor_reading(s, f, 100.0, np.random.default_rng(0))
    lsb = 0.0039 * STANDARD_GRAVITY
    np.testing.assert_allclose(v / lsb, np.round(v / lsb), atol=1e-9)
    # Sensor x is the link's y (rotated 90° about z): 1 m/s² along link x reads on sensor −y.
    assert abs(v[0, 1] + 1.0) <= lsb / 2
    # 30 m/s² exceeds ±2 g: clipped at full scale (then quantised).
    assert abs(v[1, 0] - 2 * STANDARD_GRAVITY) <= lsb / 2


@pytest.mark.parametrize("name", scenario_names())
def test_every_scenario_runs_with_truth(name: str) -> None:
    sim = simulate(name, seed=3, seconds=2.0)
    assert sim.readings.shape == (200, 4, 3)
    assert np.isfinite(sim.readings).all()
    # No saturation in the canonical scenarios: the motion stays within ±2 g.
    assert np.abs(sim.readings).max() < 2 * STANDARD_GRAVITY
    # Same seed, same data; another seed, other noise.
    again = simulate(name, seed=3, seconds=2.0)
    other = simulate(name, seed=4, seconds=2.0)
    np.testing.assert_array_equal(sim.readings, again.readings)
    assert not np.array_equal(sim.readings, other.readings)


def test_mixed_gyro_rig_round_trips_through_csv(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """BNO055s beside an ADXL357: only the BNO055s get gyro columns, and the CSV reads back."""
    from jointangle.cli.main import main
    from jointangle.io.csv_formats import read_accel_csv
    from jointangle.io.rig_file import load_rig

    rig, mixed, csv = tmp_path / "rig.toml", tmp_path / "mixed.toml", tmp_path / "a.csv"
    assert main(["simulate", "--scenario", "gravity-slow-periodic", "--seconds", "0.5", "--gyros",
                 "--out", str(tmp_path / "g.csv"), "--rig-out", str(rig)]) == 0
    text = rig.read_text()
    first = text.index('model = "bno055"')
    head, tail = text[:first], text[first + len('model = "bno055"'):]
    tail = tail.replace("address = 40", "address = 29", 1).replace("range_g = 2", "range_g = 10", 1)
    mixed.write_text(head + 'model = "adxl357"' + tail)
    assert main(["simulate", "--scenario", "gravity-slow-periodic", "--seconds", "0.5", "--rig",
                 str(mixed), "--out", str(csv)]) == 0
    header = csv.read_text().splitlines()[0].split(",")
    assert "a.0.gx" not in header and "a.1.gx" in header and "b.1.gz" in header
    data = read_accel_csv(csv, load_rig(mixed))
    assert data.gyro is not None
    assert np.isnan(data.gyro[:, 0]).all() and np.isfinite(data.gyro[:, 1:]).all()
