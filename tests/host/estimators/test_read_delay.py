"""The array filters told when the board reads each sensor (`read_delay_s`): each reading is
the motion at its own instant, and the multiplexed loop's skew costs nothing."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from jointangle.estimators.array_kf import N_STATE, ArrayModel
from jointangle.estimators.base import sensor_to_link, wrap
from jointangle.estimators.registry import get_estimator
from jointangle.io.rig_file import load_rig, write_rig
from jointangle.rig import LINK_NAMES, Rig
from jointangle.sim.as_built import BOARD_SKEW_PER_SENSOR_S, nominal_rig, only_sources
from jointangle.sim.scenarios import Simulation, simulate


def _delays(rig: Rig, delays: list[float]) -> Rig:
    it = iter(delays)
    return replace(rig, links={ln: replace(rig.links[ln], sensors=tuple(
        replace(s, read_delay_s=next(it)) for s in rig.links[ln].sensors)) for ln in LINK_NAMES})


def test_delayed_rows_are_the_state_carried_forward_and_the_jacobian_matches() -> None:
    rig = simulate("gravity-ramp", seconds=1.0).rig
    delays = [0.0, 0.3e-3, 0.6e-3, 0.9e-3]
    plain, delayed = ArrayModel(rig), ArrayModel(_delays(rig, delays))
    rng = np.random.default_rng(0)
    s = rng.normal(size=(3, N_STATE))
    s[:, 5:7] *= 9.0
    h0, h1 = plain.h(s), delayed.h(s)
    np.testing.assert_array_equal(h0[:, :2], h1[:, :2])  # sensor a.0 is read at the row's time
    # the last sensor's rows: θ, ω, α, j moved on by τ (to first order)
    tau = delays[3]
    s_fwd = s.copy()
    s_fwd[:, 0] += (s[:, 1] - s[:, 2]) * tau
    s_fwd[:, 1:3] += s[:, 3:5] * tau
    s_fwd[:, 3:5] += s[:, 9:11] * tau
    s_fwd[:, 5:7] += s[:, 7:9] * tau
    np.testing.assert_allclose(h1[:, 6:], plain.h(s_fwd)[:, 6:], atol=1e-5)
    assert np.max(np.abs(h1[:, 6:] - h0[:, 6:])) > 1e-4
    # H against central differences
    eps = 1e-6
    num = np.stack([(delayed.h(s + eps * e) - delayed.h(s - eps * e)) / (2 * eps)
                    for e in np.eye(N_STATE)], axis=-1)
    np.testing.assert_allclose(delayed.H(s), num, atol=1e-6)


def _steady_deg(rig: Rig, sim: Simulation, name: str = "array-ekf") -> float:
    est = get_estimator(name).estimate(rig, sensor_to_link(rig, sim.readings)[None])
    err = np.degrees(wrap(est.theta[0] - sim.theta))[sim.t >= 5.0]
    return float(np.sqrt(np.mean(err**2)))


def test_the_board_read_skew_costs_nothing_once_modelled() -> None:
    """gravity-fast-periodic read with the board's skew (0.23 ms a sensor) and nothing else
    wrong: without the delays array-ekf is ~1.7× its ideal figure, with them back at it."""
    ideal, told, blind = [], [], []
    for seed in range(2):
        built = simulate("gravity-fast-periodic-as-built", seed=seed)
        skewed = simulate("gravity-fast-periodic", seed=seed,
                          rig=only_sources(built.rig, ["skew"]))
        nominal = nominal_rig(skewed.rig)
        assert [s.read_delay_s for _, _, s in nominal.all_sensors()] == [
            k * BOARD_SKEW_PER_SENSOR_S for k in range(4)]
        ideal.append(_steady_deg(simulate("gravity-fast-periodic", seed=seed).rig,
                                 simulate("gravity-fast-periodic", seed=seed)))
        told.append(_steady_deg(nominal, skewed))
        blind.append(_steady_deg(_delays(nominal, [0.0] * 4), skewed))
    assert np.mean(blind) > 1.4 * np.mean(ideal)
    assert np.mean(told) < 1.1 * np.mean(ideal)


def test_read_delay_round_trips_through_the_rig_file(tmp_path: Path) -> None:
    path = tmp_path / "r.toml"
    rig = _delays(simulate("gravity-ramp", seconds=1.0).rig, [0.0, 2e-4, 4e-4, 6e-4])
    write_rig(rig, path)
    assert "read_delay_s = 0.0002" in path.read_text()
    assert [s.read_delay_s for _, _, s in load_rig(path).all_sensors()] == [
        0.0, 2e-4, 4e-4, 6e-4]
