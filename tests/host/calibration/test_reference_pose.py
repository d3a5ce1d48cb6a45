"""The joint's zero from one still pose: what motion cannot see (the direction of each link's x
axis) shifts θ by a constant, and a pose at a known angle removes it."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from jointangle.calibration.motion import MotionPrior, calibrate_motion, motion_calibrated_rig
from jointangle.calibration.reference import measure_reference, referenced_rig, turn_link
from jointangle.cli.main import main
from jointangle.estimators.base import sensor_to_link, wrap
from jointangle.estimators.registry import get_estimator
from jointangle.io.csv_formats import AccelData, write_accel_csv
from jointangle.io.rig_file import load_rig, write_rig
from jointangle.rig import LINK_NAMES, Rig
from jointangle.sim.as_built import nominal_rig
from jointangle.sim.scenarios import Simulation, simulate


def _theta_err_deg(rig: Rig, sim: Simulation, name: str = "array-ekf") -> np.ndarray:
    est = get_estimator(name).estimate(rig, sensor_to_link(rig, sim.readings)[None])
    return np.degrees(wrap(est.theta[0] - sim.theta))[sim.t >= 5.0]


def test_turning_a_link_frame_shifts_theta_by_a_constant_and_nothing_else() -> None:
    """The maths of calibration/reference.py: turning link b by β (mountings and lever arms
    together) changes the estimate by exactly −β — the motion has no say in it."""
    sim = simulate("gravity-fast-periodic", seed=1)
    base = _theta_err_deg(sim.rig, sim)
    for beta in (0.3, -0.7):
        turned = _theta_err_deg(turn_link(sim.rig, "b", beta), sim)
        assert np.mean(turned - base) == pytest.approx(-beta, abs=2e-3)
        assert np.std(turned - base) < 2e-3  # a constant: no motion reveals it
        turned_a = _theta_err_deg(turn_link(sim.rig, "a", beta), sim)
        assert np.mean(turned_a - base) == pytest.approx(beta, abs=2e-3)


def test_the_reference_pose_removes_a_link_turn() -> None:
    """A build whose link b is turned by 0.4° (its two mountings by +0.4°): the still straight
    pose reads θ off by it, and the referenced rig reads 0 again and tracks a held-out motion
    without the offset."""
    pose = simulate("gravity-reference-pose", seed=2, seconds=3.0)
    rig = pose.rig
    built = replace(rig, links={**rig.links, "b": replace(rig.links["b"], sensors=tuple(
        replace(s, sim_rotation_offset_deg=0.4) for s in rig.links["b"].sensors))})
    held = simulate("gravity-ramp", seed=2, rig=built)
    assert abs(np.mean(_theta_err_deg(rig, held))) > 0.3
    pose = simulate("gravity-reference-pose", seed=2, seconds=3.0, rig=built)
    res = measure_reference(rig, pose.readings, 0.0)
    assert res.accepted, res.reasons
    assert abs(res.offset_deg) == pytest.approx(0.4, abs=0.05)
    assert res.sigma_deg < 0.05
    fixed = referenced_rig(rig, res)
    assert measure_reference(fixed, pose.readings, 0.0).offset_deg == pytest.approx(0.0,
                                                                                     abs=1e-9)
    assert abs(np.mean(_theta_err_deg(fixed, held))) < 0.05


def test_motion_calibration_plus_reference_pose_removes_the_offset() -> None:
    """On an as-built rig the motion fit leaves each link's common turn; with the reference pose
    the constant θ offset on a held-out motion falls to the pose's noise."""
    seed = 4
    cal = simulate("gravity-free-motion-as-built", seed=seed, seconds=30.0)
    nominal = nominal_rig(cal.rig)
    rep = calibrate_motion(nominal, cal.t, cal.readings, MotionPrior(mounting_tol_deg=0.2))
    assert rep.accepted, rep.reasons
    calibrated = motion_calibrated_rig(nominal, rep)
    pose = simulate("gravity-reference-pose-as-built", seed=seed, seconds=3.0)
    res = measure_reference(calibrated, pose.readings, 0.0)
    assert res.accepted, res.reasons
    held = simulate("gravity-slow-periodic-as-built", seed=seed)
    before = abs(np.mean(_theta_err_deg(calibrated, held)))
    after = abs(np.mean(_theta_err_deg(referenced_rig(calibrated, res), held)))
    assert before > 0.05  # this build's links are turned by ~0.1° against each other
    assert after < 0.03


def test_poses_that_say_nothing_are_refused() -> None:
    # the paper's slider-crank lies flat: gravity out of the plane, θ unseen at rest
    flat = simulate("paper-table2-L30", seed=0, seconds=1.0)
    still = np.repeat(flat.readings[:1], 100, axis=0)
    res = measure_reference(flat.rig, still, 0.0)
    assert not res.accepted and "plane" in res.reasons[0]
    # moving, not held
    moving = simulate("gravity-fast-periodic", seed=0, seconds=2.0)
    res = measure_reference(moving.rig, moving.readings, 0.0)
    assert not res.accepted and any("still" in r for r in res.reasons)
    # held at another angle than the one named
    pose = simulate("gravity-reference-pose", seed=0, seconds=3.0)
    res = measure_reference(pose.rig, pose.readings, 30.0)
    assert not res.accepted and "reference" in res.reasons[0]
    assert not measure_reference(pose.rig, pose.readings[:5], 0.0).accepted


def test_turn_link_keeps_the_lever_arms_lengths() -> None:
    rig = simulate("gravity-reference-pose", seconds=1.0).rig
    turned = turn_link(rig, "a", 1.0)
    for ln in LINK_NAMES:
        la, lb = rig.links[ln], turned.links[ln]
        np.testing.assert_allclose(
            np.hypot(*(la.positions() - np.array(la.joint)).T),
            np.hypot(*(lb.positions() - np.array(lb.joint)).T), atol=1e-12)
    assert [s.rotation_deg for s in turned.links["a"].sensors] == [-1.0, -1.0]


def test_cli_reference_pose(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`calibrate --method motion --reference POSE.csv`: the written rig reads the pose at its
    angle; a pose at another angle than named is refused and nothing is written."""
    free = simulate("gravity-free-motion-as-built", seed=3, seconds=25.0)
    pose = simulate("gravity-reference-pose-as-built", seed=3, seconds=3.0)
    rig, data, ref, out = (tmp_path / n for n in ("rig.toml", "free.csv", "pose.csv", "o.toml"))
    write_rig(nominal_rig(free.rig), rig)
    write_accel_csv(data, free.rig, AccelData(t=free.t, readings=free.readings))
    write_accel_csv(ref, pose.rig, AccelData(t=pose.t, readings=pose.readings))
    args = ["calibrate", "--method", "motion", "--rig", str(rig), "--input", str(data),
            "--mounting-tolerance-deg", "0.2", "--reference", str(ref), "--json"]
    assert main([*args, "--reference-angle-deg", "20", "--out", str(out)]) == 1
    assert not out.exists()
    doc = json.loads(capsys.readouterr().out)
    assert not doc["accepted"] and "reference" in doc["reference"]["reasons"][0]
    assert main([*args, "--out", str(out)]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["accepted"] and doc["reference"]["accepted"]
    fitted = load_rig(out)
    assert measure_reference(fitted, pose.readings, 0.0).offset_deg == pytest.approx(0.0,
                                                                                     abs=1e-6)
    assert main(["calibrate", "--rig", str(rig), "--poses", str(ref), "--reference",
                 str(ref)]) == 2
    assert "--reference" in capsys.readouterr().err
