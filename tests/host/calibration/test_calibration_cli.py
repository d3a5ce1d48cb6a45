"""`jointangle calibrate` (offline form) and `jointangle bench calibration`."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from jointangle.cli.main import main
from jointangle.io.csv_formats import AccelData, write_accel_csv
from jointangle.io.rig_file import load_rig, write_rig
from jointangle.sim.scenarios import gravity_rig
from jointangle.sim.static_poses import axis_poses, static_pose_recording, with_sensor_errors


@pytest.fixture
def rig_file(tmp_path: Path) -> Path:
    path = tmp_path / "rig.toml"
    write_rig(gravity_rig(100.0), path)
    return path


def test_simulate_then_calibrate_writes_a_calibrated_rig(
        rig_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    err_rig = tmp_path / "rig_err.toml"
    poses = tmp_path / "poses.csv"
    out = tmp_path / "cal.toml"
    assert main(["calibrate", "--rig", str(rig_file), "--inject-errors", "3", "--rig-out",
                 str(err_rig), "--simulate-poses", str(poses), "--seed", "4"]) == 0
    capsys.readouterr()
    assert main(["calibrate", "--rig", str(err_rig), "--poses", str(poses), "--out", str(out),
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["accepted"] and len(doc["poses"]) == 7
    assert [s["grade"] for s in doc["sensors"]] == ["A"] * 4
    cal = load_rig(out)
    for _, _, s in cal.all_sensors():
        assert s.S is not None and s.offset is not None and s.noise_density_ug is not None
        assert s.sim_misalignment_deg is not None  # the simulated sensor is kept as it was


def test_rejected_fit_writes_nothing_and_says_why(
        rig_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rig = gravity_rig(100.0)
    rec = static_pose_recording(rig, axis_poses()[:3], seed=1)
    poses = tmp_path / "poses.csv"
    write_accel_csv(poses, rig, AccelData(t=rec.t, readings=rec.readings))
    out = tmp_path / "cal.toml"
    assert main(["calibrate", "--rig", str(rig_file), "--poses", str(poses), "--out",
                 str(out)]) == 1
    captured = capsys.readouterr()
    assert "too few distinct poses" in captured.out
    assert "nothing written" in captured.err
    assert not out.exists()


def test_bad_poses_csv_names_file_line_and_field(
        rig_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rig = gravity_rig(100.0)
    rec = static_pose_recording(rig, axis_poses()[:2], seed=2, hold_s=1.0)
    poses = tmp_path / "poses.csv"
    write_accel_csv(poses, rig, AccelData(t=rec.t, readings=rec.readings))
    lines = poses.read_text().splitlines()
    cells = lines[5].split(",")
    cells[4] = "oops"  # a.1.x
    lines[5] = ",".join(cells)
    poses.write_text("\n".join(lines) + "\n")
    assert main(["calibrate", "--rig", str(rig_file), "--poses", str(poses)]) == 2
    err = capsys.readouterr().err
    assert str(poses) in err and "line 6" in err and "a.1.x" in err


def test_offline_forms_need_the_rig_and_a_real_board_needs_it_too(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["calibrate", "--poses", str(tmp_path / "p.csv")]) == 2
    assert "--rig" in capsys.readouterr().err
    # Not a sim:// board: the rig file of the build is needed before anything is opened.
    assert main(["calibrate", "--port", str(tmp_path / "no-such-port")]) == 2
    assert "--rig" in capsys.readouterr().err


def test_bench_calibration_json_reports_the_acceptance_figures(
        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "calibration", "--json", "--seeds", "1"]) == 0
    doc = json.loads(capsys.readouterr().out)
    for key in ("residual_mg_rms", "static_theta_err_deg_before",
                "static_theta_err_deg_after"):
        assert np.isfinite(doc[key])
    # Uncalibrated sensors with these errors are degrees off; calibrated ones are not.
    assert doc["static_theta_err_deg_before"] > 1.0
    assert doc["static_theta_err_deg_after"] <= 0.2
    assert doc["residual_mg_rms"] <= 1.0
    assert doc["pass"] is True
    sensors = doc["methods"]["poses"]["sensors"]
    assert len(sensors) == 4 and all(s["offset_err_mg"] <= 2.0 for s in sensors)


def test_calibrated_rig_fixes_the_static_angle_of_a_bad_rig() -> None:
    """Through the public pieces: the static θ error of a rig with injected errors drops."""
    from jointangle.bench.calibration import static_theta_errors
    from jointangle.calibration.pipeline import calibrate_recording, calibrated_rig

    rig = with_sensor_errors(gravity_rig(100.0), 21)
    rec = static_pose_recording(rig, axis_poses(), seed=22)
    cal = calibrated_rig(rig, calibrate_recording(rig, rec.t, rec.readings), noise=False)
    before = np.abs(static_theta_errors(rig, 23, (-45.0, 0.0, 60.0)))
    after = np.abs(static_theta_errors(cal, 23, (-45.0, 0.0, 60.0)))
    assert before.max() > 1.0 and after.max() < 0.2


def test_simulate_poses_json_is_one_object(rig_file: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    poses = tmp_path / "poses.csv"
    assert main(["calibrate", "--rig", str(rig_file), "--simulate-poses", str(poses),
                 "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["poses"] == 7 and doc["samples"] > 0 and doc["out"] == str(poses)
    assert doc["rig_out"] is None and poses.exists()


@pytest.mark.parametrize(("extra", "field"), [
    (["--simulate-poses", "x.csv"], "--simulate-poses"),
    (["--inject-errors", "3", "--rig-out", "ie.toml"], "--inject-errors"),
    (["--rig-out", "ie.toml"], "--rig-out"),
])
def test_options_the_mode_would_ignore_are_refused(
        rig_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
        extra: list[str], field: str) -> None:
    poses = tmp_path / "poses.csv"
    assert main(["calibrate", "--rig", str(rig_file), "--simulate-poses", str(poses)]) == 0
    capsys.readouterr()
    args = [a if not a.endswith((".csv", ".toml")) else str(tmp_path / a) for a in extra]
    assert main(["calibrate", "--rig", str(rig_file), "--poses", str(poses), *args]) == 2
    err = capsys.readouterr().err
    assert field in err and "Traceback" not in err
    assert not (tmp_path / "ie.toml").exists() and not (tmp_path / "x.csv").exists()


def test_simulate_checks_both_outputs_before_writing_either(
        rig_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rig_out = tmp_path / "r.toml"
    assert main(["calibrate", "--rig", str(rig_file), "--inject-errors", "3", "--rig-out",
                 str(rig_out), "--simulate-poses", str(tmp_path / "nowhere" / "p.csv")]) == 2
    assert "--simulate-poses" in capsys.readouterr().err
    assert not rig_out.exists()  # the rig is written first: it was not, as the poses can't be
