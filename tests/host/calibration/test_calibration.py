"""Calibration maths, stillness detection, rejection reasons and the simulated error model."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from jointangle.calibration.fit import (
    calibration_error,
    fit_alignment,
    fit_gravity_magnitude,
    fit_linear,
    rotation_error_deg,
)
from jointangle.calibration.pipeline import (
    MG,
    calibrate_recording,
    calibrate_segments,
    calibrated_rig,
)
from jointangle.calibration.stillness import detect_still, measure_noise, windowed_std
from jointangle.rig import LinkConfig, dump_rig, parse_rig
from jointangle.sensors import STANDARD_GRAVITY
from jointangle.sim.scenarios import gravity_rig
from jointangle.sim.sensor_model import (
    link_to_sensor,
    rotation_from_vector_deg,
    sensor_distortion,
    sensor_reading,
)
from jointangle.sim.static_poses import (
    AXES,
    axis_poses,
    pose,
    random_poses,
    static_pose_recording,
    with_sensor_errors,
)

G = STANDARD_GRAVITY


def _random_model(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    m = rotation_from_vector_deg(rng.uniform(-3, 3, 3)).T
    m = (np.eye(3) + rng.uniform(-0.05, 0.05, (3, 3))) @ m
    return m, rng.uniform(-1.0, 1.0, 3)


def _unit(rng: np.random.Generator, n: int) -> np.ndarray:
    d = rng.standard_normal((n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


# --- the maths, noise-free: exact recovery --------------------------------------------------


def test_fit_linear_recovers_exact_model_from_four_poses() -> None:
    rng = np.random.default_rng(0)
    m, b = _random_model(rng)
    a = G * np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [-1, -1, -1]]) / np.array(
        [[1], [1], [1], [np.sqrt(3)]])
    v = a @ m.T + b
    fit = fit_linear(v, a, G)
    e_mat, e_off = calibration_error(fit.S, fit.offset, m, b)
    assert np.abs(e_mat).max() < 1e-12 and np.abs(e_off).max() < 1e-12
    assert np.abs(fit.residuals).max() < 1e-10


def test_fit_linear_matches_the_papers_stacked_pseudoinverse() -> None:
    """y = 𝒱⁺𝒜 with the 3P×12 matrix of Appendix IV equals our split solution."""
    rng = np.random.default_rng(1)
    v = rng.standard_normal((7, 3)) * G
    a = rng.standard_normal((7, 3)) * G
    rows = []
    for vj in v:
        blk = np.zeros((3, 12))
        for mrow in range(3):
            blk[mrow, 3 * mrow:3 * mrow + 3] = vj
            blk[mrow, 9 + mrow] = 1.0
        rows.append(blk)
    y = np.linalg.pinv(np.vstack(rows)) @ a.ravel()
    fit = fit_linear(v, a, G)
    assert np.allclose(fit.S.ravel(), y[:9]) and np.allclose(fit.offset, y[9:])


def test_gravity_magnitude_fit_recovers_intrinsic_model_up_to_rotation() -> None:
    rng = np.random.default_rng(2)
    m, b = _random_model(rng)
    f = G * _unit(rng, 20)
    v = f @ m.T + b
    fit = fit_gravity_magnitude(v, G)
    assert fit.success and np.abs(fit.residuals).max() < 1e-9
    assert np.allclose(fit.T, fit.T.T)
    # T M must be a rotation (what no magnitude can see), and T b + c = 0.
    q = fit.T @ m
    assert np.allclose(q @ q.T, np.eye(3), atol=1e-9)
    assert np.allclose(fit.T @ b + fit.c, 0.0, atol=1e-9)


def test_alignment_is_the_wahba_minimiser() -> None:
    rng = np.random.default_rng(3)
    r_true = rotation_from_vector_deg(np.array([2.0, -1.0, 2.5]))
    u = _unit(rng, 6)
    al = fit_alignment(u, u @ r_true.T)
    assert np.allclose(al.R, r_true, atol=1e-12)
    assert al.residuals.max() < 1e-6
    assert np.isclose(np.linalg.det(al.R), 1.0)


def test_calibration_error_reads_back_a_known_rotation() -> None:
    r = rotation_from_vector_deg(np.array([0.0, 0.0, 0.3]))
    e_mat, e_off = calibration_error(np.eye(3), np.zeros(3), r, np.zeros(3))
    assert np.allclose(rotation_error_deg(e_mat), [0.0, 0.0, 0.3], atol=1e-5)
    assert np.allclose(e_off, 0.0)


# --- the simulated error model --------------------------------------------------------------


def test_sensor_distortion_is_what_sensor_reading_applies() -> None:
    rig = with_sensor_errors(gravity_rig(100.0), 4)
    s = replace(rig.links["a"].sensors[0], quantize=False, noise_density_ug=(0.0, 0.0, 0.0),
                rotation_deg=30.0)
    f = G * _unit(np.random.default_rng(5), 10)
    got = sensor_reading(s, f, 100.0, np.random.default_rng(0))
    m, b = sensor_distortion(s)
    assert np.allclose(got, link_to_sensor(30.0, f) @ m.T + b)
    # Bounds of the injected errors (issue 7).
    assert s.sim_misalignment_deg is not None and s.sim_scale_error is not None
    assert s.sim_bias_mps2 is not None and s.sim_cross_axis is not None
    assert np.linalg.norm(s.sim_misalignment_deg) <= 3.0
    assert np.abs(s.sim_scale_error).max() <= 0.05
    assert np.abs(s.sim_cross_axis).max() <= 0.1
    assert np.abs(s.sim_bias_mps2).max() <= 0.1 * G


def test_new_simulation_fields_round_trip_through_the_rig_file() -> None:
    rig = with_sensor_errors(gravity_rig(100.0), 6)
    back = parse_rig(dump_rig(rig))
    assert back.links["b"].sensors[1] == rig.links["b"].sensors[1]


def test_rig_without_new_fields_reads_as_before(example_rig_text: str) -> None:
    s = parse_rig(example_rig_text).links["a"].sensors[0]
    assert s.sim_misalignment_deg is None and s.sim_cross_axis is None
    m, b = sensor_distortion(s)
    assert np.array_equal(m, np.eye(3)) and np.array_equal(b, np.zeros(3))


# --- stillness and noise --------------------------------------------------------------------


def test_windowed_std_matches_direct_computation() -> None:
    x = np.random.default_rng(7).standard_normal((200, 2, 3))
    w = windowed_std(x, 20)
    assert np.allclose(w[100], x[90:110].std(axis=0, ddof=1))
    assert np.allclose(w[0], x[0:20].std(axis=0, ddof=1))


def test_stillness_finds_every_hold_and_measures_datasheet_noise() -> None:
    rig = gravity_rig(100.0)
    rec = static_pose_recording(rig, axis_poses(), seed=1)
    segs = detect_still(rig, rec.t, rec.readings)
    assert len(segs) == len(rec.holds) and all(s.still for s in segs)
    for s, (a, b) in zip(segs, rec.holds, strict=True):
        assert a <= s.t_start and s.t_stop <= b
    noise = measure_noise(rig, rec.readings, segs)
    assert noise is not None
    # ADXL345 datasheet: 290 µg/√Hz on x, y and 430 on z (quantisation removed).
    assert np.allclose(noise.density_ug[:, :2], 290.0, rtol=0.1)
    assert np.allclose(noise.density_ug[:, 2], 430.0, rtol=0.1)


def test_a_creeping_hold_is_flagged_not_still() -> None:
    rig = gravity_rig(100.0)
    rec = static_pose_recording(rig, axis_poses()[:5], seed=2, hold_s=6.0)
    readings = rec.readings.copy()
    a, b = (round(x * 100) for x in rec.holds[2])
    readings[a:b, 1, 0] += np.linspace(0.0, 0.15, b - a)  # 15 mg creep over the hold
    segs = detect_still(rig, rec.t, readings)
    flagged = [s for s in segs if not s.still]
    assert len(flagged) == 1 and "drifted" in str(flagged[0].reason)
    assert "sensor 1 axis x" in str(flagged[0].reason)


# --- end to end on simulated poses ----------------------------------------------------------


@pytest.mark.parametrize("method", ["poses", "gravity"])
def test_calibration_recovers_injected_errors(method: str) -> None:
    rig = with_sensor_errors(gravity_rig(100.0), 8)
    if method == "poses":
        poses = axis_poses()
    else:
        poses = random_poses(16, np.random.default_rng(9), min_axis_distance_deg=30.0)
        poses += [pose(AXES["+z"]), pose(AXES["+x"])]
    rec = static_pose_recording(rig, poses, seed=10)
    report = calibrate_recording(rig, rec.t, rec.readings, method)
    assert report.accepted, report.reasons()
    for r, (_, _, s) in zip(report.sensors, rig.all_sensors(), strict=True):
        assert r.S is not None and r.offset is not None
        e_mat, e_off = calibration_error(r.S, r.offset, *sensor_distortion(s))
        assert np.abs(e_off).max() < 2 * MG
        assert np.abs(np.diag(e_mat)).max() < 1e-3
        assert np.linalg.norm(rotation_error_deg(e_mat)) < 0.2
        assert r.grade == "A" and r.residual_mg_rms < 1.0
    cal = calibrated_rig(rig, report)
    assert cal.links["a"].sensors[0].S is not None
    assert parse_rig(dump_rig(cal)).links["b"].sensors[0].S == cal.links["b"].sensors[0].S


def test_noise_below_the_quantisation_is_not_written_as_zero() -> None:
    """A sensor quieter than its LSB measures a white-noise density of 0, which a rig file may
    not hold (the filters' Q̂ needs > 0): the calibrated rig keeps the density it had."""
    rig = with_sensor_errors(gravity_rig(100.0), 8)
    quiet = replace(rig.links["a"].sensors[0], noise_density_ug=(1.0, 1.0, 1.0))
    rig = replace(rig, links={**rig.links, "a": LinkConfig(
        rig.links["a"].joint, (quiet, *rig.links["a"].sensors[1:]))})
    rec = static_pose_recording(rig, axis_poses(), seed=10)
    report = calibrate_recording(rig, rec.t, rec.readings, "poses")
    assert report.accepted and report.sensors[0].noise_density_ug == (0.0, 0.0, 0.0)
    cal = parse_rig(dump_rig(calibrated_rig(rig, report)))
    assert cal.links["a"].sensors[0].noise_density_ug == (1.0, 1.0, 1.0)
    assert cal.links["a"].sensors[1].noise_density_ug == report.sensors[1].noise_density_ug


def test_too_few_poses_is_rejected_with_the_reason() -> None:
    rig = gravity_rig(100.0)
    rec = static_pose_recording(rig, axis_poses()[:3], seed=11)
    report = calibrate_recording(rig, rec.t, rec.readings, "poses")
    assert not report.accepted
    assert all("too few distinct poses: 3" in r for r in report.reasons())
    with pytest.raises(ValueError, match="rejected"):
        calibrated_rig(rig, report)


def test_poses_in_one_plane_are_rejected_as_ill_conditioned() -> None:
    rig = gravity_rig(100.0)
    planar = [pose(AXES[k]) for k in ("+x", "-x", "+y", "-y", "+x")]
    rec = static_pose_recording(rig, planar, seed=12)
    report = calibrate_recording(rig, rec.t, rec.readings, "poses")
    assert not report.accepted
    assert all("ill-conditioned" in r for r in report.reasons())


def test_a_pose_off_its_axis_is_rejected_as_a_large_residual() -> None:
    rig = gravity_rig(100.0)
    poses = axis_poses()
    poses[1] = pose(np.array([1.0, 0.0, 0.12]))  # "+x" held 7° off
    rec = static_pose_recording(rig, poses, seed=13)
    report = calibrate_recording(rig, rec.t, rec.readings, "poses")
    assert not report.accepted
    assert all("residual too large" in r for r in report.reasons())


def test_a_pose_that_was_not_still_is_excluded() -> None:
    rig = gravity_rig(100.0)
    rec = static_pose_recording(rig, axis_poses(), seed=14, hold_s=5.0)
    readings = rec.readings.copy()
    a, b = (round(x * 100) for x in rec.holds[3])
    readings[a:b, :, 1] += np.linspace(0.0, 0.2, b - a)[:, None]
    segs = detect_still(rig, rec.t, readings)
    report = calibrate_segments(rig, segs, readings, "poses")
    excluded = [p for p in report.poses if p.reason is not None]
    assert len(excluded) == 1 and "not still" in str(excluded[0].reason)
    assert report.accepted  # six distinct poses remain


def test_gravity_alignment_drops_an_arbitrary_pose_that_looks_like_an_axis() -> None:
    """A hold 8° from +y passes the first identification; its residual gives it away when
    enough true link poses outvote it, and the fit is rejected when they cannot."""
    rig = with_sensor_errors(gravity_rig(100.0), 15)
    poses = random_poses(14, np.random.default_rng(16), min_axis_distance_deg=30.0)
    fake = pose(np.array([0.14, 1.0, 0.0]))
    rec = static_pose_recording(rig, [*poses, pose(AXES["+z"]), pose(AXES["+x"]), fake],
                                seed=17)
    report = calibrate_recording(rig, rec.t, rec.readings, "gravity")
    assert not report.accepted
    assert all("disagree" in r for r in report.reasons())
    rec = static_pose_recording(
        rig, [*poses, pose(AXES["+z"]), pose(AXES["+x"]), pose(AXES["-x"]), fake], seed=17)
    report = calibrate_recording(rig, rec.t, rec.readings, "gravity")
    assert report.accepted, report.reasons()
    for r, (_, _, s) in zip(report.sensors, rig.all_sensors(), strict=True):
        assert r.S is not None and r.offset is not None
        e_mat, _ = calibration_error(r.S, r.offset, *sensor_distortion(s))
        assert np.linalg.norm(rotation_error_deg(e_mat)) < 0.2


def test_gravity_method_needs_enough_spread_orientations() -> None:
    rig = gravity_rig(100.0)
    few = random_poses(6, np.random.default_rng(18), min_axis_distance_deg=30.0)
    rec = static_pose_recording(rig, few, seed=19)
    report = calibrate_recording(rig, rec.t, rec.readings, "gravity")
    assert not report.accepted
    assert all("too few distinct poses: 6 still orientations" in r for r in report.reasons())
    # Twelve orientations, all turned about one axis: a plane of directions.
    ring = [pose(np.array([np.cos(a), np.sin(a), 0.0])) for a in np.radians(np.arange(12) * 30)]
    rec = static_pose_recording(rig, ring, seed=20)
    report = calibrate_recording(rig, rec.t, rec.readings, "gravity")
    assert not report.accepted
    assert all("ill-conditioned" in r for r in report.reasons())


def test_gravity_alignment_without_link_poses_is_rejected_but_fiducial_works() -> None:
    rig = with_sensor_errors(gravity_rig(100.0), 24)
    poses = random_poses(20, np.random.default_rng(25), min_axis_distance_deg=30.0)
    rec = static_pose_recording(rig, poses, seed=26)
    report = calibrate_recording(rig, rec.t, rec.readings, "gravity")
    assert not report.accepted
    assert all("alignment needs" in r for r in report.reasons())
    fid = calibrate_recording(rig, rec.t, rec.readings, "gravity", alignment="fiducial")
    assert fid.accepted, fid.reasons()
    # Relative alignment: a.1 now agrees with a.0 (Madgwick §6.2.2), whatever a.0's own error.
    sensors = rig.all_sensors()
    s0, s1 = fid.sensors[0], fid.sensors[1]
    assert s0.S is not None and s1.S is not None
    r0 = s0.S @ sensor_distortion(sensors[0][2])[0]
    r1 = s1.S @ sensor_distortion(sensors[1][2])[0]
    assert np.linalg.norm(rotation_error_deg(r1 @ np.linalg.inv(r0) - np.eye(3))) < 0.2


def test_noise_is_measured_even_when_the_sensor_is_noisier_than_its_datasheet() -> None:
    base = gravity_rig(100.0)
    noisy = replace(base, links={ln: replace(lk, sensors=tuple(
        replace(s, noise_density_ug=(900.0, 900.0, 900.0)) for s in lk.sensors))
        for ln, lk in base.links.items()})
    rec = static_pose_recording(noisy, axis_poses(), seed=27)
    segs = detect_still(base, rec.t, rec.readings)  # the file says datasheet noise
    assert len(segs) == 7 and all(s.still for s in segs)
    noise = measure_noise(base, rec.readings, segs)
    assert noise is not None
    assert np.allclose(noise.density_ug, 900.0, rtol=0.1)


def test_four_poses_fit_exactly_and_are_graded_c() -> None:
    """Appendix IV's minimum: four independent poses determine S and o with nothing left over
    to check them, so the fit is accepted at grade C only."""
    rig = with_sensor_errors(gravity_rig(100.0), 28)
    four = [pose(AXES[k]) for k in ("+z", "+x", "+y", "-x")]
    rec = static_pose_recording(rig, four, seed=29)
    report = calibrate_recording(rig, rec.t, rec.readings, "poses")
    assert report.accepted, report.reasons()
    assert {r.grade for r in report.sensors} == {"C"}
    assert all(r.residual_mg_rms < 1e-6 for r in report.sensors)


def test_a_recording_without_stillness_is_rejected_with_the_reason() -> None:
    rig = gravity_rig(100.0)
    rec = static_pose_recording(rig, axis_poses(), seed=30, hold_s=0.3)
    report = calibrate_recording(rig, rec.t, rec.readings, "poses")
    assert not report.poses and not report.accepted
    assert all("no still pose found" in r for r in report.reasons())
