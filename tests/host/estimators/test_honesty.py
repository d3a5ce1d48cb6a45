"""Honesty: estimators never read truth, and real-time ones never read beyond their lag."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from jointangle.cli.main import main
from jointangle.estimators.base import sensor_to_link
from jointangle.estimators.inputs import requires_gyro
from jointangle.estimators.registry import ESTIMATORS, get_estimator
from jointangle.sim.scenarios import simulate


@pytest.fixture(scope="module")
def sim_files(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path, Path]:
    d = tmp_path_factory.mktemp("honesty")
    data, rig = d / "data.csv", d / "rig.toml"
    assert main(["simulate", "--scenario", "paper-table2-L20", "--seed", "5", "--seconds", "6",
                 "--out", str(data), "--rig-out", str(rig)]) == 0
    lines = data.read_text().splitlines()
    header = lines[0].split(",")
    n_truth = 3
    assert header[-n_truth:] == ["theta", "omega_a", "omega_b"]
    # Same file without the truth columns ...
    no_truth = d / "no_truth.csv"
    no_truth.write_text("\n".join(",".join(ln.split(",")[:-n_truth]) for ln in lines) + "\n")
    # ... and with the truth columns scrambled (rows shuffled, values scaled).
    rng = np.random.default_rng(0)
    rows = [ln.split(",") for ln in lines[1:]]
    perm = rng.permutation(len(rows))
    scrambled = d / "scrambled.csv"
    out = [lines[0]]
    for i, row in enumerate(rows):
        truth = [str(float(v) * -3.0 + 1.0) for v in rows[perm[i]][-n_truth:]]
        out.append(",".join(row[:-n_truth] + truth))
    scrambled.write_text("\n".join(out) + "\n")
    return rig, data, no_truth, scrambled


# Gyro methods (incl-kf) refuse this accelerometer-only CSV; test_neighbours.py checks them on
# a CSV with gyro columns.
ACCEL_ONLY = [n for n in ESTIMATORS if not requires_gyro(get_estimator(n))]


@pytest.mark.parametrize("name", ACCEL_ONLY)
def test_truth_columns_do_not_change_estimates(
        name: str, sim_files: tuple[Path, Path, Path, Path], tmp_path: Path) -> None:
    rig, *inputs = sim_files
    outputs = []
    for i, src in enumerate(inputs):
        out = tmp_path / f"est{i}.csv"
        assert main(["estimate", "--rig", str(rig), "--input", str(src), "--filter", name,
                     "--out", str(out)]) == 0
        outputs.append(out.read_text())
    assert outputs[0] == outputs[1] == outputs[2]
    assert len(outputs[0].splitlines()) == 601


REALTIME = [n for n in ESTIMATORS if n != "array-rts"]


@pytest.mark.parametrize("name", REALTIME)
def test_realtime_estimate_ignores_samples_beyond_its_lag(name: str) -> None:
    sim = simulate("paper-table2-L10", seed=2, seconds=4)
    rig = sim.rig
    acc = sensor_to_link(rig, sim.readings)[None]
    est = get_estimator(name)
    lag_s = est.latency_s(rig)
    assert lag_s is not None and lag_s <= 0.12 + 1e-12
    lag = round(lag_s * rig.sample_rate_hz)
    base = est.estimate(rig, acc)
    rng = np.random.default_rng(9)
    for k in (0, 57, 250):
        changed = acc.copy()
        changed[:, k + lag + 1 :] += rng.normal(0.0, 0.5, changed[:, k + lag + 1 :].shape)
        other = est.estimate(rig, changed)
        for a, b in ((base.theta, other.theta), (base.omega_a, other.omega_a),
                     (base.omega_b, other.omega_b)):
            np.testing.assert_array_equal(a[:, : k + 1], b[:, : k + 1])
        # ... and the perturbation is visible later, so the test can fail.
        assert not np.allclose(base.theta[:, k + lag + 2 :], other.theta[:, k + lag + 2 :])


def test_offline_estimator_declares_itself_offline() -> None:
    sim = simulate("paper-table2-L30", seed=0, seconds=1)
    assert get_estimator("array-rts").latency_s(sim.rig) is None
