"""Observability: a vertical hinge at rest hides θ; gravity in the plane or motion shows it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from jointangle.cli.main import main
from jointangle.estimators.base import sensor_to_link
from jointangle.io.csv_formats import AccelData, write_accel_csv
from jointangle.observability import observable
from jointangle.sensors import STANDARD_GRAVITY
from jointangle.sim.mechanism import two_link
from jointangle.sim.motion import Constant, MinimumJerkMoves
from jointangle.sim.scenarios import gravity_rig, simulate, simulate_rig

G = STANDARD_GRAVITY


def _vertical_hinge(move_link_a: bool, seconds: float = 6.0
                    ) -> tuple[np.ndarray, np.ndarray, object]:
    """Gravity along the hinge (out of the plane). Link b makes one 40° move over 1 s at
    t = 2 s; link a stays still, or turns 40° about its far end at the same time (which
    accelerates the joint)."""
    rig = gravity_rig(100.0)
    t = np.arange(round(seconds * 100)) / 100.0
    move = MinimumJerkMoves(0.0, ((2.0, 1.0, np.radians(40.0)),))
    link_a = move if move_link_a else Constant(0.0)
    mech = two_link(t, link_a, Constant(0.0) if move_link_a else move, (0.30, 0.0))
    readings = simulate_rig(rig, mech, np.array([0.0, 0.0, -G]), seed=1)
    return t, readings, rig


def test_vertical_hinge_at_rest_is_not_observable() -> None:
    t, readings, rig = _vertical_hinge(move_link_a=True)
    seen = observable(rig, sensor_to_link(rig, readings)[None])[0]  # type: ignore[arg-type]
    assert not seen[(t > 0.5) & (t < 1.9)].any()  # at rest before the move
    assert not seen[t > 3.5].any()  # at rest after it
    assert seen[(t > 2.3) & (t < 2.7)].mean() > 0.8  # the move accelerates the joint


def test_clamped_link_and_vertical_hinge_never_show_the_angle() -> None:
    """The joint never accelerates when link a is clamped: even while link b moves, its angle
    relative to link a cannot be read from the joint's force."""
    _, readings, rig = _vertical_hinge(move_link_a=False)
    seen = observable(rig, sensor_to_link(rig, readings)[None])[0]  # type: ignore[arg-type]
    assert not seen.any()


@pytest.mark.parametrize("scenario", ["gravity-ramp", "paper-table2-L10"])
def test_canonical_scenarios_are_observable(scenario: str) -> None:
    sim = simulate(scenario, seed=0, seconds=10)
    seen = observable(sim.rig, sensor_to_link(sim.rig, sim.readings)[None])[0]
    assert seen[sim.t >= 0.25].mean() > 0.99


def test_estimate_flags_and_warns(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    t, readings, rig = _vertical_hinge(move_link_a=True)
    data, rig_path, est = tmp_path / "v.csv", tmp_path / "v.toml", tmp_path / "e.csv"
    write_accel_csv(data, rig, AccelData(t=t, readings=readings))  # type: ignore[arg-type]
    from jointangle.io.rig_file import write_rig

    write_rig(rig, rig_path)  # type: ignore[arg-type]
    assert main(["estimate", "--rig", str(rig_path), "--input", str(data), "--filter",
                 "array-ekf", "--out", str(est)]) == 0
    assert "not observable" in capsys.readouterr().err
    table = np.loadtxt(est, delimiter=",", skiprows=1)
    header = est.read_text().splitlines()[0].split(",")
    flags = table[:, header.index("observable")]
    assert flags[50:190].max() == 0.0 and flags[230:270].mean() > 0.8
